// Reference resizing (schema 1.7, float32) as ONNX Resize computes it, written for clarity, on
// output rows [row_begin, row_end) so that a session can split a layer over threads.
#pragma once

#include "kernels/tensor_view.h"
#include "sfrt/model.h"

namespace sfrt::ref {

// At most 4 taps per axis (kCubic), with weights summing to 1.
struct ResizeTaps {
  int count = 0;
  int index[4] = {0, 0, 0, 0};
  float weight[4] = {0, 0, 0, 0};
};

// The taps output position `y` of an axis of length `in` reads; `num` / `den` is the axis' scale.
ResizeTaps ResizeAxisTaps(const ResizeParams& params, int y, int in, int64_t num, int64_t den);

// `out` has the layer's output size for `in` (sfrt/shapes.h) and in's channels.
void ResizeRows(const ConstTensorView& in, const ResizeParams& params, const TensorView& out,
                int row_begin, int row_end);

}  // namespace sfrt::ref
