// The int8 convolution driver shared by every SIMD tier (kernels/int8_job.h), written once over
// an int8 vocabulary `V` that each kernels/<isa>/conv2d_u8s8_<isa>.cc defines in its own
// anonymous namespace and compiles with its own flags. Everything here is a template on V, so
// each ISA's instantiations have internal linkage and can never be merged across translation
// units built with different flags (as conv_driver_inl.h). Bit for bit equal to
// ref::Conv2dInt8Rows: the arithmetic is int8_job.h's.
//
// V provides: Acc (a register of kLanes int32 output channels), kLanes, kNr (output channels per
// packed block, PackedInt8Conv::nr), Zero(), Load(const int32_t*), Add(Acc, Acc),
// MulScalar(Acc, int32_t), ZeroPointCoefficient(z), and two functions that see the registers:
//   Accumulate<MR, NV>(xs, ws, taps, groups, init, sums): the sums of MR pixels x NV vectors over
//     `taps` taps (xs[t * MR + m] pixel m's input at tap t, ws[t] the tap's packed weights
//     [groups][kNr][4]), starting from init[NV], into sums[m * NV + v];
//   Finish<NV>(acc, epilogue, out): Int8Dequantize (and Int8Quantize) of one pixel's NV vectors.
// The accumulators start from ZeroPointCoefficient(in_zero_point) times the tap_sums of the taps
// inside the input, so that Accumulate's dot products end as sum (x - z) * w.
//
// The register tile: MR output pixels x NV vectors, NV = the block's valid channels / kLanes
// rounded up, so a layer with few output channels computes no empty vectors; each ISA names MR
// for every NV. Pixels whose window leaves the input go through a one-pixel tile with only the
// taps inside. The fused upsample's interior rows use the phase kernels where the convolution
// has them, on the same tiles. MinOf, MaxOf and InsideColumns are conv_driver_inl.h's.
#pragma once

#include <cstddef>
#include <cstdint>

#include "kernels/int8_job.h"
#include "kernels/simd/conv_driver_inl.h"

namespace sfrt::simd {

// One block's epilogue (Int8Dequantize, then Int8Quantize for a uint8 output). Trivial (no
// member initialisers), so it has no code that translation units built with different flags
// could share.
struct Int8Epilogue {
  const float* multiplier;  // the block's kNr values
  const float* bias;
  Activation act;
  float slope;
  bool out_float;
  float inv_scale;
  int zero_point;
  int valid;  // channels of the block that exist
};

// Accumulate, then the epilogue; pixel m's output is out + m * out_step bytes.
template <typename V, int MR, int NV>
inline void Int8Tile(const uint8_t* const* xs, const int8_t* const* ws, int taps, int groups,
                     const typename V::Acc* init, const Int8Epilogue& e, void* out,
                     ptrdiff_t out_step) {
  typename V::Acc sums[MR * NV];
  V::template Accumulate<MR, NV>(xs, ws, taps, groups, init, sums);
#pragma GCC unroll 16
  for (int m = 0; m < MR; ++m) {
    V::template Finish<NV>(sums + m * NV, e, static_cast<char*>(out) + m * out_step);
  }
}

// Int8Tile with r pixels for a run-time r in [1, MR] (a row's leftover pixels).
template <typename V, int MR, int NV>
inline void Int8TileUpTo(int r, const uint8_t* const* xs, const int8_t* const* ws, int taps,
                         int groups, const typename V::Acc* init, const Int8Epilogue& e, void* out,
                         ptrdiff_t out_step) {
  if constexpr (MR > 1) {
    if (r < MR) {
      Int8TileUpTo<V, MR - 1, NV>(r, xs, ws, taps, groups, init, e, out, out_step);
      return;
    }
  }
  Int8Tile<V, MR, NV>(xs, ws, taps, groups, init, e, out, out_step);
}

// What every row of one call shares.
template <typename V>
struct Int8Job {
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
  int32_t coefficient = 0;  // V::ZeroPointCoefficient(in_zero_point)
  bool phases = false;      // the fused upsample's interior from the phase kernels

