// Prepares an int8 convolution (kernels/int8_job.h) at Session::Create, into memory the session
// owns: the per-channel multipliers and biases every tier reads and, for a SIMD tile of nr
// output channels, the weights in groups of 4 input channels and the per-tap weight sums.
#pragma once

#include <cstddef>

#include "kernels/int8_job.h"
#include "sfrt/model.h"

namespace sfrt {

// Whether PackInt8Conv with nr > 0 adds the few-output layout (PackedInt8Conv::few_weights):
// at most kInt8FewOutChannels outputs, at least kInt8FewOutMinInputs inputs.
inline bool Int8FewOutputs(const ConvParams& params) {
  return params.out_channels <= kInt8FewOutChannels && params.in_channels >= kInt8FewOutMinInputs;
}

// A convolution that one group of 4 input channels feeds, with at most 4 outputs (the
// 1/16-width model's 4->3 output layer; the 1/64-width layers): PackedInt8Conv::narrow where the
// kernel table has a narrow kernel.
inline bool Int8NarrowConv(const ConvParams& params) {
  return params.in_channels <= 4 && params.out_channels <= 4;
}

// Bytes PackInt8Conv writes for `params` with blocks of `nr` output channels (0: the reference
// layout, per-channel arrays only). A multiple of 64.
size_t PackedInt8Bytes(const ConvParams& params, int nr);

// Writes the packing into `dst` (PackedInt8Bytes bytes, 64-byte aligned) and returns the
// descriptor pointing into it and at params.weights_q. The output is uint8 quantised with
// `out_quant` (a chain's params.output_quant, or what a graph's readers share), or float32 when
// `out_quant` is null.
PackedInt8Conv PackInt8Conv(const ConvParams& params, int nr, const QuantParams* out_quant,
                            void* dst);

}  // namespace sfrt
