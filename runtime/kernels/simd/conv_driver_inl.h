// The convolution loops shared by every SIMD tier, written once over a small vector vocabulary
// `V` that each kernels/<isa>/conv2d_<isa>.cc defines in its own anonymous namespace and
// compiles with its own flags. Everything here is a template on V, so each ISA's instantiations
// have internal linkage and can never be merged across translation units built with different
// flags. No standard-library calls for the same reason.
//
// V provides: Reg, kLanes, kRegs (the vector registers there are), Load(const float*),
// LoadPartial(const float*, n) (other lanes 0), Broadcast(const float*), Fma(a, b, acc) = a*b+acc,
// Store(float*, Reg), StorePartial(float*, Reg, n), Leaky(Reg, slope), Relu(Reg).
//
// The register tile: MR output pixels x NV vectors of output channels, accumulated in registers
// while input values are broadcast and the packed weights of one channel block are loaded once
// per input channel. Pixels whose window leaves the image use only the taps that fall inside
// (zero padding adds nothing), in the same tiles where a run of pixels shares those taps (a
// plain convolution's top and bottom rows; the fused upsample's border rows and columns, every
// second pixel), else one at a time with MR = 1. Input channels are summed in
// blocks of PackedConv::cin_block (conv_job.h): the first block starts from the bias, later ones
// from the partial sums in the output, and only the last applies the activation.
#pragma once

#include <cstddef>
#include <cstdint>

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
// Prefetches `bytes` from `ahead` bytes past `at`, a cache line at a time (an address only: past
// the end of a tensor the prefetch is dropped, never read).
static inline void PrefetchAhead(const void* at, size_t ahead, size_t bytes) {
  const uintptr_t from = reinterpret_cast<uintptr_t>(at) + ahead;
  for (size_t b = 0; b < bytes; b += 64) {
    __builtin_prefetch(reinterpret_cast<const void*>(from + b));
  }
}

// The output columns [lo, hi) of a kw-wide, stride-sw convolution with pl columns of left padding
// whose whole window lies inside an in_w-wide input (ox * sw - pl >= 0 and
// ox * sw - pl + kw <= in_w), so they need no bounds checks; lo == hi when there are none.
struct ColumnRange {  // trivial (no member initialisers): no code to share between ISAs
  int lo;
  int hi;
};
static inline ColumnRange InsideColumns(int out_w, int in_w, int kw, int sw, int pl) {
  const int lo = MinOf(out_w, (pl + sw - 1) / sw);
  return {lo, MaxOf(lo, MinOf(out_w, FloorDiv(in_w - kw + pl, sw) + 1))};
}

