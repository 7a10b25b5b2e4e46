// Reference int8 kernels: written for clarity, the oracle the SIMD int8 kernels are tested
// against bit for bit. The arithmetic is kernels/int8_job.h's. Not fast on purpose.
#pragma once

#include "kernels/int8_job.h"
#include "kernels/tensor_view.h"

namespace sfrt::ref {

// Output rows [row_begin, row_end) of an int8 convolution (all output channels; the block
// arguments are ignored), reading args.conv->weights_hwio:
//   acc[o] = sum over (ky, kx, ci) with the input pixel inside the input of
//            (x_q - in_zero_point) * w_q[ky][kx][ci][o]
// where, for args.upsampled, the input is C (see int8_job.h) instead of args.in itself; then
// the epilogue Int8Dequantize (and Int8Quantize for a uint8 output).
void Conv2dInt8Rows(const Int8ConvArgs& args, int row_begin, int row_end, int blk_begin,
                    int blk_end);

// out[y][x][c] = Int8Quantize(in[y][x][c], inv_scale, zero_point) for rows [row_begin, row_end).
void QuantizeRows(const ConstTensorView& in, float inv_scale, int zero_point, const ByteView& out,
                  int row_begin, int row_end);

}  // namespace sfrt::ref
