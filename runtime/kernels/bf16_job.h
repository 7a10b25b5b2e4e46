// What a bf16 convolution kernel is given, for every tier (the scalar reference in
// kernels/ref/conv2d_bf16_ref.cc and the SIMD kernels), and the arithmetic they share.
//
// Bf16 arithmetic (docs/model-format.md, "Bf16 arithmetic"): activations between bf16 layers are
// bfloat16 (the upper 16 bits of a float32), weights are the model's float32 weights rounded to
// bfloat16 at Session::Create. For output pixel p and channel o:
//   acc = sum over the taps inside the input of x * w     (each product exact in float32; the
//                                                          sum in float32, in an order each
//                                                          tier chooses)
//   y   = activation(acc + bias[o])                        (float32)
// and the output is y (float32), or y rounded to bfloat16 (to nearest, ties to even) when the
// next convolution is bf16 too. The sum's order is free, so tiers agree to float32 rounding of
// the sum, not bit for bit (the int8 path is the bit-exact one); the reference sums in double.
//
// The fused nearest-2x upsample (+ crop) -> 3x3 convolution reads C as int8_job.h describes;
// with phase kernels (PackedBf16Conv::phase_weights), every output pixel whose 3x3 window lies
// inside C is computed from the 2x2 kernel of its phase over the low-resolution map, the kernel
// being the 3x3 taps that read the same low-resolution pixel summed in float32 and then rounded
// to bfloat16 (4/9 of the multiply-accumulates).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "kernels/tensor_view.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"

