// Prepares an int8 convolution (kernels/int8_job.h) at Session::Create, into memory the session
// owns: the per-channel multipliers and biases every tier reads and, for a SIMD tile of nr
// output channels, the weights in groups of 4 input channels and the per-tap weight sums.
#pragma once

#include <cstddef>

#include "kernels/int8_job.h"
#include "sfrt/model.h"

namespace sfrt {

// Bytes PackInt8Conv writes for `params` with blocks of `nr` output channels (0: the reference
// layout, per-channel arrays only). A multiple of 64.
size_t PackedInt8Bytes(const ConvParams& params, int nr);

// Writes the packing into `dst` (PackedInt8Bytes bytes, 64-byte aligned) and returns the
// descriptor pointing into it and at params.weights_q. The output is float32 when `out_float`,
// else uint8 quantised with params.output_quant.
PackedInt8Conv PackInt8Conv(const ConvParams& params, int nr, bool out_float, void* dst);

}  // namespace sfrt
