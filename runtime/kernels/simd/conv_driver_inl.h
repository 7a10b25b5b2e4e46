// The convolution loops shared by every SIMD tier, written once over a small vector vocabulary
// `V` that each kernels/<isa>/conv2d_<isa>.cc defines in its own anonymous namespace and
// compiles with its own flags. Everything here is a template on V, so each ISA's instantiations
// have internal linkage and can never be merged across translation units built with different
// flags. No standard-library calls for the same reason.
//
// V provides: Reg, kLanes, Load(const float*), LoadPartial(const float*, n) (other lanes 0),
// Broadcast(const float*), Fma(a, b, acc) = a*b+acc, Store(float*, Reg),
// StorePartial(float*, Reg, n), Leaky(Reg, slope), Relu(Reg).
//
// The register tile: MR output pixels x NV vectors of output channels, accumulated in registers
// while input values are broadcast and the packed weights of one channel block are loaded once
// per input channel. Pixels whose window leaves the image go through the same tile with MR = 1
// and only the taps that fall inside (zero padding adds nothing). Input channels are summed in
// blocks of PackedConv::cin_block (conv_job.h): the first block starts from the bias, later ones
// from the partial sums in the output, and only the last applies the activation.
#pragma once

#include <cstddef>

#include "kernels/conv_job.h"

namespace sfrt::simd {

// Pass over one block of input channels (`cin` of them) for MR pixels x NV vectors. `first`:
// start from the bias; otherwise from the partial sums in `out`. `last`: apply the activation.
template <typename V, int MR, int NV>
inline void ConvTile(const float* const* xs, const float* const* ws, int taps, ptrdiff_t x_step,
                     int cin, const float* bias, float* out, ptrdiff_t out_step, int valid,
                     bool first, bool last, Activation act, float slope) {
  constexpr int kL = V::kLanes;
  typename V::Reg acc[MR][NV];
  if (first) {
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) {
      const typename V::Reg b = V::Load(bias + v * kL);
#pragma GCC unroll 16
      for (int m = 0; m < MR; ++m) acc[m][v] = b;
    }
  } else {
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) {
        const float* src = out + m * out_step + v * kL;
        const int left = valid - v * kL;
        acc[m][v] = left >= kL ? V::Load(src) : V::LoadPartial(src, left > 0 ? left : 0);
      }
    }
  }
  for (int t = 0; t < taps; ++t) {
    const float* x = xs[t];
    const float* w = ws[t];
    for (int ci = 0; ci < cin; ++ci) {
      typename V::Reg wv[NV];
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) wv[v] = V::Load(w + v * kL);
      w += NV * kL;
#pragma GCC unroll 16
      for (int m = 0; m < MR; ++m) {
        const typename V::Reg b = V::Broadcast(x + m * x_step + ci);
#pragma GCC unroll 4
        for (int v = 0; v < NV; ++v) acc[m][v] = V::Fma(b, wv[v], acc[m][v]);
      }
    }
  }
#pragma GCC unroll 16
  for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) {
      typename V::Reg r = acc[m][v];
      if (last && act == Activation::kLeakyRelu) {
        r = V::Leaky(r, slope);
      } else if (last && act == Activation::kRelu) {
        r = V::Relu(r);
      }
      float* dst = out + m * out_step + v * kL;
      const int left = valid - v * kL;
      if (left >= kL) {
        V::Store(dst, r);
      } else if (left > 0) {
        V::StorePartial(dst, r, left);
      }
    }
  }
}

// ConvTile with R pixels for a run-time R in [1, MR]: the leftover pixels of a row go through
// one narrower tile instead of R single-pixel ones.
template <typename V, int MR, int NV>
inline void ConvTileUpTo(int r, const float* const* xs, const float* const* ws, int taps,
                         ptrdiff_t x_step, int cin, const float* bias, float* out,
                         ptrdiff_t out_step, int valid, bool first, bool last, Activation act,
                         float slope) {
  if constexpr (MR > 1) {
    if (r < MR) {
      ConvTileUpTo<V, MR - 1, NV>(r, xs, ws, taps, x_step, cin, bias, out, out_step, valid, first,
                                  last, act, slope);
      return;
    }
  }
  ConvTile<V, MR, NV>(xs, ws, taps, x_step, cin, bias, out, out_step, valid, first, last, act,
                      slope);
}

// static: internal linkage in every ISA's translation unit.
static inline int MinOf(int a, int b) { return a < b ? a : b; }
static inline int MaxOf(int a, int b) { return a < b ? b : a; }
// floor(a / b) for b > 0.
static inline int FloorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// The output columns [lo, hi) of a kw-wide, stride-sw convolution with pl columns of left padding
// whose whole window lies inside an in_w-wide input (ox * sw - pl >= 0 and
// ox * sw - pl + kw <= in_w), so they need no bounds checks; lo == hi when there are none.
struct ColumnRange {
  int lo = 0;
  int hi = 0;
};
static inline ColumnRange InsideColumns(int out_w, int in_w, int kw, int sw, int pl) {
  const int lo = MinOf(out_w, (pl + sw - 1) / sw);
  return {lo, MaxOf(lo, MinOf(out_w, FloorDiv(in_w - kw + pl, sw) + 1))};
}

