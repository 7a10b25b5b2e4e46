// The NEON int8 convolution loops, written once over a dot-product vocabulary `D` that each of
// conv2d_u8s8_neon_dot.cc (sdot, Armv8.2 dotprod) and conv2d_u8s8_neon_usdot.cc (sudot, Armv8.6
// i8mm) defines in its own anonymous namespace and compiles with its own -march: everything here
// is a member of NeonDotKernels<D>, so each variant's code has internal linkage and can never be
// merged across the two translation units. Bit for bit equal to ref::Conv2dInt8Rows: the
// arithmetic is kernels/int8_job.h's (both files are compiled with -ffp-contract=off).
//
// D provides: X (the input vector type the dot product takes), Prepare(uint8x16_t) -> X,
// Dot<lane>(acc, w, x) adding to each int32 lane i of acc the products of w's bytes 4i..4i+3
// with x's bytes 4*lane..4*lane+3, and ZeroPointCoefficient(z): the accumulators start from that
// times the tap_sums of the taps inside the input, so that they end as sum (x - z) * w.
//
// Blocks of 16 output channels (PackInt8Conv with nr 16): one group of 4 input channels of a tap
// is 64 bytes, four 16-byte vectors of 4 output channels x 4 input channels, which is what a
// dot product by element consumes. Register tile: MR output pixels x NV vectors of 4 int32
// channels, NV = the block's valid channels / 4 rounded up: 5x4 (20 accumulators, 5 input and 4
// weight vectors of the 32), 6x3, 8x2 and 8x1. One 16-byte load of a pixel serves four groups of
// input channels (by lane); a last partial load reads only the groups that exist (4-byte units,
// so at most 3 bytes past the pixel's channels). Pixels whose window leaves the input go through
// a one-pixel tile with only those taps. The fused upsample's interior rows use the phase kernels
// where the convolution has them, on the same tiles (int8_job.h; as the AVX-512 VNNI kernel).
#pragma once

#include <arm_neon.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "kernels/int8_job.h"

namespace sfrt::neon {

template <typename D>
struct NeonDotKernels {
  static constexpr int kLanes = 4;
  static constexpr int kNr = 16;  // output channels per block
  static constexpr int kMaxNv = kNr / kLanes;
  using X = typename D::X;

  static int MinOf(int a, int b) { return a < b ? a : b; }
  static int MaxOf(int a, int b) { return a < b ? b : a; }
  // floor(a / b) for b > 0.
  static int FloorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

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

  // The sums of MR pixels x NV vectors over `taps` taps: xs[t * MR + m] is pixel m's input at
  // tap t, ws[t] the tap's packed weights ([groups][kNr][4]), starting from init. Its own
  // function, as the AVX-512 kernel's, so the accumulators stay in registers.
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

  // One block's epilogue (Int8Dequantize, then Int8Quantize for a uint8 output).
  struct Epilogue {
    const float* multiplier = nullptr;  // the block's kNr values
    const float* bias = nullptr;
    Activation act = Activation::kNone;
    float slope = 0.0f;
    bool out_float = false;
    float inv_scale = 1.0f;
    int zero_point = 0;
    int valid = 0;  // channels of the block that exist
  };

  // Lane-wise Int8Dequantize / Int8Quantize of one pixel's NV vectors into `out` (the pixel's
  // first channel of the block: float or uint8). Separate multiplies and adds, never fused.
  template <int NV>
  static void Finish(const int32x4_t* acc, const Epilogue& e, void* out) {
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

  // Accumulate, then the epilogue; pixel m's output is out + m * out_step bytes.
  template <int MR, int NV>
  static void Tile(const uint8_t* const* xs, const int8_t* const* ws, int taps, int groups,
                   const int32x4_t* init, const Epilogue& e, void* out, ptrdiff_t out_step) {
    int32x4_t sums[MR * NV];
    Accumulate<MR, NV>(xs, ws, taps, groups, init, sums);
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
      Finish<NV>(sums + m * NV, e, static_cast<char*>(out) + m * out_step);
    }
  }

