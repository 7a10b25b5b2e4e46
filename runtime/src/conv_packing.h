// Packs a convolution's HWIO weights into the output-channel-blocked layout the SIMD kernels
// read (kernels/conv_job.h), at Session::Create, into memory the session owns.
//
// The fused upsample-conv: with U the nearest-2x upsampling of a low-resolution map L,
// U[y] = L[y / 2], so for an output row whose first tap reads upsampled row a, the three taps
// read L rows (a / 2, a / 2, a / 2 + 1) when a is even and (a / 2, a / 2 + 1, a / 2 + 1) when a
// is odd. Taps that read the same row share an input value, so their weights can be summed
// first: per output phase (a mod 2, and the same for columns) a 2x2 kernel over L with
// 4 / 9 of the multiply-accumulates, equal to the 3x3 result up to rounding. It holds wherever
// the whole 3x3 window lies inside the (cropped) upsampled map; the kernels use the 3x3
// weights for the border pixels, where zero padding stands for some taps.
#pragma once

#include <cstddef>

#include "kernels/conv_job.h"
#include "sfrt/model.h"

namespace sfrt {

// Floats needed for the blocked weights and bias of `params` with blocks of `nr` channels, and
// for the phase weights when `with_phases` (3x3 kernels only).
size_t PackedConvFloats(const ConvParams& params, int nr, bool with_phases);

// Writes the packed weights into `dst` (PackedConvFloats floats, 64-byte aligned, each part
// starting on a 16-float boundary) and returns the descriptor pointing into it, with
// cin_block = DefaultCinBlock(params, nr, with_phases).
PackedConv PackConv(const ConvParams& params, int nr, bool with_phases, float* dst);

// The few-output kernel's packing (kernels/simd/conv_few_out_inl.h): one block, weights
// [taps][out_channels][in_channels rounded up to 16] (zero-filled), bias [out_channels rounded
// up to 16]. For out_channels <= kFewOutChannels.
size_t PackedConvFewOutFloats(const ConvParams& params);
PackedConv PackConvFewOut(const ConvParams& params, float* dst);

// Bytes of one output-channel block's weights for one input-channel block that the kernels
// keep in cache (about a quarter of a 1 MiB L2, leaving room for the input rows and the
// output partial sums the same pass touches).
inline constexpr size_t kConvWeightBlockBytes = 256 * 1024;

// Input channels per pass: the most whose weights (taps x cin_block x nr floats; the fused
// upsample-conv's interior reads 2x2 phase kernels) fit kConvWeightBlockBytes, at least 16,
// split evenly across the passes; in_channels when they all fit.
int DefaultCinBlock(const ConvParams& params, int nr, bool with_phases);

// The weights (of every block) beyond which they are taken not to stay in cache from one output
// row to the next (about half an L2: 1 MiB on Zen 4 and 5, 2 MiB on Sapphire Rapids).
inline constexpr double kRowsFirstWeightBytes = 512.0 * 1024.0;

// Whether a plain convolution over `in` with `out_rows` output rows reads fewer bytes rows
// first (ConvArgs::rows_first): then the input once and the weights once per output row (once
// in all where they fit kRowsFirstWeightBytes); else the weights once and the input once per
// block. Never for one block. (SceneEDNet's conv1 at 540x960 with blocks of 16 channels: 33 MB
// of input for each of 8 blocks against 0.3 MB of weights in all.)
bool ConvRowsFirst(const PackedConv& p, const ConstTensorView& in, int out_rows);

}  // namespace sfrt
