// The NEON int8 vocabulary (kernels/simd/dot_driver_inl.h) for the dot products by element,
// written once over a dot-product `D` that each of conv2d_u8s8_neon_dot.cc (sdot, Armv8.2
// dotprod) and conv2d_u8s8_neon_usdot.cc (sudot, Armv8.6 i8mm) defines in its own anonymous
// namespace and compiles with its own -march: NeonDotInt8<D> and the driver's instantiations on
// it have internal linkage and can never be merged across the two translation units. Bit for bit
// equal to ref::Conv2dInt8Rows: the arithmetic is kernels/int8_job.h's (both files are compiled
// with -ffp-contract=off).
//
// D provides: X (the input vector type the dot product takes), Prepare(uint8x16_t) -> X,
// Dot<lane>(acc, w, x) adding to each int32 lane i of acc the products of w's bytes 4i..4i+3
// with x's bytes 4*lane..4*lane+3, and ZeroPointCoefficient(z): the accumulators start from that
// times the tap_sums of the taps inside the input, so that they end as sum (x - z) * w.
//
// Blocks of 16 output channels (PackInt8Conv with nr 16): one group of 4 input channels of a tap
// is 64 bytes, four 16-byte vectors of 4 output channels x 4 input channels, which is what a
// dot product by element consumes. Vectors of 4 int32 channels; the files' tiles are 5x4 (20
// accumulators, 5 input and 4 weight vectors of the 32), 6x3, 8x2 and 8x1. One 16-byte load of
// a pixel serves four groups of input channels (by lane); a last partial load reads only the
// groups that exist (4-byte units, so at most 3 bytes past the pixel's channels).
#pragma once

#include <arm_neon.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "kernels/int8_job.h"
#include "kernels/simd/dot_driver_inl.h"

namespace sfrt::neon {

template <typename D>
struct NeonDotInt8 {
  using Conv = PackedInt8Conv;
  using Acc = int32x4_t;
  static constexpr int kLanes = 4;
  static constexpr int kNr = 16;  // output channels per block
  static constexpr int kMaxNv = kNr / kLanes;
  using X = typename D::X;

  static Acc Zero() { return vdupq_n_s32(0); }
  static Acc Load(const int32_t* p) { return vld1q_s32(p); }
  static Acc Add(Acc a, Acc b) { return vaddq_s32(a, b); }
  static Acc MulScalar(Acc a, int32_t c) { return vmulq_n_s32(a, c); }
  static int32_t ZeroPointCoefficient(int zero_point) {
    return D::ZeroPointCoefficient(zero_point);
  }

  // `groups` (1..3) groups of 4 input channels from p, the other lanes zero.
  static uint8x16_t LoadGroups(const uint8_t* p, int groups) {
    uint32_t last;
    if (groups == 2) return vcombine_u8(vld1_u8(p), vdup_n_u8(0));
    if (groups == 1) {
      std::memcpy(&last, p, sizeof(last));
      return vreinterpretq_u8_u32(vsetq_lane_u32(last, vdupq_n_u32(0), 0));
    }
    std::memcpy(&last, p + 8, sizeof(last));
    return vcombine_u8(vld1_u8(p), vreinterpret_u8_u32(vset_lane_u32(last, vdup_n_u32(0), 0)));
  }

