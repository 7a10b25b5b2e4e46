// NEON bf16 convolution kernels with bfdot by element (Armv8.6 BF16 extension; compiled with
// -march=armv8.2-a+bf16 only in this translation unit; runtime/CMakeLists.txt), run only where
// HWCAP2 says so: the arithmetic is kernels/bf16_job.h's, the loops
// kernels/simd/dot_driver_inl.h's; this file has the vocabulary.
//
// Blocks of 16 output channels (PackBf16Conv with nr 16): one group of 2 input channels of a tap
// is 64 bytes, four 16-byte vectors of 4 output channels x 2 input channels, which is what
// vbfdotq_laneq_f32 consumes (lane i += w[2i] * x[2 * lane] + w[2i + 1] * x[2 * lane + 1]).
// Vectors of 4 float32 channels; the tiles are 5x4 (20 accumulators, 5 input and 4 weight
// vectors of the 32), 6x3, 8x2 and 8x1. One 16-byte load of a pixel serves four groups of input
// channels (by lane); a last partial load reads only the groups that exist (4-byte units, so at
// most 2 bytes past the pixel's channels when in_channels is odd, multiplied by zero weights).
// bfdot's products are exact; it flushes denormals to zero and rounds its sums to odd (no
// FEAT_EBF16), well inside the tolerance of bf16_job.h's float32 sums. The epilogue adds the
// bias (not fused), applies the activation and stores float32 or bf16 with bfcvtn (to nearest
// even under the default FPCR: FloatToBf16 for every finite value).
#include <arm_neon.h>
#include <sys/auxv.h>

#include <cstdint>
#include <cstring>

#include "kernels/bf16_job.h"
#include "kernels/simd/dot_driver_inl.h"

#ifndef HWCAP2_BF16
#define HWCAP2_BF16 (1 << 14)
#endif

namespace sfrt::neon {
namespace {

// The bf16 vocabulary of kernels/simd/dot_driver_inl.h.
struct V {
  using Conv = PackedBf16Conv;
  using Acc = float32x4_t;
  static constexpr int kLanes = 4;
  static constexpr int kNr = 16;               // output channels per block
  static constexpr int kGroupElems = 2 * kNr;  // bf16 weights of one group (64 bytes)
  static Acc Zero() { return vdupq_n_f32(0.0f); }

  // `groups` (1..3) groups of 2 input channels from p, the other lanes zero.
  static bfloat16x8_t LoadGroups(const uint16_t* p, int groups) {
    uint32_t last;
    uint16x8_t x;
    if (groups == 2) {
      x = vcombine_u16(vld1_u16(p), vdup_n_u16(0));
    } else if (groups == 1) {
      std::memcpy(&last, p, sizeof(last));
      x = vreinterpretq_u16_u32(vsetq_lane_u32(last, vdupq_n_u32(0), 0));
    } else {
      std::memcpy(&last, p + 4, sizeof(last));
      x = vcombine_u16(vld1_u16(p), vreinterpret_u16_u32(vset_lane_u32(last, vdup_n_u32(0), 0)));
    }
    return vreinterpretq_bf16_u16(x);
  }

  // One group of 2 input channels (lane L of each pixel's x) with its 64 bytes of weights.
  template <int L, int MR, int NV>
  [[gnu::always_inline]] static inline void Step(float32x4_t (&acc)[MR][NV],
                                                 const bfloat16x8_t (&x)[MR], const uint16_t* w) {
    // The weights of one group at a time: scheduled together, the four groups' 16 vectors
    // would push the accumulators out of the registers.
    asm volatile("" ::: "memory");
    bfloat16x8_t wv[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) wv[v] = vreinterpretq_bf16_u16(vld1q_u16(w + v * 8));
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) acc[m][v] = vbfdotq_laneq_f32(acc[m][v], wv[v], x[m], L);
    }
  }

