// The crop rule both importers lower a traced crop with (ONNX Slice chains and Keras Cropping2D):
// the rule that keeps a U-Net's crops right at every input size, not only the traced one.
#pragma once

#include <string>

#include "sfrt/exporter/model_spec.h"

namespace sfrt::exporter {

// A crop as an importer traced it at the size the network was built for: its output's size there,
// and `skip`, an earlier layer of that size which the crop's only reader (a Concat) also reads
// ("" when there is none).
struct TracedCrop {
  int out_h = 0;
  int out_w = 0;
  std::string skip;
};

// A crop removing on at most one side per axis becomes a crop to its skip's size when it has one
// (a U-Net cutting an upsampled tensor to its skip connection's size), or a crop to the input size
// when at the built size (input_h x input_w) it restores it; any other keeps its amounts at every
// size (kExplicit). Returns why it keeps them; "" when its rule follows the input size.
inline std::string ChooseCropRule(CropSpec& crop, const TracedCrop& t, int input_h, int input_w) {
  const Pads& a = crop.amounts;
  const bool one_sided = (a.top == 0 || a.bottom == 0) && (a.left == 0 || a.right == 0);
  if (!t.skip.empty() && one_sided) {
    CropToSecondInput(crop, t.skip);
    return "";
  }
  crop.rule = CropRule::kExplicit;
  if (t.out_h != input_h || t.out_w != input_w) {
    return "at the built size " + std::to_string(input_h) + "x" + std::to_string(input_w) +
           " its output is " + std::to_string(t.out_h) + "x" + std::to_string(t.out_w) +
           ", not the input size";
  }
  if (!one_sided) return "it crops both sides of an axis";
  crop.rule = CropRule::kToInputSize;
  crop.excess_rows_from_top = a.top > 0 || a.bottom == 0;
  crop.excess_cols_from_left = a.left > 0 || a.right == 0;
  return "";
}

}  // namespace sfrt::exporter