  // One group of 4 input channels (lane L of each pixel's x) with its 64 bytes of weights.
  template <int L, int MR, int NV>
  [[gnu::always_inline]] static inline void Step(int32x4_t (&acc)[MR][NV], const X (&x)[MR],
                                                 const int8_t* w) {
    // The weights of one group at a time: scheduled together, the four groups' 16 vectors
    // would push the accumulators out of the registers.
    asm volatile("" ::: "memory");
    int8x16_t wv[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) wv[v] = vld1q_s8(w + v * 16);
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) acc[m][v] = D::template Dot<L>(acc[m][v], wv[v], x[m]);
    }
  }

  // The sums of MR pixels x NV vectors (dot_driver_inl.h). Its own function, as the AVX-512
  // VNNI kernel's, so the accumulators stay in registers.
  template <int MR, int NV>
  [[gnu::noinline]] static void Accumulate(const uint8_t* const* xs, const int8_t* const* ws,
                                           int taps, int groups, const int32x4_t* init,
                                           int32x4_t* sums) {
    int32x4_t acc[MR][NV];
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) acc[m][v] = init[v];
    }
    const int quads = groups / 4, rest = groups % 4;
    for (int t = 0; t < taps; ++t) {
      const uint8_t* const* x = xs + t * MR;
      const int8_t* w = ws[t];
      X xv[MR];
      for (int q = 0; q < quads; ++q) {
#pragma GCC unroll 16
        for (int m = 0; m < MR; ++m) xv[m] = D::Prepare(vld1q_u8(x[m] + 16 * q));
        Step<0>(acc, xv, w);
        Step<1>(acc, xv, w + 4 * kNr);
        Step<2>(acc, xv, w + 8 * kNr);
        Step<3>(acc, xv, w + 12 * kNr);
        w += 16 * kNr;
      }
      if (rest > 0) {
#pragma GCC unroll 16
        for (int m = 0; m < MR; ++m) xv[m] = D::Prepare(LoadGroups(x[m] + 16 * quads, rest));
        Step<0>(acc, xv, w);
        if (rest > 1) Step<1>(acc, xv, w + 4 * kNr);
        if (rest > 2) Step<2>(acc, xv, w + 8 * kNr);
      }
    }
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) sums[m * NV + v] = acc[m][v];
    }
  }

  // Lane-wise Int8Dequantize / Int8Quantize of one pixel's NV vectors into `out` (the pixel's
  // first channel of the block: float or uint8). Separate multiplies and adds, never fused.
  template <int NV>
  static void Finish(const int32x4_t* acc, const simd::DotEpilogue& e, void* out) {
    const float32x4_t zero = vdupq_n_f32(0.0f);
    float32x4_t y[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) {
      y[v] = vcvtq_f32_s32(acc[v]);  // scvtf: to nearest even
      y[v] = vmulq_f32(y[v], vld1q_f32(e.multiplier + v * kLanes));
      y[v] = vaddq_f32(y[v], vld1q_f32(e.bias + v * kLanes));
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
    const float32x4_t lo = vdupq_n_f32(-512.0f), hi = vdupq_n_f32(512.0f);
    uint16x4_t q16[kMaxNv];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) {
      float32x4_t t = vmulq_f32(y[v], vdupq_n_f32(e.inv_scale));
      // t > -512 ? t : -512, then t < 512 ? t : 512, as Int8Quantize (a NaN becomes -512).
      t = vbslq_f32(vcgtq_f32(t, lo), t, lo);
      t = vbslq_f32(vcltq_f32(t, hi), t, hi);
      int32x4_t q = vcvtnq_s32_f32(t);  // fcvtns: to nearest even
      q = vaddq_s32(q, vdupq_n_s32(e.zero_point));
      q = vmaxq_s32(q, vdupq_n_s32(0));
      q = vminq_s32(q, vdupq_n_s32(255));
      q16[v] = vmovn_u32(vreinterpretq_u32_s32(q));
    }
#pragma GCC unroll 4
    for (int v = NV; v < kMaxNv; ++v) q16[v] = vdup_n_u16(0);
    const uint8x16_t bytes = vcombine_u8(vmovn_u16(vcombine_u16(q16[0], q16[1])),
                                         vmovn_u16(vcombine_u16(q16[2], q16[3])));
    uint8_t* o = static_cast<uint8_t*>(out);
    if (e.valid >= kNr) {
      vst1q_u8(o, bytes);
    } else {
      uint8_t tmp[kNr];
      vst1q_u8(tmp, bytes);
      for (int i = 0; i < e.valid; ++i) o[i] = tmp[i];
    }
  }
};

}  // namespace sfrt::neon