  // The sums of MR pixels x NV vectors (dot_driver_inl.h). Its own function, as the other
  // dot-product kernels', so the accumulators stay in registers.
  template <int MR, int NV>
  [[gnu::noinline]] static void Accumulate(const uint16_t* const* xs, const uint16_t* const* ws,
                                           int taps, int groups, const Acc* init, Acc* sums) {
    float32x4_t acc[MR][NV];
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) acc[m][v] = init[v];
    }
    const int quads = groups / 4, rest = groups % 4;
    for (int t = 0; t < taps; ++t) {
      const uint16_t* const* x = xs + t * MR;
      const uint16_t* w = ws[t];
      bfloat16x8_t xv[MR];
      for (int q = 0; q < quads; ++q) {
#pragma GCC unroll 16
        for (int m = 0; m < MR; ++m) xv[m] = vreinterpretq_bf16_u16(vld1q_u16(x[m] + 8 * q));
        Step<0>(acc, xv, w);
        Step<1>(acc, xv, w + kGroupElems);
        Step<2>(acc, xv, w + 2 * kGroupElems);
        Step<3>(acc, xv, w + 3 * kGroupElems);
        w += 4 * kGroupElems;
      }
      if (rest > 0) {
#pragma GCC unroll 16
        for (int m = 0; m < MR; ++m) xv[m] = LoadGroups(x[m] + 8 * quads, rest);
        Step<0>(acc, xv, w);
        if (rest > 1) Step<1>(acc, xv, w + kGroupElems);
        if (rest > 2) Step<2>(acc, xv, w + 2 * kGroupElems);
      }
    }
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) sums[m * NV + v] = acc[m][v];
    }
  }

  // Bias, activation and (bf16 output) the rounding to nearest even of one pixel's NV vectors
  // into `out` (the pixel's first channel of the block: float or bf16), e.valid channels.
  template <int NV>
  static void Finish(const Acc* acc, const simd::DotEpilogue& e, void* out) {
    const float32x4_t zero = vdupq_n_f32(0.0f);
    float32x4_t y[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) {
      y[v] = vaddq_f32(acc[v], vld1q_f32(e.bias + v * kLanes));
      if (e.act == Activation::kLeakyRelu) {
        const uint32x4_t negative = vcltq_f32(y[v], zero);
        y[v] = vbslq_f32(negative, vmulq_f32(y[v], vdupq_n_f32(e.slope)), y[v]);
      } else if (e.act == Activation::kRelu) {
        const uint32x4_t positive = vcgtq_f32(y[v], zero);
        y[v] = vbslq_f32(positive, y[v], zero);
      }
    }
    if (e.out_float) {
      float* o = static_cast<float*>(out);
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) {
        const int left = e.valid - v * kLanes;
        if (left >= kLanes) {
          vst1q_f32(o + v * kLanes, y[v]);
        } else {
          float tmp[kLanes];
          vst1q_f32(tmp, y[v]);
          for (int i = 0; i < left; ++i) o[v * kLanes + i] = tmp[i];
        }
      }
      return;
    }
    // bfcvtn / bfcvtn2: two vectors into one of 8 bf16 channels.
    uint16x8_t h[(NV + 1) / 2];
#pragma GCC unroll 2
    for (int k = 0; k < (NV + 1) / 2; ++k) {
      bfloat16x8_t b = vcvtq_low_bf16_f32(y[2 * k]);
      if (2 * k + 1 < NV) b = vcvtq_high_bf16_f32(b, y[2 * k + 1]);
      h[k] = vreinterpretq_u16_bf16(b);
    }
    uint16_t* o = static_cast<uint16_t*>(out);
    if (e.valid >= NV * kLanes) {
#pragma GCC unroll 2
      for (int k = 0; k < NV / 2; ++k) vst1q_u16(o + 8 * k, h[k]);
      if constexpr (NV % 2 != 0) vst1_u16(o + 8 * (NV / 2), vget_low_u16(h[NV / 2]));
    } else {
      uint16_t tmp[kNr];
#pragma GCC unroll 2
      for (int k = 0; k < (NV + 1) / 2; ++k) vst1q_u16(tmp + 8 * k, h[k]);
      for (int i = 0; i < e.valid; ++i) o[i] = tmp[i];
    }
  }
};

// FloatToBf16 of 4 values in integer arithmetic (the same bits whatever FPCR says): bits +
// 0x7fff + bit 16, upper half; a NaN keeps its upper half, quieted.
inline uint16x4_t ToBf16x4(float32x4_t v) {
  const uint32x4_t bits = vreinterpretq_u32_f32(v);
  const uint32x4_t lsb = vandq_u32(vshrq_n_u32(bits, 16), vdupq_n_u32(1));
  const uint32x4_t rounded = vaddq_u32(bits, vaddq_u32(lsb, vdupq_n_u32(0x7fff)));
  const uint32x4_t quiet_nan = vorrq_u32(bits, vdupq_n_u32(0x400000));
  const uint32x4_t ordered = vceqq_f32(v, v);  // false for NaN
  return vshrn_n_u32(vbslq_u32(ordered, rounded, quiet_nan), 16);
}

}  // namespace

void ToBf16Rows(const ConstTensorView& in, const Bf16View& out, int row_begin, int row_end) {
  const ptrdiff_t n = static_cast<ptrdiff_t>(in.width) * in.channels;  // a row is dense
  for (int y = row_begin; y < row_end; ++y) {
    const float* src = in.pixel(y, 0);
    uint16_t* dst = out.pixel(y, 0);
    ptrdiff_t i = 0;
    for (; i + 8 <= n; i += 8) {
      vst1_u16(dst + i, ToBf16x4(vld1q_f32(src + i)));
      vst1_u16(dst + i + 4, ToBf16x4(vld1q_f32(src + i + 4)));
    }
    for (; i < n; ++i) dst[i] = FloatToBf16(src[i]);
  }
}

const IsaBf16Kernels* Bf16Kernels() {
  // The tiles' pixels for 1, 2, 3 and 4 valid vectors: 8x1, 8x2, 6x3, 5x4.
  static constexpr IsaBf16Kernels kKernels = {
      V::kNr, simd::DotConvRows<V, 8, 8, 6, 5>, simd::DotUpConvRows<V, 8, 8, 6, 5>,
      "conv2d_bf16__neon_bfdot_5x16", "upconv2d_bf16__neon_bfdot_5x16"};
  return (getauxval(AT_HWCAP2) & HWCAP2_BF16) != 0 ? &kKernels : nullptr;
}

}  // namespace sfrt::neon