// Plain convolution, any kernel size up to kMaxConvTaps taps, any stride.
template <typename V, int MR, int NV>
void ConvRows(const ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  const PackedConv& p = *a.conv;
  constexpr int kNr = NV * V::kLanes;
  const int cin = p.in_channels;
  const int kc_max = p.cin_block > 0 ? MinOf(p.cin_block, cin) : cin;
  const int kh = p.kernel_h, kw = p.kernel_w, sh = p.stride_h, sw = p.stride_w;
  const int taps = kh * kw;
  const ptrdiff_t tap_floats = static_cast<ptrdiff_t>(cin) * kNr;
  const int pt = a.pads.top, pl = a.pads.left;
  const int in_h = a.in.height, in_w = a.in.width, out_w = a.out.width;
  const int cout = p.out_channels;
  const Activation act = p.activation;
  const float slope = p.leaky_slope;
  const ColumnRange inside = InsideColumns(out_w, in_w, kw, sw, pl);
  const int x_lo = inside.lo, x_hi = inside.hi;
  const ptrdiff_t x_step = static_cast<ptrdiff_t>(sw) * cin;
  const float* xs[kMaxConvTaps];
  const float* ws[kMaxConvTaps];

  for (int blk = blk_begin; blk < blk_end; ++blk) {
    const float* wblk = p.weights + static_cast<ptrdiff_t>(blk) * taps * tap_floats;
    const float* bias = p.bias + blk * kNr;
    const int valid = MinOf(kNr, cout - blk * kNr);
    for (int c0 = 0; c0 < cin; c0 += kc_max) {
      const int kc = MinOf(kc_max, cin - c0);
      const bool first = c0 == 0, last = c0 + kc == cin;
      const float* wb = wblk + static_cast<ptrdiff_t>(c0) * kNr;
      for (int oy = row_begin; oy < row_end; ++oy) {
        const int iy0 = oy * sh - pt;
        const int ky_lo = MaxOf(0, -iy0);
        const int ky_hi = MinOf(kh, in_h - iy0);
        float* orow = a.out.pixel(oy, 0) + blk * kNr;
        // One pixel with bounds checks (borders and leftovers).
        auto single = [&](int ox) {
          int n = 0;
          const int ix0 = ox * sw - pl;
          for (int ky = ky_lo; ky < ky_hi; ++ky) {
            for (int kx = 0; kx < kw; ++kx) {
              const int ix = ix0 + kx;
              if (ix < 0 || ix >= in_w) continue;
              xs[n] = a.in.pixel(iy0 + ky, ix) + c0;
              ws[n] = wb + (ky * kw + kx) * tap_floats;
              ++n;
            }
          }
          ConvTile<V, 1, NV>(xs, ws, n, 0, kc, bias, orow + static_cast<ptrdiff_t>(ox) * cout, 0,
                             valid, first, last, act, slope);
        };
        for (int ox = 0; ox < x_lo; ++ox) single(ox);
        int ox = x_lo;
        if (ox < x_hi) {
          int n = 0;
          for (int ky = ky_lo; ky < ky_hi; ++ky) {
            for (int kx = 0; kx < kw; ++kx) {
              ws[n] = wb + (ky * kw + kx) * tap_floats;
              ++n;
            }
          }
          for (; ox + MR <= x_hi; ox += MR) {
            int t = 0;
            const int ix0 = ox * sw - pl;
            for (int ky = ky_lo; ky < ky_hi; ++ky) {
              for (int kx = 0; kx < kw; ++kx) xs[t++] = a.in.pixel(iy0 + ky, ix0 + kx) + c0;
            }
            ConvTile<V, MR, NV>(xs, ws, n, x_step, kc, bias,
                                orow + static_cast<ptrdiff_t>(ox) * cout, cout, valid, first, last,
                                act, slope);
          }
          if (ox < x_hi) {
            int t = 0;
            const int ix0 = ox * sw - pl;
            for (int ky = ky_lo; ky < ky_hi; ++ky) {
              for (int kx = 0; kx < kw; ++kx) xs[t++] = a.in.pixel(iy0 + ky, ix0 + kx) + c0;
            }
            ConvTileUpTo<V, MR - 1, NV>(x_hi - ox, xs, ws, n, x_step, kc, bias,
                                        orow + static_cast<ptrdiff_t>(ox) * cout, cout, valid,
                                        first, last, act, slope);
            ox = x_hi;
          }
        }
        for (; ox < out_w; ++ox) single(ox);
      }
    }
  }
}

