// Imports a SceneEDNet-shaped ONNX graph (as torch.onnx.export writes it, opsets 11 to 17) into
// a ModelSpec.
//
// The graph must have one float32 input of static shape (1, C, H, W) (the traced size) and one
// output, joined by a chain, or a graph (schema 1.5: skip connections), of:
//   Conv       2-D, group 1, dilation 1, any kernel and strides; pads or auto_pad NOTSET,
//              SAME_UPPER, VALID; bias optional. OIHW weights become HWIO.
//   Pad        mode constant, value 0, H/W only; folded into the next Conv's pads.
//   BatchNormalization  (inference) folded into the Conv right before it.
//   LeakyRelu  (alpha, ONNX default 0.01) and Relu: fused into the Conv (or Add) right before
//              them. Fusing needs that layer's output to have no other reader.
//   Resize     mode nearest with integer H/W factors (from scales, or sizes over the traced
//   Upsample   shape), when the coordinate_transformation_mode / nearest_mode pair computes
//              in[floor(y / f)] at every size: asymmetric + floor; half_pixel or
//              pytorch_half_pixel + round_prefer_floor/ceil; tf_half_pixel_for_nn + floor;
//              asymmetric + round_prefer_floor and align_corners + round_prefer_floor/ceil at
//              factors <= 2.
//   Slice      axes 2/3 (no-op on axes 0/1), step 1, any start/end (negative, INT64_MAX);
//              consecutive Slices form one crop.
//   Identity
//   Concat     along the channels (axis 1 or -3) of tensors of equal height and width.
//   Add        of two tensors of the same shape (no broadcasting).
// A chain imports with no layer naming its inputs (the files a pre-1.5 runtime reads); a graph
// names them, with InputSpec::name the graph input's name.
// Initialisers and Constant nodes (FLOAT, DOUBLE, INT64, INT32, BOOL; raw_data or typed fields)
// are constants, and so is the result of any supported shape op whose inputs are all constants:
// Shape/Size (of any tensor, all shapes are static), Gather, Cast, Concat, Unsqueeze, Squeeze,
// Slice, Reshape, Expand, Transpose, Tile, Range, ConstantOfShape, arithmetic, comparisons,
// Clip, Where, ... (the full list is in every "unsupported" error). That covers the pads and
// crop bounds torch computes from x.shape. Nodes the output does not depend on are ignored.
//
// Rules decided from the traced size:
// - Padding: each conv's traced pads are its Pad nodes' amounts plus its own. With
//   PaddingDetection::kAuto, if every conv's pads equal TensorFlow SAME_UPPER at its traced input
//   size, every conv gets PaddingRule::kSameUpper, otherwise every conv keeps kExplicit.
//   ConvSpec::pads always holds the traced amounts.
// - Crop: a crop whose output has the graph input's H and W and that removes rows (columns) on at
//   most one side becomes CropRule::kToInputSize, removing the excess from the side the traced
//   slice removed it from (top/left when it removed nothing on that axis). A crop whose only
//   reader is a Concat that also reads an earlier tensor of the crop's output size, removing on
//   at most one side per axis, becomes CropRule::kToSecondInput with that tensor as its second
//   input (a U-Net cutting an upsampled tensor to its skip's size; an axis with nothing removed
//   takes the other axis' side, or bottom/right as PyTorch's x[..., :h, :w]). Any other crop is
//   kExplicit. CropSpec::amounts always holds the traced amounts. torch.onnx.export drops a
//   slice that removes nothing at the traced size, so trace a model whose crops depend on the
//   size at a size where they remove something (or with padding computed from x.shape).
// - Layer names are the ONNX node names (a crop takes its first Slice's name); unnamed nodes get
//   conv<i>, up<i>, crop<i>, concat<i>, add<i> (counting from 0 per kind).
//
// Errors are one line naming the file and, where there is one, the node ("node '<name>' (op
// <Type>)"), the attribute or input and the offending value.
//
// Memory: a tensor's declared shape is compared with the values the file holds for it before
// anything is sized from it, and the constants and weights an import decodes, evaluates and copies
// take at most 32 MiB plus 16 bytes per byte of the file in all; past that the import fails naming
// the tensor. A file cannot make an import allocate more than that plus the parsed file, whatever
// it declares (tests/fuzz/importer_allocation_test.cc).
#pragma once

#include <string>
#include <string_view>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/status.h"

namespace sfrt::exporter {

enum class PaddingDetection {
  kAuto,       // SameUpper if every conv's pads equal the same-upper amounts at the traced size
  kSameUpper,  // force SameUpper (error naming the conv and both pads if the traced pads differ)
  kExplicit,   // keep the traced numbers
};

struct OnnxImportOptions {
  PaddingDetection padding = PaddingDetection::kAuto;
  // The graph output the model computes (an sfrt model has one output). Empty: the graph's only
  // output; a graph with several is refused, listing them. A MaxPool's Indices output (INT64 in
  // ONNX) becomes an argmax pool whose float32 values are the indices.
  std::string output;
};

// Fills layers, input (channels, traced size), output channels and producer (format, file
// name, SHA-256). Name, preprocessing and camera keep ModelSpec's defaults for the caller to set.
Result<ModelSpec> ImportOnnx(const std::string& path, const OnnxImportOptions& options = {});

// ImportOnnx on a file's bytes held in memory: `label` stands for the path in messages and gives
// producer.source_file its base name; the SHA-256 is of `bytes`.
Result<ModelSpec> ImportOnnxFromMemory(std::string_view bytes, const std::string& label,
                                       const OnnxImportOptions& options = {});

}  // namespace sfrt::exporter