// Plain convolution, any kernel size up to kMaxConvTaps taps, any stride: each block through
// the rows [row_begin, row_end).
template <typename V, int MR, int NV>
void ConvBlockRows(const ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
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

// What the tiles of one pass share: one block of output channels over one block of kc input
// channels (first: start from the bias; last: apply the activation). Trivial (no member
// initialisers), as UpConvPass, so it has no code that translation units built with different
// flags could share.
struct TilePass {
  int kc;
  const float* bias;
  int valid;
  bool first;
  bool last;
  Activation act;
  float slope;
};

// `count` pixels, their inputs x_step floats and their outputs out_step floats apart, MR at a
// time (the leftovers in one narrower tile), over the n taps xs (advanced here) and ws.
template <typename V, int MR, int NV>
inline void ConvTiles(int count, const float** xs, const float* const* ws, int n, ptrdiff_t x_step,
                      float* out, ptrdiff_t out_step, const TilePass& t) {
  int i = 0;
  for (; i + MR <= count; i += MR) {
    ConvTile<V, MR, NV>(xs, ws, n, x_step, t.kc, t.bias, out + i * out_step, out_step, t.valid,
                        t.first, t.last, t.act, t.slope);
    for (int k = 0; k < n; ++k) xs[k] += MR * x_step;
  }
  if (i < count) {
    ConvTileUpTo<V, MR - 1, NV>(count - i, xs, ws, n, x_step, t.kc, t.bias, out + i * out_step,
                                out_step, t.valid, t.first, t.last, t.act, t.slope);
  }
}

// The plain convolution's ConvRowsFn: rows outer and blocks inner where a.rows_first.
template <typename V, int MR, int NV>
void ConvRows(const ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  if (!a.rows_first) {
    ConvBlockRows<V, MR, NV>(a, row_begin, row_end, blk_begin, blk_end);
    return;
  }
  for (int oy = row_begin; oy < row_end; ++oy) {
    ConvBlockRows<V, MR, NV>(a, oy, oy + 1, blk_begin, blk_end);
  }
}

// The fused upsample -> conv (UpConvRows below): what one call's pixels share, for one block of
// outputs and one block of input channels.
struct UpConvPass {
  const ConvArgs* a;
  const float* wb;       // the block's 3x3 weights from input channel c0 on
  const float* pw;       // the block's phase weights from input channel c0 on (phase 0), or null
  ptrdiff_t tap_floats;  // weights per tap
  ptrdiff_t phase_floats;
  int c0;
  int blk_off;  // the block's first output channel
  TilePass tile;
};

// The 3x3 taps of output pixel (oy, ox) that fall inside C, each at its low-resolution pixel
// (channels from c0 on), into xs and ws; returns how many. Output pixels two columns (rows)
// further read, for every such tap, the low-resolution pixel one column (row) further.
// static: internal linkage in every ISA's translation unit.
static inline int UpConvTaps(const UpConvPass& u, int oy, int ox, const float** xs,
                             const float** ws) {
  const ConvArgs& a = *u.a;
  const int cy0 = oy - a.pads.top, cx0 = ox - a.pads.left;
  int n = 0;
  for (int ky = 0; ky < 3; ++ky) {
    const int cy = cy0 + ky;
    if (cy < 0 || cy >= a.c_height) continue;
    for (int kx = 0; kx < 3; ++kx) {
      const int cx = cx0 + kx;
      if (cx < 0 || cx >= a.c_width) continue;
      xs[n] = a.in.pixel((cy + a.crop_top) >> 1, (cx + a.crop_left) >> 1) + u.c0;
      ws[n] = u.wb + (ky * 3 + kx) * u.tap_floats;
      ++n;
    }
  }
  return n;
}

// Columns [x_lo, x_hi) of output row oy whose window lies inside C: per column phase, every
// second pixel through the phase's 2x2 kernel over consecutive low-resolution pixels.
template <typename V, int MR, int NV>
void UpConvInteriorRow(const UpConvPass& u, int oy, int x_lo, int x_hi) {
  const ConvArgs& a = *u.a;
  const int cin = a.conv->in_channels, cout = a.conv->out_channels;
  const int ay = oy - a.pads.top + a.crop_top;  // upsampled row of the window's first tap
  const int py = ay & 1, by = ay >> 1;
  float* orow = a.out.pixel(oy, 0) + u.blk_off;
  const float* xs[4];
  const float* ws[4];
  for (int px = 0; px < 2; ++px) {
    // First interior column of this phase: (ox - pl + crop_left) & 1 == px.
    const int ox = x_lo + ((x_lo - a.pads.left + a.crop_left + px) & 1);
    if (ox >= x_hi) continue;
    const float* pw = u.pw + (py * 2 + px) * u.phase_floats;
    for (int t = 0; t < 4; ++t) ws[t] = pw + t * u.tap_floats;
    const int bx = (ox - a.pads.left + a.crop_left) >> 1;
    xs[0] = a.in.pixel(by, bx) + u.c0;
    xs[1] = a.in.pixel(by, bx + 1) + u.c0;
    xs[2] = a.in.pixel(by + 1, bx) + u.c0;
    xs[3] = a.in.pixel(by + 1, bx + 1) + u.c0;
    ConvTiles<V, MR, NV>((x_hi - ox + 1) / 2, xs, ws, 4, cin,
                         orow + static_cast<ptrdiff_t>(ox) * cout, 2 * static_cast<ptrdiff_t>(cout),
                         u.tile);
  }
}

// Every second pixel of the run from (oy, ox): `count` pixels two columns (along_row) or two rows
// apart, their windows alike in which taps fall inside C (a border row's interior columns, a
// border column's interior rows), MR at a time over those taps.
template <typename V, int MR, int NV>
void UpConvBorderRun(const UpConvPass& u, int oy, int ox, int count, bool along_row) {
  if (count <= 0) return;
  const ConvArgs& a = *u.a;
  const float* xs[9];
  const float* ws[9];
  const int n = UpConvTaps(u, oy, ox, xs, ws);
  const ptrdiff_t x_step = along_row ? a.in.channels : a.in.row_stride;
  const ptrdiff_t out_step = 2 * (along_row ? a.conv->out_channels : a.out.row_stride);
  ConvTiles<V, MR, NV>(count, xs, ws, n, x_step, a.out.pixel(oy, ox) + u.blk_off, out_step, u.tile);
}

// One output pixel over the taps that fall inside C (the corners).
template <typename V, int NV>
void UpConvSingle(const UpConvPass& u, int oy, int ox) {
  const float* xs[9];
  const float* ws[9];
  const int n = UpConvTaps(u, oy, ox, xs, ws);
  const TilePass& t = u.tile;
  ConvTile<V, 1, NV>(xs, ws, n, 0, t.kc, t.bias, u.a->out.pixel(oy, ox) + u.blk_off, 0, t.valid,
                     t.first, t.last, t.act, t.slope);
}

// Rows [row_begin, row_end) of one pass. The interior rows' interior columns through the phase
// kernels (unless a.skip_interior); the border rows' interior columns and the border columns'
// interior rows in runs of every second pixel through the tiles; the corners one by one.
template <typename V, int MR, int NV>
void UpConvPassRows(const UpConvPass& u, int row_begin, int row_end) {
  const ConvArgs& a = *u.a;
  const int pt = a.pads.top, pl = a.pads.left, out_w = a.out.width;
  // Interior columns: ox - pl >= 0 and ox - pl + 3 <= cw; rows likewise.
  const int x_lo = MinOf(out_w, MaxOf(0, pl));
  const int x_hi = MaxOf(x_lo, MinOf(out_w, a.c_width - 3 + pl + 1));
  const int y_lo = MinOf(row_end, MaxOf(row_begin, pt));
  const int y_hi = MaxOf(y_lo, MinOf(row_end, a.c_height - 3 + pt + 1));
  for (int oy = row_begin; oy < row_end; ++oy) {
    if (oy >= y_lo && oy < y_hi) {
      if (!a.skip_interior) UpConvInteriorRow<V, MR, NV>(u, oy, x_lo, x_hi);
      continue;
    }
    for (int ox = 0; ox < x_lo; ++ox) UpConvSingle<V, NV>(u, oy, ox);
    for (int ox = x_hi; ox < out_w; ++ox) UpConvSingle<V, NV>(u, oy, ox);
    for (int start = x_lo; start < x_lo + 2; ++start) {
      UpConvBorderRun<V, MR, NV>(u, oy, start, (x_hi - start + 1) / 2, true);
    }
  }
  auto border_column = [&](int ox) {
    for (int start = y_lo; start < y_lo + 2; ++start) {
      UpConvBorderRun<V, MR, NV>(u, start, ox, (y_hi - start + 1) / 2, false);
    }
  };
  for (int ox = 0; ox < x_lo; ++ox) border_column(ox);
  for (int ox = x_hi; ox < out_w; ++ox) border_column(ox);
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
  UpConvPass u{};
  u.a = &a;
  u.tap_floats = static_cast<ptrdiff_t>(cin) * kNr;
  u.phase_floats = p.blocks * 4 * u.tap_floats;
  u.tile.act = p.activation;
  u.tile.slope = p.leaky_slope;
  for (int blk = blk_begin; blk < blk_end; ++blk) {
    u.blk_off = blk * kNr;
    u.tile.bias = p.bias + blk * kNr;
    u.tile.valid = MinOf(kNr, p.out_channels - blk * kNr);
    for (int c0 = 0; c0 < cin; c0 += kc_max) {
      u.c0 = c0;
      u.tile.kc = MinOf(kc_max, cin - c0);
      u.tile.first = c0 == 0;
      u.tile.last = c0 + u.tile.kc == cin;
      u.wb = p.weights + blk * 9 * u.tap_floats + static_cast<ptrdiff_t>(c0) * kNr;
      u.pw = p.phase_weights == nullptr
                 ? nullptr
                 : p.phase_weights + blk * 4 * u.tap_floats + static_cast<ptrdiff_t>(c0) * kNr;
      UpConvPassRows<V, MR, NV>(u, row_begin, row_end);
    }
  }
}

}  // namespace sfrt::simd