  const uint8_t* Source(int y, int x) const {
    if (!up) return a->in.pixel(y, x);
    return a->in.pixel((y + a->crop_top) / 2, (x + a->crop_left) / 2);
  }
  void* Out(int oy, int ox, int blk) const {
    if (a->conv->out_float) return a->out_f32.pixel(oy, ox) + blk * V::kNr;
    return a->out_u8.pixel(oy, ox) + blk * V::kNr;
  }
};

// coefficient * (sum of the tap_sums of taps[0, n)) for NV vectors.
template <typename V, int NV>
inline void Int8ZeroPointInit(const int32_t* const* sums, int n, int32_t coefficient,
                              typename V::Acc* init) {
  typename V::Acc s[NV];
#pragma GCC unroll 4
  for (int v = 0; v < NV; ++v) s[v] = V::Zero();
  for (int t = 0; t < n; ++t) {
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) s[v] = V::Add(s[v], V::Load(sums[t] + v * V::kLanes));
  }
#pragma GCC unroll 4
  for (int v = 0; v < NV; ++v) init[v] = V::MulScalar(s[v], coefficient);
}

// The interior pixels of output row oy (whose 3x3 window lies inside C, first tap on C row
// iy0) from the 2x2 kernels of their phases over the low-resolution map (int8_job.h): per
// column phase, every second output pixel, reading consecutive low-resolution pixels.
template <typename V, int MR, int NV>
void Int8PhaseRow(const Int8Job<V>& j, int blk, const Int8Epilogue& e3x3, int oy, int iy0) {
  constexpr int kNr = V::kNr;
  const PackedInt8Conv& p = *j.a->conv;
  const int ay = iy0 + j.a->crop_top;
  const int by = ay >> 1;
  const ptrdiff_t phase_bytes = static_cast<ptrdiff_t>(p.blocks) * 4 * j.tap_bytes;
  const ptrdiff_t phase_sums = static_cast<ptrdiff_t>(p.blocks) * 4 * kNr;
  const uint8_t* xs[4 * MR];
  const int8_t* ws[4];
  const int32_t* ss[4];
  typename V::Acc init[NV];
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
    Int8ZeroPointInit<V, NV>(ss, 4, j.coefficient, init);
    Int8Epilogue e = e3x3;
    e.multiplier = p.phase_multiplier + phase * p.blocks * kNr + blk * kNr;
    // Pixels ox, ox + 2, ... (r of them) read low-resolution columns bx, bx + 1, ...
    auto tiles = [&](int r) {
      const int bx = (ox - j.pl + j.a->crop_left) >> 1;
      for (int t = 0; t < 4; ++t) {
        for (int m = 0; m < r; ++m) xs[t * r + m] = j.a->in.pixel(by + t / 2, bx + m + t % 2);
      }
      Int8TileUpTo<V, MR, NV>(r, xs, ws, 4, j.groups, init, e, j.Out(oy, ox, blk), 2 * j.out_pixel);
    };
    for (; ox + 2 * (MR - 1) < j.x_hi; ox += 2 * MR) tiles(MR);
    if (ox < j.x_hi) tiles((j.x_hi - ox + 1) / 2);
  }
}

