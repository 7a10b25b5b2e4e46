// What an int8 convolution kernel is given, for every tier (the scalar reference in
// kernels/ref/conv2d_int8_ref.cc and the SIMD kernels), and the arithmetic they all share.
//
// Int8 arithmetic (docs/model-format.md, "Int8 arithmetic"): activations are uint8 with a
// per-tensor scale and zero point, weights int8 symmetric per output channel. For output pixel p
// and channel o, over the taps whose input pixel lies inside the input (padding is real zero):
//   acc = sum (x_q - in_zero_point) * w_q                         (int32, exact)
//   y   = float(acc) * multiplier[o]                               (one float multiply)
//   y   = y + bias[o]                                              (one float add, not fused)
//   y   = activation(y)        leaky: y < 0 ? y * slope : y;  relu: y > 0 ? y : 0
// and the output is y (float32), or, quantised,
//   t   = min(max(y * out_inv_scale, -512), 512)
//   q   = clamp(round_half_even(t) + out_zero_point, 0, 255)
// Every step is a single IEEE-754 operation in round-to-nearest-even (int32 -> float included),
// so every tier produces the same bytes: the kernels must not fuse the multiply and the add (the
// runtime is compiled without floating-point contraction) and use the rounding conversion
// (cvtps2dq, fcvtns), not truncation. multiplier[o] = input scale * weight_scales[o] and
// out_inv_scale = 1 / output scale are computed once, at Session::Create, in float.
//
// The fused nearest-2x upsample (+ crop) -> convolution reads C, the upsampled map with crop_top
// rows and crop_left columns removed (c_height x c_width): C(cy, cx) is
// in((cy + crop_top) / 2, (cx + crop_left) / 2). It is the same integer sum as upsampling the
// bytes first, so its results are those of the unfused reference, bit for bit, unless the
// convolution has phase weights (ConvParams::phase_weights_q): then every output pixel whose
// 3x3 window lies inside C (cy0 = oy - pads.top >= 0, cy0 + 3 <= c_height, likewise for x)
// is computed from the 2x2 kernel of its phase over the low-resolution map instead:
//   a = cy0 + crop_top, b = cx0 + crop_left, phase p = (a & 1) * 2 + (b & 1),
//   acc = sum over (ty, tx, ci) of (in(a / 2 + ty, b / 2 + tx)[ci] - in_zero_point)
//                                  * phase_w[p][ty][tx][ci][o]
// with phase_multiplier[p][o] in the epilogue (4/9 of the multiply-accumulates); the other
// pixels use the 3x3 weights as above. The phase kernels are the 3x3 taps that read the same
// low-resolution pixel summed in float, then quantised (the exporter does it), so this is the
// same function as the 3x3 form up to quantisation.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "kernels/tensor_view.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"

