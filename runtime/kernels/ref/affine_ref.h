// Reference per-channel affine transform (schema 1.7, float32), written for clarity, on output rows
// [row_begin, row_end) so that a session can split a layer over threads.
#pragma once

#include "kernels/tensor_view.h"
#include "sfrt/model.h"

namespace sfrt::ref {

// out[y][x][c] = act(in[y][x][c] * scale[c] + shift[c]); `out` has in's size and channels.
void ChannelAffineRows(const ConstTensorView& in, const ChannelAffineParams& params,
                       const TensorView& out, int row_begin, int row_end);

}  // namespace sfrt::ref
