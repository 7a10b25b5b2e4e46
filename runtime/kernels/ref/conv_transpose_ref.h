// Reference transposed convolution (schema 1.6, float32), written for clarity: each output pixel
// gathers the input pixels and taps that reach it (sfrt/model.h, ConvTransposeParams), on output
// rows [row_begin, row_end) so that a session can split a layer over threads.
#pragma once

#include "kernels/tensor_view.h"
#include "sfrt/model.h"

namespace sfrt::ref {

// `out` has the layer's full output size for `in` (sfrt/shapes.h); in.channels ==
// params.in_channels, out.channels == params.out_channels.
void ConvTranspose2dRows(const ConstTensorView& in, const ConvTransposeParams& params,
                         const TensorView& out, int row_begin, int row_end);

}  // namespace sfrt::ref