namespace sfrt {

// float32 -> bfloat16, to nearest with ties to even; a NaN stays a (quiet) NaN.
inline uint16_t FloatToBf16(float f) {
  uint32_t bits;
  std::memcpy(&bits, &f, sizeof(bits));
  if ((bits & 0x7fffffffu) > 0x7f800000u) return static_cast<uint16_t>((bits >> 16) | 0x40u);
  bits += 0x7fffu + ((bits >> 16) & 1u);
  return static_cast<uint16_t>(bits >> 16);
}

inline float Bf16ToFloat(uint16_t h) {
  const uint32_t bits = static_cast<uint32_t>(h) << 16;
  float f;
  std::memcpy(&f, &bits, sizeof(f));
  return f;
}

// The per-channel epilogue of the bf16 arithmetic above (bias, then activation, in float32),
// written once for the scalar tiers (the reference, the AMX tiles' epilogue).
inline float Bf16Epilogue(float acc, float bias, Activation act, float slope) {
  float y = acc + bias;
  if (act == Activation::kLeakyRelu) {
    y = y < 0.0f ? y * slope : y;
  } else if (act == Activation::kRelu) {
    y = y > 0.0f ? y : 0.0f;
  }
  return y;
}

// Bytes a kernel may read past the last pixel of a bf16 tensor: the SIMD kernels read input
// channels in pairs (a 32-bit group), so with an odd channel count they read one value past each
// pixel (the next pixel's first channel, or past the tensor's end) and multiply it by a zero
// weight. That value must be finite (0 * inf is NaN): the session leaves this much room after
// every bf16 tensor and zeroes it when it writes the tensor.
inline constexpr size_t kBf16TensorSlack = 64;

// One bf16 convolution as the session prepared it at Create.
struct PackedBf16Conv {
  int in_channels = 0;
  int out_channels = 0;
  int kernel_h = 0;
  int kernel_w = 0;
  int stride_h = 1;
  int stride_w = 1;
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  bool out_float = false;  // float32 output, else bfloat16
  // Per output channel, blocks * nr values (zero beyond out_channels; out_channels when nr == 0).
  const float* bias = nullptr;
  // The weights rounded to bf16, HWIO (what the reference reads).
  const uint16_t* weights_hwio = nullptr;
  // The SIMD layout, for kernels with nr > 0 (null when nr == 0): output channels in blocks of
  // nr (the last zero-padded), input channels in pairs (cin2 = in_channels rounded up to 2,
  // zero-padded): weights[block][tap][ci / 2][nr][ci % 2] (64-byte aligned).
  int nr = 0;
  int blocks = 1;
  int cin2 = 0;
  const uint16_t* weights = nullptr;
  // Phase kernels (see above), or null: [4][2][2][in][out] bf16 (the reference), and for nr > 0
  // the SIMD layout, phase p's part starting at p * blocks * 4 * cin2 * nr elements.
  const uint16_t* phase_weights_hwio = nullptr;
  const uint16_t* phase_weights = nullptr;
  // Convolutions with few outputs (at most kBf16FewOutChannels, at least kBf16FewOutMinInputs
  // inputs, nr > 0), for kernels vectorised over input channels: few_weights[tap][o][ci], each
  // (tap, o) row few_ci_stride values (in_channels rounded up to 32, zero-filled); null
  // otherwise.
  const uint16_t* few_weights = nullptr;
  int few_ci_stride = 0;
  // AMX: the 1 x 4 tile blocking even where the 2 x 2 applies (KernelTuning::amx_pairs false).
  bool amx_1x4 = false;
};
inline constexpr int kBf16FewOutChannels = 4;
inline constexpr int kBf16FewOutMinInputs = 16;

// One kernel call; the upsample fields are Int8ConvArgs's (int8_job.h).
struct Bf16ConvArgs {
  const PackedBf16Conv* conv = nullptr;
  ConstBf16View in;
  Bf16View out_bf16;   // when !conv->out_float
  TensorView out_f32;  // when conv->out_float
  Padding pads;
  bool upsampled = false;
  int crop_top = 0;
  int crop_left = 0;
  int c_height = 0;
  int c_width = 0;
  // Output columns [col_begin, col_end) of each row (clamped to the output's width): the kernels
  // compute only those (a caller splitting rows by columns, as the AMX kernels hand their border
  // columns to the AVX512_BF16 ones), with or without `upsampled`.
  int col_begin = 0;
  int col_end = 1 << 30;
};

// Computes output rows [row_begin, row_end), output-channel blocks [blk_begin, blk_end) (the
// reference has one block). Safe to call concurrently on disjoint (rows x blocks) rectangles.
using Bf16ConvRowsFn = void (*)(const Bf16ConvArgs& args, int row_begin, int row_end, int blk_begin,
                                int blk_end);

struct IsaBf16Kernels {
  int nr = 0;
  Bf16ConvRowsFn conv = nullptr;    // any kernel size up to kMaxBf16Taps, any stride
  Bf16ConvRowsFn upconv = nullptr;  // fused nearest-2x upsample (+ crop) -> 3x3 stride 1
  const char* conv_name = "";
  const char* upconv_name = "";
  // Non-empty when `conv` computes the few-output layers (PackedBf16Conv::few_weights) with a
  // kernel of their own: its name.
  const char* few_out_name = "";
};
inline constexpr int kMaxBf16Taps = 64;

// The bf16 kernels of `isa` that this CPU can run, or null (the session then uses the
// reference, ref::Conv2dBf16Rows).
const IsaBf16Kernels* Bf16KernelsFor(Isa isa);

// Rows [row_begin, row_end) of a float32 tensor to bf16, FloatToBf16 per value (the step before
// a bf16 convolution that reads a float32 tensor). Safe on disjoint row ranges.
using ToBf16RowsFn = void (*)(const ConstTensorView& in, const Bf16View& out, int row_begin,
                              int row_end);
// The ISA's vectorised conversion (the same bits as FloatToBf16) where it has bf16 kernels, else
// ref::ToBf16Rows. `name` is what steps() shows.
struct ToBf16Kernel {
  ToBf16RowsFn fn = nullptr;
  const char* name = "";
};
ToBf16Kernel ToBf16KernelFor(Isa isa);

namespace avx512 {
// Null when the CPU lacks AVX512_BF16.
const IsaBf16Kernels* Bf16Kernels();
void ToBf16Rows(const ConstTensorView& in, const Bf16View& out, int row_begin, int row_end);
}  // namespace avx512
namespace avx512 {
// The AMX bf16 kernels (tdpbf16ps; kernels/simd/amx_driver_inl.h), with the AVX512_BF16 kernels
// for what the tiles leave: null unless the CPU has AVX512_BF16, AMX-TILE and AMX-BF16 and the OS
// and Linux let sfrt use the tiles (src/cpu_features.h, amx_bf16); null in builds without them.
const IsaBf16Kernels* Bf16KernelsAmx();
}  // namespace avx512
namespace amx {
// The AMX bf16 kernels' blocking over the scalar emulation of the tiles (int8_job.h's
// Int8KernelsEmulated, for bf16; its violations counter counts these too).
const IsaBf16Kernels* Bf16KernelsEmulated();
}  // namespace amx
namespace neon {
// Null when the CPU lacks the BF16 extension (Armv8.6 bfdot).
const IsaBf16Kernels* Bf16Kernels();
void ToBf16Rows(const ConstTensorView& in, const Bf16View& out, int row_begin, int row_end);
}  // namespace neon

}  // namespace sfrt