namespace sfrt {
namespace simd {
struct DotEpilogue;  // kernels/simd/dot_driver_inl.h
}  // namespace simd

// Bytes a kernel may read past the last pixel of a uint8 tensor: the SIMD kernels read input
// channels four at a time, so a tensor whose channel count is not a multiple of 4 is read up to
// 3 bytes beyond its end (multiplied by zero weights). The session's arena leaves this much
// room after every uint8 tensor.
inline constexpr size_t kInt8TensorSlack = 64;

// The per-channel epilogue of the int8 arithmetic above, written once for every tier.
inline float Int8Dequantize(int32_t acc, float multiplier, float bias, Activation act,
                            float slope) {
  float y = static_cast<float>(acc) * multiplier;
  y = y + bias;
  if (act == Activation::kLeakyRelu) {
    y = y < 0.0f ? y * slope : y;
  } else if (act == Activation::kRelu) {
    y = y > 0.0f ? y : 0.0f;
  }
  return y;
}

inline uint8_t Int8Quantize(float y, float inv_scale, int zero_point) {
  float t = y * inv_scale;
  // Written as x86's maxps/minps behave (the second operand when unordered), so a NaN input
  // quantises to 0 on every tier, and nothing converts NaN to int.
  t = t > -512.0f ? t : -512.0f;
  t = t < 512.0f ? t : 512.0f;
  const int q = static_cast<int>(std::nearbyint(t)) + zero_point;
  return static_cast<uint8_t>(q < 0 ? 0 : (q > 255 ? 255 : q));
}

// One int8 convolution as the session prepared it at Create.
struct PackedInt8Conv {
  int in_channels = 0;
  int out_channels = 0;
  int kernel_h = 0;
  int kernel_w = 0;
  int stride_h = 1;
  int stride_w = 1;
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  int in_zero_point = 0;
  // Output: float32 when out_float, else uint8 quantised with out_inv_scale / out_zero_point.
  bool out_float = false;
  float out_inv_scale = 1.0f;
  int out_zero_point = 0;
  // Per output channel, blocks * nr values (zero beyond out_channels; out_channels values when
  // nr == 0).
  const float* multiplier = nullptr;
  const float* bias = nullptr;
  // The model's weights, HWIO int8 (what the reference reads).
  const int8_t* weights_hwio = nullptr;
  // The SIMD layout, for kernels with nr > 0 (null when nr == 0): output channels in blocks of
  // nr (the last zero-padded), input channels in groups of 4 (cin4 = in_channels rounded up to
  // 4, zero-padded):
  //   weights[block][tap][ci / 4][nr][ci % 4]        (int8, 64-byte aligned)
  //   tap_sums[block][tap][nr] = sum over ci of weights (int32), for the zero-point correction:
  //   sum (x - z) * w = sum x * w - z * (sum of the tap_sums of the taps inside the input).
  int nr = 0;
  int blocks = 1;
  int cin4 = 0;
  const int8_t* weights = nullptr;
  const int32_t* tap_sums = nullptr;
  // Phase kernels (see above), or all null: the file's [4][2][2][in][out] (the reference);
  // phase_multiplier[p * lanes + o] with lanes = blocks * nr (out_channels when nr == 0); for
  // nr > 0 the SIMD layout, phase p's part starting at p * blocks * 4 * cin4 * nr bytes and
  // p * blocks * 4 * nr sums: [block][tap][ci / 4][nr][ci % 4] and [block][tap][nr], 4 taps
  // (ty * 2 + tx).
  const int8_t* phase_weights_hwio = nullptr;
  const float* phase_multiplier = nullptr;
  const int8_t* phase_weights = nullptr;
  const int32_t* phase_tap_sums = nullptr;
  // Convolutions with few outputs (at most kInt8FewOutChannels, at least kInt8FewOutMinInputs
  // inputs, nr > 0), for kernels vectorised over input channels: few_weights[tap][o][ci], each
  // (tap, o) row few_ci_stride bytes (in_channels rounded up to 64, zero-filled); null
  // otherwise. tap_sums are there as well.
  const int8_t* few_weights = nullptr;
  int few_ci_stride = 0;
  // Set by the session where a kernel table has a kernel for narrow convolutions (at most 4
  // inputs and 4 outputs, int8_packing.h's Int8NarrowConv; nr > 0) and KernelTuning::few_out
  // allows it.
  bool narrow = false;
  // AMX: the 1 x 4 tile blocking even where the 2 x 2 applies (KernelTuning::amx_pairs false).
  bool amx_1x4 = false;
};
inline constexpr int kInt8FewOutChannels = 4;
inline constexpr int kInt8FewOutMinInputs = 16;

// One kernel call; see the fused upsample above for the `upsampled` fields.
struct Int8ConvArgs {
  const PackedInt8Conv* conv = nullptr;
  ConstByteView in;
  ByteView out_u8;     // when !conv->out_float
  TensorView out_f32;  // when conv->out_float
  Padding pads;        // in effect at this size (only top/left are read)
  bool upsampled = false;
  int crop_top = 0;
  int crop_left = 0;
  int c_height = 0;
  int c_width = 0;
  // Output columns [col_begin, col_end) of each row (clamped to the output's width): the kernels
  // compute only those (a caller splitting rows by columns, as the AMX kernels hand their border
  // columns to the VNNI ones), with or without `upsampled`.
  int col_begin = 0;
  int col_end = 1 << 30;
};

// Computes output rows [row_begin, row_end), output-channel blocks [blk_begin, blk_end) (the
// reference has one block). Safe to call concurrently on disjoint (rows x blocks) rectangles.
using Int8ConvRowsFn = void (*)(const Int8ConvArgs& args, int row_begin, int row_end, int blk_begin,
                                int blk_end);

// An ISA's int8 kernels (one register tile; nr output channels per block).
struct IsaInt8Kernels {
  int nr = 0;
  Int8ConvRowsFn conv = nullptr;    // any kernel size up to kMaxInt8Taps, any stride
  Int8ConvRowsFn upconv = nullptr;  // fused nearest-2x upsample (+ crop) -> 3x3 stride 1
  const char* conv_name = "";
  const char* upconv_name = "";
  // Non-empty when `conv` computes the few-output layers (PackedInt8Conv::few_weights) with a
  // kernel of their own: its name.
  const char* few_out_name = "";
  // Non-empty when `conv` computes the narrow convolutions (PackedInt8Conv::narrow) with a
  // kernel of their own: its name.
  const char* narrow_name = "";
};
inline constexpr int kMaxInt8Taps = 64;

// The int8 kernels of `isa` that this CPU can run, or null (the session then uses the
// reference, ref::Conv2dInt8Rows).
const IsaInt8Kernels* Int8KernelsFor(Isa isa);

namespace avx512 {
// Null when the CPU lacks AVX-512 VNNI.
const IsaInt8Kernels* Int8Kernels();
// The AMX kernels (tdpbusd on 16x64-byte tiles; kernels/simd/amx_driver_inl.h). Their
// border columns and the layers they leave (the fused upsample's, the few-output ones) run on the
// VNNI kernels. Null unless the CPU has AVX-512 VNNI, AMX-TILE and AMX-INT8, the OS enables the
// tile state, CPUID leaf 0x1D lists palette 1 with 8 tiles of 16 rows x 64 bytes, and Linux
// grants the tile data permission (arch_prctl ARCH_REQ_XCOMP_PERM); null in builds without them.
const IsaInt8Kernels* Int8KernelsAmx();
// The AMX kernels' epilogue of one stored C tile (their tile policy's Finish: AVX-512 code
// without a tile instruction, simd::AmxFinishScalar's arithmetic), int8 (`quantized`) or bf16,
// for tests: it runs on a CPU with AVX-512 VNNI and AVX512_BF16 but no AMX, where the AMX kernels
// do not. Null on other CPUs and in builds without the AMX kernels.
using AmxTileFinishFn = void (*)(bool quantized, const int32_t* sums, const int32_t* init,
                                 const simd::DotEpilogue& e, void* out, ptrdiff_t out_step);
AmxTileFinishFn AmxTileFinish();
}  // namespace avx512
namespace amx {
// The AMX kernels' blocking and packing over a scalar emulation of the tile registers and of
// tdpbusd (every CPU; tests): the same bytes as the reference. Their border columns and the
// layers the AMX kernels leave run on the reference. `violations` counts the tile operations
// that broke the rules AMX enforces (tile shapes beyond palette 1, a tdpbusd whose operand
// shapes disagree): a test expects none.
const IsaInt8Kernels* Int8KernelsEmulated();
long EmulatedTileViolations();
}  // namespace amx

// Rows [row_begin, row_end) of a float32 tensor to uint8, Int8Quantize per value (the step
// before an int8 convolution that reads a float32 tensor). Safe on disjoint row ranges.
using QuantizeRowsFn = void (*)(const ConstTensorView& in, float inv_scale, int zero_point,
                                const ByteView& out, int row_begin, int row_end);
// The ISA's vectorised quantisation (the same bytes as Int8Quantize): avx512 where the CPU runs
// its int8 kernels (VNNI), neon always; else ref::QuantizeRows. `name` is what steps() shows.
struct QuantizeKernel {
  QuantizeRowsFn fn = nullptr;
  const char* name = "";
};
QuantizeKernel QuantizeKernelFor(Isa isa);
namespace avx512 {
void QuantizeRows(const ConstTensorView& in, float inv_scale, int zero_point, const ByteView& out,
                  int row_begin, int row_end);
}
namespace neon {
void QuantizeRows(const ConstTensorView& in, float inv_scale, int zero_point, const ByteView& out,
                  int row_begin, int row_end);
}  // namespace neon

}  // namespace sfrt
