// Reference kernels for the layers that read more than one tensor (schema 1.5): channel
// concatenation (float32, and uint8 and bf16 for reduced-precision graphs) and element-wise
// addition (float32), on output rows [row_begin, row_end) so that a session can split them over
// threads. Every input has the output's height and width.
#pragma once

#include "kernels/tensor_view.h"
#include "sfrt/model.h"

namespace sfrt::ref {

// out[y][x] = inputs[0][y][x] ++ inputs[1][y][x] ++ ... (channels in input order);
// out.channels is the sum of the inputs' channels.
void ConcatRows(const ConstTensorView* inputs, int count, const TensorView& out, int row_begin,
                int row_end);
// The same for uint8 tensors of one quantisation, and for bf16 tensors.
void ConcatRows(const ConstByteView* inputs, int count, const ByteView& out, int row_begin,
                int row_end);
void ConcatRows(const ConstBf16View* inputs, int count, const Bf16View& out, int row_begin,
                int row_end);

// out[y][x][c] = act(a[y][x][c] + b[y][x][c]); a, b and out have the same shape.
void AddRows(const ConstTensorView& a, const ConstTensorView& b, const AddParams& params,
             const TensorView& out, int row_begin, int row_end);

}  // namespace sfrt::ref
