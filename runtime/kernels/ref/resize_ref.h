// Reference resizing (schema 1.7, float32) as ONNX Resize computes it, written for clarity, on
// output rows [row_begin, row_end) so that a session can split a layer over threads.
#pragma once

#include "kernels/tensor_view.h"
#include "sfrt/model.h"

namespace sfrt::ref {

// At most 4 taps per axis (kCubic), with weights summing to 1. `outside`
// (kTfCropAndResize): the source coordinate lies outside the input, so the output pixel is the
// extrapolation value and the taps are unused.
struct ResizeTaps {
  int count = 0;
  int index[4] = {0, 0, 0, 0};
  float weight[4] = {0, 0, 0, 0};
  bool outside = false;
};

enum class ResizeAxis { kHeight, kWidth };

// The taps output position `y` of `axis` reads, the input being `in` long along it.
ResizeTaps ResizeAxisTaps(const ResizeParams& params, ResizeAxis axis, int y, int in);

// `out` has the layer's output size for `in` (sfrt/shapes.h) and in's channels.
void ResizeRows(const ConstTensorView& in, const ResizeParams& params, const TensorView& out,
                int row_begin, int row_end);

}  // namespace sfrt::ref
