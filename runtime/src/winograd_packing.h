// Winograd F(m x m, 3 x 3) weights for the SIMD tiers (kernels/winograd_job.h), transformed and
// packed at Session::Create into memory the session owns, and the rule that decides at plan time
// which convolutions take the Winograd path.
#pragma once

#include <cstddef>

#include "kernels/winograd_job.h"
#include "sfrt/model.h"

namespace sfrt {

// True for the convolutions where Winograd pays: 3x3, stride 1, with at least
// kWinogradMinChannels input and output channels (the transforms cost O(channels) per tile, the
// products O(cin x cout), so with few channels the transforms and the scratch traffic dominate).
// In SceneEDNet at full width: conv4 (512 -> 1024) and conv5 (1024 -> 1024); the 64 -> 3 output
// convolution stays direct.
inline constexpr int kWinogradMinChannels = 64;
bool WinogradApplies(const ConvParams& params);

// Floats for U, bias and the zero block of `params` with tile side m and blocks of nr channels.
size_t PackedWinogradFloats(const ConvParams& params, int m, int nr);

// U[p][block][ci][j] = (G g GT)[p] of weight (ci, block * nr + j), computed in double and rounded
// once; writes PackedWinogradFloats floats at dst (64-byte aligned) and returns the descriptor.
PackedWinograd PackWinograd(const ConvParams& params, int m, int nr, float* dst);

// The fused upsample(2x) -> 3x3 convolution as F(2x2, 2x2) over the four phase kernels
// (WinogradPhaseTransform): U[p][block][ci][j] for column n = block * nr + j = phase *
// phase_stride + co, each phase kernel built from the 3x3 weights as conv_packing.h describes.
// WinogradUpApplies: where it pays (enough channels for the products to dominate).
bool WinogradUpApplies(const ConvParams& params);
size_t PackedWinogradUpFloats(const ConvParams& params, int nr);
PackedWinograd PackWinogradUp(const ConvParams& params, int nr, float* dst);

}  // namespace sfrt
