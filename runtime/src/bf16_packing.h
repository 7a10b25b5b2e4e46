// Prepares a bf16 convolution (kernels/bf16_job.h) at Session::Create, into memory the session
// owns: the biases, the float32 weights rounded to bf16 (HWIO, what the reference reads) and,
// for a SIMD tile of nr output channels, the same in blocks of nr with input channels in pairs.
#pragma once

#include <cstddef>

#include "kernels/bf16_job.h"
#include "sfrt/model.h"

namespace sfrt {

// Whether PackBf16Conv with nr > 0 adds the few-output layout (PackedBf16Conv::few_weights):
// at most kBf16FewOutChannels outputs, at least kBf16FewOutMinInputs inputs.
inline bool Bf16FewOutputs(const ConvParams& params) {
  return params.out_channels <= kBf16FewOutChannels && params.in_channels >= kBf16FewOutMinInputs;
}

// Bytes PackBf16Conv writes for `params` with blocks of `nr` output channels (0: the reference
// layout only), with the phase kernels of a 3x3 convolution that reads a nearest-2x upsampling
// when `with_phases`. A multiple of 64.
size_t PackedBf16Bytes(const ConvParams& params, int nr, bool with_phases);

// Writes the packing into `dst` (PackedBf16Bytes bytes, 64-byte aligned) and returns the
// descriptor pointing into it. The phase kernels sum the float32 3x3 taps that read the same
// low-resolution pixel (conv_packing.h's grouping), then round the sums to bf16.
PackedBf16Conv PackBf16Conv(const ConvParams& params, int nr, bool with_phases, bool out_float,
                            void* dst);

}  // namespace sfrt