  // Tile with r pixels for a run-time r in [1, MR] (a row's leftover pixels).
  template <int MR, int NV>
  static void TileUpTo(int r, const uint8_t* const* xs, const int8_t* const* ws, int taps,
                       int groups, const int32x4_t* init, const Epilogue& e, void* out,
                       ptrdiff_t out_step) {
    if constexpr (MR > 1) {
      if (r < MR) {
        TileUpTo<MR - 1, NV>(r, xs, ws, taps, groups, init, e, out, out_step);
        return;
      }
    }
    Tile<MR, NV>(xs, ws, taps, groups, init, e, out, out_step);
  }

  // What every row of one call shares.
  struct Job {
    const Int8ConvArgs* a = nullptr;
    bool up = false;  // reads C (the fused upsample) instead of a.in
    int kh = 0, kw = 0, sh = 1, sw = 1;
    int pt = 0, pl = 0;
    int src_h = 0, src_w = 0;  // the map the convolution reads
    int out_w = 0;
    int groups = 0;
    ptrdiff_t tap_bytes = 0;  // packed weights of one tap of one block
    ptrdiff_t out_pixel = 0;  // bytes between output pixels
    int x_lo = 0, x_hi = 0;   // output columns whose window lies inside the map
    int32_t coefficient = 0;  // D::ZeroPointCoefficient(in_zero_point)
    bool phases = false;      // the fused upsample's interior from the phase kernels

    const uint8_t* Source(int y, int x) const {
      if (!up) return a->in.pixel(y, x);
      return a->in.pixel((y + a->crop_top) / 2, (x + a->crop_left) / 2);
    }
    void* Out(int oy, int ox, int blk) const {
      if (a->conv->out_float) return a->out_f32.pixel(oy, ox) + blk * kNr;
      return a->out_u8.pixel(oy, ox) + blk * kNr;
    }
  };