// Fused nearest-2x upsample -> crop -> 3x3 stride-1 convolution (see conv_job.h). Output pixels
// whose 3x3 window lies inside C use the 2x2 phase kernels on the low-resolution map; the
// others (the padding border) use the 3x3 weights, each tap mapped to its low-resolution pixel.
template <typename V, int MR, int NV>
void UpConvRows(const ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  const PackedConv& p = *a.conv;
  constexpr int kNr = NV * V::kLanes;
  const int cin = p.in_channels;
  const int kc_max = p.cin_block > 0 ? MinOf(p.cin_block, cin) : cin;
  const int cout = p.out_channels;
  const Activation act = p.activation;
  const float slope = p.leaky_slope;
  const ptrdiff_t tap_floats = static_cast<ptrdiff_t>(cin) * kNr;
  const ptrdiff_t block_floats = 9 * tap_floats;
  const ptrdiff_t phase_block_floats = 4 * tap_floats;
  const ptrdiff_t phase_floats = p.blocks * phase_block_floats;
  const int pt = a.pads.top, pl = a.pads.left;
  const int ch = a.c_height, cw = a.c_width, out_w = a.out.width;
  // Interior columns: ox - pl >= 0 and ox - pl + 3 <= cw.
  const int x_lo = MinOf(out_w, MaxOf(0, pl));
  const int x_hi = MaxOf(x_lo, MinOf(out_w, cw - 3 + pl + 1));
  const float* xs[9];
  const float* ws[9];

  for (int blk = blk_begin; blk < blk_end; ++blk) {
    const float* bias = p.bias + blk * kNr;
    const int valid = MinOf(kNr, cout - blk * kNr);
    for (int c0 = 0; c0 < cin; c0 += kc_max) {
      const int kc = MinOf(kc_max, cin - c0);
      const bool first = c0 == 0, last = c0 + kc == cin;
      const float* wb = p.weights + blk * block_floats + static_cast<ptrdiff_t>(c0) * kNr;
      for (int oy = row_begin; oy < row_end; ++oy) {
        const int cy0 = oy - pt;
        const bool row_inside = cy0 >= 0 && cy0 + 3 <= ch;
        float* orow = a.out.pixel(oy, 0) + blk * kNr;
        auto single = [&](int ox) {
          int n = 0;
          const int cx0 = ox - pl;
          for (int ky = 0; ky < 3; ++ky) {
            const int cy = cy0 + ky;
            if (cy < 0 || cy >= ch) continue;
            for (int kx = 0; kx < 3; ++kx) {
              const int cx = cx0 + kx;
              if (cx < 0 || cx >= cw) continue;
              xs[n] = a.in.pixel((cy + a.crop_top) >> 1, (cx + a.crop_left) >> 1) + c0;
              ws[n] = wb + (ky * 3 + kx) * tap_floats;
              ++n;
            }
          }
          ConvTile<V, 1, NV>(xs, ws, n, 0, kc, bias, orow + static_cast<ptrdiff_t>(ox) * cout, 0,
                             valid, first, last, act, slope);
        };
        if (!row_inside) {
          for (int ox = 0; ox < out_w; ++ox) single(ox);
          continue;
        }
        for (int ox = 0; ox < x_lo; ++ox) single(ox);
        for (int ox = x_hi; ox < out_w; ++ox) single(ox);
        if (a.skip_interior) continue;
        const int ay = cy0 + a.crop_top;  // upsampled row of the window's first tap
        const int py = ay & 1, by = ay >> 1;
        for (int px = 0; px < 2; ++px) {
          // First interior column of this phase: (ox - pl + crop_left) & 1 == px.
          int ox = x_lo + ((x_lo - pl + a.crop_left + px) & 1);
          if (ox >= x_hi) continue;
          const float* pw = p.phase_weights + (py * 2 + px) * phase_floats +
                            blk * phase_block_floats + static_cast<ptrdiff_t>(c0) * kNr;
          for (int t = 0; t < 4; ++t) ws[t] = pw + t * tap_floats;
          auto taps_at = [&](int x) {
            const int bx = (x - pl + a.crop_left) >> 1;
            xs[0] = a.in.pixel(by, bx) + c0;
            xs[1] = a.in.pixel(by, bx + 1) + c0;
            xs[2] = a.in.pixel(by + 1, bx) + c0;
            xs[3] = a.in.pixel(by + 1, bx + 1) + c0;
          };
          for (; ox + 2 * (MR - 1) < x_hi; ox += 2 * MR) {
            taps_at(ox);
            ConvTile<V, MR, NV>(xs, ws, 4, cin, kc, bias, orow + static_cast<ptrdiff_t>(ox) * cout,
                                2 * static_cast<ptrdiff_t>(cout), valid, first, last, act, slope);
          }
          if (ox < x_hi) {
            taps_at(ox);
            ConvTileUpTo<V, MR - 1, NV>((x_hi - ox + 1) / 2, xs, ws, 4, cin, kc, bias,
                                        orow + static_cast<ptrdiff_t>(ox) * cout,
                                        2 * static_cast<ptrdiff_t>(cout), valid, first, last, act,
                                        slope);
          }
        }
      }
    }
  }
}

}  // namespace sfrt::simd
