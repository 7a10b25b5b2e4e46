// Reference bf16 kernels: written for clarity, the oracle the SIMD bf16 kernels are tested
// against. The arithmetic is kernels/bf16_job.h's. Not fast on purpose.
#pragma once

#include "kernels/bf16_job.h"
#include "kernels/tensor_view.h"

namespace sfrt::ref {

// Output rows [row_begin, row_end) of a bf16 convolution (all output channels; the block
// arguments are ignored), reading args.conv->weights_hwio (and phase_weights_hwio):
//   acc[o] = sum over (ky, kx, ci) with the input pixel inside the input of x * w[ky][kx][ci][o]
// summed in double (every product of two bf16 values is exact), then rounded once to float32;
// where args.upsampled the input is C (bf16_job.h). Then bias and activation in float32, and
// the bf16 rounding for a bf16 output.
void Conv2dBf16Rows(const Bf16ConvArgs& args, int row_begin, int row_end, int blk_begin,
                    int blk_end);

// out[y][x][c] = FloatToBf16(in[y][x][c]) for rows [row_begin, row_end).
void ToBf16Rows(const ConstTensorView& in, const Bf16View& out, int row_begin, int row_end);

}  // namespace sfrt::ref