  // coefficient * (sum of the tap_sums of taps[0, n)) for NV vectors.
  template <int NV>
  static void ZeroPointInit(const int32_t* const* sums, int n, int32_t coefficient,
                            int32x4_t* init) {
    int32x4_t s[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) s[v] = vdupq_n_s32(0);
    for (int t = 0; t < n; ++t) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) s[v] = vaddq_s32(s[v], vld1q_s32(sums[t] + v * kLanes));
    }
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) init[v] = vmulq_n_s32(s[v], coefficient);
  }

  // The interior pixels of output row oy (whose 3x3 window lies inside C, first tap on C row
  // iy0) from the 2x2 kernels of their phases over the low-resolution map (int8_job.h): per
  // column phase, every second output pixel, reading consecutive low-resolution pixels.
  template <int MR, int NV>
  static void PhaseRow(const Job& j, int blk, const Epilogue& e3x3, int oy, int iy0) {
    const PackedInt8Conv& p = *j.a->conv;
    const int ay = iy0 + j.a->crop_top;
    const int by = ay >> 1;
    const ptrdiff_t phase_bytes = static_cast<ptrdiff_t>(p.blocks) * 4 * j.tap_bytes;
    const ptrdiff_t phase_sums = static_cast<ptrdiff_t>(p.blocks) * 4 * kNr;
    const uint8_t* xs[4 * MR];
    const int8_t* ws[4];
    const int32_t* ss[4];
    int32x4_t init[NV];
    for (int px = 0; px < 2; ++px) {
      // First interior column of this phase: (ox - pl + crop_left) & 1 == px.
      int ox = j.x_lo + ((j.x_lo - j.pl + j.a->crop_left + px) & 1);
      if (ox >= j.x_hi) continue;
      const int phase = (ay & 1) * 2 + px;
      const int8_t* pw = p.phase_weights + phase * phase_bytes + blk * 4 * j.tap_bytes;
      const int32_t* ps = p.phase_tap_sums + phase * phase_sums + blk * 4 * kNr;
      for (int t = 0; t < 4; ++t) {
        ws[t] = pw + t * j.tap_bytes;
        ss[t] = ps + t * kNr;
      }
      ZeroPointInit<NV>(ss, 4, j.coefficient, init);
      Epilogue e = e3x3;
      e.multiplier = p.phase_multiplier + phase * p.blocks * kNr + blk * kNr;
      // Pixels ox, ox + 2, ... (r of them) read low-resolution columns bx, bx + 1, ...
      auto tiles = [&](int r) {
        const int bx = (ox - j.pl + j.a->crop_left) >> 1;
        for (int t = 0; t < 4; ++t) {
          for (int m = 0; m < r; ++m) xs[t * r + m] = j.a->in.pixel(by + t / 2, bx + m + t % 2);
        }
        TileUpTo<MR, NV>(r, xs, ws, 4, j.groups, init, e, j.Out(oy, ox, blk), 2 * j.out_pixel);
      };
      for (; ox + 2 * (MR - 1) < j.x_hi; ox += 2 * MR) tiles(MR);
      if (ox < j.x_hi) tiles((j.x_hi - ox + 1) / 2);
    }
  }

  // Output rows [row_begin, row_end) of block `blk` with the MR x NV tile.
  template <int MR, int NV>
  static void BlockRows(const Job& j, int blk, int row_begin, int row_end) {
    const PackedInt8Conv& p = *j.a->conv;
    const int taps = j.kh * j.kw;
    const int8_t* wblk = p.weights + static_cast<ptrdiff_t>(blk) * taps * j.tap_bytes;
    const int32_t* sblk = p.tap_sums + static_cast<ptrdiff_t>(blk) * taps * kNr;
    Epilogue e;
    e.multiplier = p.multiplier + blk * kNr;
    e.bias = p.bias + blk * kNr;
    e.act = p.activation;
    e.slope = p.leaky_slope;
    e.out_float = p.out_float;
    e.inv_scale = p.out_inv_scale;
    e.zero_point = p.out_zero_point;
    e.valid = MinOf(kNr, p.out_channels - blk * kNr);

    const uint8_t* xs[kMaxInt8Taps * MR];
    const int8_t* ws[kMaxInt8Taps];
    const int32_t* ss[kMaxInt8Taps];
    int32x4_t init[NV];
    for (int oy = row_begin; oy < row_end; ++oy) {
      const int iy0 = oy * j.sh - j.pt;
      const int ky_lo = MaxOf(0, -iy0);
      const int ky_hi = MinOf(j.kh, j.src_h - iy0);

      // One pixel with only the taps inside the map (borders).
      auto single = [&](int ox) {
        const int ix0 = ox * j.sw - j.pl;
        int n = 0;
        for (int ky = ky_lo; ky < ky_hi; ++ky) {
          for (int kx = 0; kx < j.kw; ++kx) {
            const int ix = ix0 + kx;
            if (ix < 0 || ix >= j.src_w) continue;
            xs[n] = j.Source(iy0 + ky, ix);
            ws[n] = wblk + (ky * j.kw + kx) * j.tap_bytes;
            ss[n] = sblk + (ky * j.kw + kx) * kNr;
            ++n;
          }
        }
        int32x4_t one_init[NV];
        ZeroPointInit<NV>(ss, n, j.coefficient, one_init);
        Tile<1, NV>(xs, ws, n, j.groups, one_init, e, j.Out(oy, ox, blk), 0);
      };
      // Pixels [ox, ox + r) of the interior: every kx, the rows inside.
      auto tiles = [&](int ox, int r) {
        int t = 0;
        for (int ky = ky_lo; ky < ky_hi; ++ky) {
          for (int kx = 0; kx < j.kw; ++kx) {
            for (int m = 0; m < r; ++m)
              xs[t * r + m] = j.Source(iy0 + ky, (ox + m) * j.sw - j.pl + kx);
            ++t;
          }
        }
        TileUpTo<MR, NV>(r, xs, ws, t, j.groups, init, e, j.Out(oy, ox, blk), j.out_pixel);
      };

      for (int ox = 0; ox < j.x_lo; ++ox) single(ox);
      if (j.x_lo < j.x_hi && j.phases && iy0 >= 0 && iy0 + 3 <= j.src_h) {
        PhaseRow<MR, NV>(j, blk, e, oy, iy0);
      } else if (j.x_lo < j.x_hi) {
        int n = 0;
        for (int ky = ky_lo; ky < ky_hi; ++ky) {
          for (int kx = 0; kx < j.kw; ++kx) {
            ws[n] = wblk + (ky * j.kw + kx) * j.tap_bytes;
            ss[n] = sblk + (ky * j.kw + kx) * kNr;
            ++n;
          }
        }
        ZeroPointInit<NV>(ss, n, j.coefficient, init);
        int ox = j.x_lo;
        for (; ox + MR <= j.x_hi; ox += MR) tiles(ox, MR);
        if (ox < j.x_hi) tiles(ox, j.x_hi - ox);
      }
      for (int ox = j.x_hi; ox < j.out_w; ++ox) single(ox);
    }
  }

  static void Rows(const Int8ConvArgs& a, bool up, int row_begin, int row_end, int blk_begin,
                   int blk_end) {
    const PackedInt8Conv& p = *a.conv;
    Job j;
    j.a = &a;
    j.up = up;
    j.kh = p.kernel_h;
    j.kw = p.kernel_w;
    j.sh = up ? 1 : p.stride_h;
    j.sw = up ? 1 : p.stride_w;
    j.pt = a.pads.top;
    j.pl = a.pads.left;
    j.src_h = up ? a.c_height : a.in.height;
    j.src_w = up ? a.c_width : a.in.width;
    j.out_w = p.out_float ? a.out_f32.width : a.out_u8.width;
    j.groups = p.cin4 / 4;
    j.tap_bytes = static_cast<ptrdiff_t>(p.cin4) * kNr;
    j.out_pixel = p.out_float ? static_cast<ptrdiff_t>(a.out_f32.channels) * sizeof(float)
                              : static_cast<ptrdiff_t>(a.out_u8.channels);
    // Columns with ox * sw - pl >= 0 and ox * sw - pl + kw <= src_w.
    j.x_lo = MinOf(j.out_w, (j.pl + j.sw - 1) / j.sw);
    j.x_hi = MaxOf(j.x_lo, MinOf(j.out_w, FloorDiv(j.src_w - j.kw + j.pl, j.sw) + 1));
    j.coefficient = D::ZeroPointCoefficient(p.in_zero_point);
    j.phases = up && p.phase_weights != nullptr;

    for (int blk = blk_begin; blk < blk_end; ++blk) {
      const int valid = MinOf(kNr, p.out_channels - blk * kNr);
      switch ((valid + kLanes - 1) / kLanes) {
        case 1:
          BlockRows<8, 1>(j, blk, row_begin, row_end);
          break;
        case 2:
          BlockRows<8, 2>(j, blk, row_begin, row_end);
          break;
        case 3:
          BlockRows<6, 3>(j, blk, row_begin, row_end);
          break;
        default:
          BlockRows<5, kMaxNv>(j, blk, row_begin, row_end);
          break;
      }
    }
  }

  static void ConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin,
                       int blk_end) {
    Rows(a, false, row_begin, row_end, blk_begin, blk_end);
  }

  static void UpConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin,
                         int blk_end) {
    Rows(a, true, row_begin, row_end, blk_begin, blk_end);
  }
};

}  // namespace sfrt::neon