// Output rows [row_begin, row_end) of block `blk` with the MR x NV tile.
template <typename V, int MR, int NV>
void Int8BlockRows(const Int8Job<V>& j, int blk, int row_begin, int row_end) {
  constexpr int kNr = V::kNr;
  const PackedInt8Conv& p = *j.a->conv;
  const int taps = j.kh * j.kw;
  const int8_t* wblk = p.weights + static_cast<ptrdiff_t>(blk) * taps * j.tap_bytes;
  const int32_t* sblk = p.tap_sums + static_cast<ptrdiff_t>(blk) * taps * kNr;
  const Int8Epilogue e = {.multiplier = p.multiplier + blk * kNr,
                          .bias = p.bias + blk * kNr,
                          .act = p.activation,
                          .slope = p.leaky_slope,
                          .out_float = p.out_float,
                          .inv_scale = p.out_inv_scale,
                          .zero_point = p.out_zero_point,
                          .valid = MinOf(kNr, p.out_channels - blk * kNr)};

  const uint8_t* xs[kMaxInt8Taps * MR];
  const int8_t* ws[kMaxInt8Taps];
  const int32_t* ss[kMaxInt8Taps];
  typename V::Acc init[NV];
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
      typename V::Acc one_init[NV];
      Int8ZeroPointInit<V, NV>(ss, n, j.coefficient, one_init);
      Int8Tile<V, 1, NV>(xs, ws, n, j.groups, one_init, e, j.Out(oy, ox, blk), 0);
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
      Int8TileUpTo<V, MR, NV>(r, xs, ws, t, j.groups, init, e, j.Out(oy, ox, blk), j.out_pixel);
    };

    for (int ox = 0; ox < j.x_lo; ++ox) single(ox);
    if (j.x_lo < j.x_hi && j.phases && iy0 >= 0 && iy0 + 3 <= j.src_h) {
      Int8PhaseRow<V, MR, NV>(j, blk, e, oy, iy0);
    } else if (j.x_lo < j.x_hi) {
      int n = 0;
      for (int ky = ky_lo; ky < ky_hi; ++ky) {
        for (int kx = 0; kx < j.kw; ++kx) {
          ws[n] = wblk + (ky * j.kw + kx) * j.tap_bytes;
          ss[n] = sblk + (ky * j.kw + kx) * kNr;
          ++n;
        }
      }
      Int8ZeroPointInit<V, NV>(ss, n, j.coefficient, init);
      int ox = j.x_lo;
      for (; ox + MR <= j.x_hi; ox += MR) tiles(ox, MR);
      if (ox < j.x_hi) tiles(ox, j.x_hi - ox);
    }
    for (int ox = j.x_hi; ox < j.out_w; ++ox) single(ox);
  }
}

// Int8BlockRows for nv valid vectors, MR0, Mr... being the tiles' pixels for NV, NV + 1, ...
template <typename V, int NV, int MR0, int... Mr>
void Int8BlockRowsFor(int nv, const Int8Job<V>& j, int blk, int row_begin, int row_end) {
  if constexpr (sizeof...(Mr) > 0) {
    if (nv > NV) {
      Int8BlockRowsFor<V, NV + 1, Mr...>(nv, j, blk, row_begin, row_end);
      return;
    }
  }
  Int8BlockRows<V, MR0, NV>(j, blk, row_begin, row_end);
}

// Rows [row_begin, row_end) of blocks [blk_begin, blk_end): the plain convolution, or (up) the
// fused upsample's. Mr...: the tile's pixels for 1, 2, ... kNr / kLanes valid vectors.
template <typename V, int... Mr>
void Int8Rows(const Int8ConvArgs& a, bool up, int row_begin, int row_end, int blk_begin,
              int blk_end) {
  static_assert(sizeof...(Mr) == V::kNr / V::kLanes, "one tile per valid-vector count");
  const PackedInt8Conv& p = *a.conv;
  Int8Job<V> j;
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
  j.tap_bytes = static_cast<ptrdiff_t>(p.cin4) * V::kNr;
  j.out_pixel = p.out_float ? static_cast<ptrdiff_t>(a.out_f32.channels) * sizeof(float)
                            : static_cast<ptrdiff_t>(a.out_u8.channels);
  const ColumnRange inside = InsideColumns(j.out_w, j.src_w, j.kw, j.sw, j.pl);
  j.x_lo = inside.lo;
  j.x_hi = inside.hi;
  j.coefficient = V::ZeroPointCoefficient(p.in_zero_point);
  j.phases = up && p.phase_weights != nullptr;

  for (int blk = blk_begin; blk < blk_end; ++blk) {
    const int valid = MinOf(V::kNr, p.out_channels - blk * V::kNr);
    const int nv = (valid + V::kLanes - 1) / V::kLanes;
    Int8BlockRowsFor<V, 1, Mr...>(nv, j, blk, row_begin, row_end);
  }
}

// The kernel table's entries (Int8ConvRowsFn), with internal linkage as every template on V.
template <typename V, int... Mr>
void Int8ConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  Int8Rows<V, Mr...>(a, false, row_begin, row_end, blk_begin, blk_end);
}

template <typename V, int... Mr>
void Int8UpConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  Int8Rows<V, Mr...>(a, true, row_begin, row_end, blk_begin, blk_end);
}

}  // namespace sfrt::simd
