// What an optimised convolution kernel is given: weights packed at Session::Create, and one
// call's views. Shared by every SIMD tier (kernels/<isa>/) and the session that dispatches them.
//
// Packed layout ("output-channel blocked"): output channels are split into blocks of `nr`
// (nr = vectors per tile x SIMD lanes); the last block is zero-padded. For each block, taps
// (ky, kx) in row-major order, then input channels, then the block's nr output channels:
//   weights[block][ky * kernel_w + kx][ci][nr]          bias[block * nr + j]
// The fused upsample-conv adds, per output phase (py, px) of a nearest-2x-upsampled input,
// the 2x2 kernel over the low-resolution map whose taps are sums of the 3x3 taps:
//   phase_weights[py * 2 + px][block][ty * 2 + tx][ci][nr]
// where, along each axis, phase 0 gives tap 0 = w0 + w1 and tap 1 = w2, and phase 1 gives
// tap 0 = w0 and tap 1 = w1 + w2 (see docs in runtime/src/conv_packing.h).
#pragma once

#include <cstddef>

#include "kernels/tensor_view.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"

namespace sfrt {

inline constexpr int kMaxConvTaps = 64;  // kernel_h * kernel_w the SIMD kernels accept

struct PackedConv {
  int in_channels = 0;
  int out_channels = 0;
  int kernel_h = 0;
  int kernel_w = 0;
  int stride_h = 1;
  int stride_w = 1;
  int nr = 0;      // output channels per block
  int blocks = 0;  // ceil(out_channels / nr)
  // Input channels summed per pass (cache blocking): the kernels walk output-channel block ->
  // input-channel block of this many channels -> rows -> register tiles, so one block's
  // weights (taps x cin_block x nr floats) stay in L2 while every row of the range uses them
  // (with ConvArgs::rows_first, each row in turn goes through that walk).
  // Passes after the first add to the partial sums already in the output; the last applies
  // the activation. Any value from 1 to in_channels is correct (tests use odd ones).
  int cin_block = 0;
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  const float* weights = nullptr;        // [blocks][taps][in_channels][nr], 64-byte aligned
  const float* bias = nullptr;           // [blocks * nr]
  const float* phase_weights = nullptr;  // [4][blocks][4][in_channels][nr], or null
  // The few-output kernel's layout instead (kernels/simd/conv_few_out_inl.h): one block,
  // [taps][out_channels][few_ci_stride], zero beyond in_channels; null for the others.
  const float* few_weights = nullptr;
  int few_ci_stride = 0;  // in_channels rounded up to 16
};

// One kernel call. For a plain convolution `in` is the convolution's input. For the fused
// upsample(2x, nearest) -> crop -> 3x3 stride-1 convolution, `in` is the low-resolution map and
// the convolution reads C, the upsampled map with `crop_top` rows and `crop_left` columns
// removed, of size c_height x c_width (zero outside it).
struct ConvArgs {
  const PackedConv* conv = nullptr;
  ConstTensorView in;
  TensorView out;
  Padding pads;  // in effect at this size (only top/left are read)
  int crop_top = 0;
  int crop_left = 0;
  int c_height = 0;
  int c_width = 0;
  // Fused upsample-conv: leave the interior pixels (whose 3x3 window lies inside C) untouched,
  // computing only the border; set when the Winograd phase path writes the interior.
  bool skip_interior = false;
  // Plain convolutions: each output row through every block of the call before the next row
  // (the row's inputs read once, the blocks' weights once per row unless they stay in cache)
  // instead of each block through every row (its weights read once, the inputs once per
  // block). The session sets it where it reads fewer bytes (conv_packing.h, ConvRowsFirst).
  bool rows_first = false;
};

// Computes output rows [row_begin, row_end) of args.out, output-channel blocks
// [blk_begin, blk_end) only. Safe to call concurrently on disjoint (rows x blocks) rectangles.
using ConvRowsFn = void (*)(const ConvArgs& args, int row_begin, int row_end, int blk_begin,
                            int blk_end);

// One register tile shape of one ISA.
struct ConvKernelVariant {
  int nr = 0;  // output channels per block
  ConvRowsFn conv = nullptr;
  ConvRowsFn upconv = nullptr;
  const char* conv_name = "";
  const char* upconv_name = "";
};

// An ISA's kernels, by increasing nr. A layer uses the narrowest variant whose nr covers its
// output channels, or the widest (PickConvVariant).
inline constexpr int kMaxConvVariants = 4;
// Layers with at most this many output channels (and at least kFewOutMinInputs inputs) use the
// ISA's few-output kernel, vectorised over input channels, where it has one.
inline constexpr int kFewOutChannels = 4;
inline constexpr int kFewOutMinInputs = 16;
struct IsaConvKernels {
  ConvKernelVariant variants[kMaxConvVariants];
  int count = 0;
  ConvRowsFn few_out = nullptr;  // plain convolutions with few outputs (few_weights)
  const char* few_out_name = "";
};

inline const ConvKernelVariant& PickConvVariant(const IsaConvKernels& k, int out_channels) {
  for (int i = 0; i < k.count; ++i) {
    if (out_channels <= k.variants[i].nr) return k.variants[i];
  }
  return k.variants[k.count - 1];
}

// The kernels of `isa`, or null for kRef, kAuto and ISAs this build has no kernels for (whether
// the CPU can run them is IsaSupported's question).
const IsaConvKernels* ConvKernelsFor(Isa isa);

namespace avx2 {
const IsaConvKernels& ConvKernels();
}
namespace avx512 {
const IsaConvKernels& ConvKernels();
}
namespace neon {
const IsaConvKernels& ConvKernels();
}

}  // namespace sfrt
