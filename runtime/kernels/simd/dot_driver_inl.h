// The convolution driver shared by every SIMD tier's dot-product kernels: int8 (kernels/int8_job.h:
// AVX-512 VNNI, NEON sdot/sudot) and bf16 (kernels/bf16_job.h: AVX512_BF16, NEON bfdot), written
// once over a vocabulary `V` that each kernels/<isa>/conv2d_<types>_<isa>.cc defines in its own
// anonymous namespace and compiles with its own flags. Everything here is a template on V, so
// each ISA's instantiations have internal linkage and can never be merged across translation
// units built with different flags (as conv_driver_inl.h). The int8 instantiations are bit for
// bit equal to ref::Conv2dInt8Rows (the arithmetic is int8_job.h's); the bf16 ones equal
// ref::Conv2dBf16Rows up to the order of the float32 sums.
//
// A dot-product instruction adds to each 32-bit output lane the products of one 32-bit group of
// inputs: 4 uint8 (vpdpbusd, sdot) or 2 bf16 (vdpbf16ps, bfdot). The packed weights hold input
// channels in such groups: [block][tap][group][kNr][DotTraits::kGroup].
//
// V provides: Conv (PackedInt8Conv or PackedBf16Conv), Acc (a register of kLanes int32 or float
// output channels), kLanes, kNr (output channels per packed block, Conv::nr), Zero(), and two
// functions that see the registers:
//   Accumulate<MR, NV>(xs, ws, taps, groups, init, sums): the sums of MR pixels x NV vectors over
//     `taps` taps (xs[t * MR + m] pixel m's input at tap t, ws[t] the tap's packed weights
//     [groups][kNr][kGroup]), starting from init[NV], into sums[m * NV + v];
//   Finish<NV>(acc, epilogue, out): the epilogue of one pixel's NV vectors.
// An int8 V also provides Load(const int32_t*), Add(Acc, Acc), MulScalar(Acc, int32_t) and
// ZeroPointCoefficient(z): its accumulators start from ZeroPointCoefficient(in_zero_point) times
// the tap_sums of the taps inside the input, so that the dot products end as sum (x - z) * w.
// A bf16 V's accumulators start from zero.
//
// The register tile: MR output pixels x NV vectors, NV = the block's valid channels / kLanes
// rounded up, so a layer with few output channels computes no empty vectors; each ISA names MR
// for every NV. Pixels whose window leaves the input use only the taps inside: the top and bottom
// rows in tiles along the row, the left and right columns in tiles of MR rows down the column,
// the corners one pixel at a time. The fused upsample's interior rows use the phase kernels where
// the convolution has them, on the same tiles. Where the input's pixels hold nothing but their
// groups (DotJob::dense), the interior tiles take each window row as one tap of kw times the
// groups: its pixels' bytes follow each other as its taps' packed weights do (conv0: 3 taps of 9
// groups instead of 9 of 3). MinOf, MaxOf and InsideColumns are conv_driver_inl.h's.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "kernels/bf16_job.h"
#include "kernels/int8_job.h"
#include "kernels/simd/conv_driver_inl.h"

namespace sfrt::simd {

// What the driver needs to know of each element type, by packed-convolution type.
template <typename Conv>
struct DotTraits;

template <>
struct DotTraits<PackedInt8Conv> {
  using Elem = uint8_t;
  using Weight = int8_t;
  using Args = Int8ConvArgs;
  static constexpr int kGroup = 4;  // inputs per 32-bit group
  static constexpr bool kQuantized = true;
  static int Groups(const PackedInt8Conv& p) { return p.cin4 / 4; }
  static const ByteView& LowOut(const Int8ConvArgs& a) { return a.out_u8; }
};

template <>
struct DotTraits<PackedBf16Conv> {
  using Elem = uint16_t;
  using Weight = uint16_t;
  using Args = Bf16ConvArgs;
  static constexpr int kGroup = 2;
  static constexpr bool kQuantized = false;
  static int Groups(const PackedBf16Conv& p) { return p.cin2 / 2; }
  static const Bf16View& LowOut(const Bf16ConvArgs& a) { return a.out_bf16; }
};

// One block's epilogue: int8, Int8Dequantize then Int8Quantize for a uint8 output; bf16, bias and
// activation then the bf16 rounding for a bf16 output (multiplier, inv_scale and zero_point
// unused). Trivial (no member initialisers), so it has no code that translation units built
// with different flags could share.
struct DotEpilogue {
  const float* multiplier;  // the block's kNr values
  const float* bias;
  Activation act;
  float slope;
  bool out_float;
  float inv_scale;
  int zero_point;
  int valid;  // channels of the block that exist
};

template <typename V>
using ElemOf = typename DotTraits<typename V::Conv>::Elem;
template <typename V>
using WeightOf = typename DotTraits<typename V::Conv>::Weight;

// Accumulate, then the epilogue; pixel m's output is out + m * out_step bytes.
template <typename V, int MR, int NV>
inline void DotTile(const ElemOf<V>* const* xs, const WeightOf<V>* const* ws, int taps, int groups,
                    const typename V::Acc* init, const DotEpilogue& e, void* out,
                    ptrdiff_t out_step) {
  typename V::Acc sums[MR * NV];
  V::template Accumulate<MR, NV>(xs, ws, taps, groups, init, sums);
#pragma GCC unroll 16
  for (int m = 0; m < MR; ++m) {
    V::template Finish<NV>(sums + m * NV, e, static_cast<char*>(out) + m * out_step);
  }
}

// DotTile with r pixels for a run-time r in [1, MR] (a row's leftover pixels).
template <typename V, int MR, int NV>
inline void DotTileUpTo(int r, const ElemOf<V>* const* xs, const WeightOf<V>* const* ws, int taps,
                        int groups, const typename V::Acc* init, const DotEpilogue& e, void* out,
                        ptrdiff_t out_step) {
  if constexpr (MR > 1) {
    if (r < MR) {
      DotTileUpTo<V, MR - 1, NV>(r, xs, ws, taps, groups, init, e, out, out_step);
      return;
    }
  }
  DotTile<V, MR, NV>(xs, ws, taps, groups, init, e, out, out_step);
}

// What every row of one call shares.
template <typename V>
struct DotJob {
  using T = DotTraits<typename V::Conv>;
  const typename T::Args* a = nullptr;
  bool up = false;  // reads C (the fused upsample) instead of a.in
  int kh = 0, kw = 0, sh = 1, sw = 1;
  int pt = 0, pl = 0;
  int src_h = 0, src_w = 0;  // the map the convolution reads
  int out_w = 0;
  int groups = 0;
  ptrdiff_t tap_elems = 0;  // packed weights of one tap of one block
  ptrdiff_t out_pixel = 0;  // bytes between output pixels
  int x_lo = 0, x_hi = 0;   // output columns whose window lies inside the map
  int cb = 0, ce = 0;       // the columns this call computes (Args::col_begin, col_end)
  int32_t coefficient = 0;  // int8: V::ZeroPointCoefficient(in_zero_point)
  bool phases = false;      // the fused upsample's interior from the phase kernels
  // The input's pixels hold exactly `groups` groups, so the taps along a window row read
  // consecutive pixels' bytes, as their packed weights lie: a tile takes them as one tap of
  // their groups together (DotBlockRows without the upsample, DotPhaseRow).
  bool dense = false;

  const ElemOf<V>* Source(int y, int x) const {
    if (!up) return a->in.pixel(y, x);
    return a->in.pixel((y + a->crop_top) / 2, (x + a->crop_left) / 2);
  }
  void* Out(int oy, int ox, int blk) const {
    if (a->conv->out_float) return a->out_f32.pixel(oy, ox) + blk * V::kNr;
    return T::LowOut(*a).pixel(oy, ox) + blk * V::kNr;
  }
};

// The accumulators' start for NV vectors over taps[0, n): int8, coefficient * (the sum of the
// taps' tap_sums); bf16, zero.
template <typename V, int NV>
inline void DotInit(const int32_t* const* sums, int n, int32_t coefficient, typename V::Acc* init) {
  if constexpr (DotTraits<typename V::Conv>::kQuantized) {
    typename V::Acc s[NV];
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) s[v] = V::Zero();
    for (int t = 0; t < n; ++t) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) s[v] = V::Add(s[v], V::Load(sums[t] + v * V::kLanes));
    }
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) init[v] = V::MulScalar(s[v], coefficient);
  } else {
    (void)sums;
    (void)n;
    (void)coefficient;
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) init[v] = V::Zero();
  }
}

// The tap sums of block `blk`'s tap t (int8), or null (bf16 has none).
template <typename V>
inline const int32_t* TapSums(const typename V::Conv& p, bool phase_sums, int phase, int blk,
                              int t) {
  if constexpr (DotTraits<typename V::Conv>::kQuantized) {
    const int taps = phase_sums ? 4 : p.kernel_h * p.kernel_w;
    const int32_t* base =
        phase_sums ? p.phase_tap_sums + phase * p.blocks * 4 * V::kNr : p.tap_sums;
    return base + (static_cast<ptrdiff_t>(blk) * taps + t) * V::kNr;
  } else {
    (void)p;
    (void)phase_sums;
    (void)phase;
    (void)blk;
    (void)t;
    return nullptr;
  }
}

// The interior pixels [lo, hi) of output row oy (whose 3x3 window lies inside C, first tap on C
// row iy0) from the 2x2 kernels of their phases over the low-resolution map: per column phase,
// every second output pixel, reading consecutive low-resolution pixels.
template <typename V, int MR, int NV>
void DotPhaseRow(const DotJob<V>& j, int blk, const DotEpilogue& e3x3, int oy, int iy0, int lo,
                 int hi) {
  const typename V::Conv& p = *j.a->conv;
  const int ay = iy0 + j.a->crop_top;
  const int by = ay >> 1;
  const ptrdiff_t phase_elems = static_cast<ptrdiff_t>(p.blocks) * 4 * j.tap_elems;
  const ElemOf<V>* xs[4 * MR];
  const WeightOf<V>* ws[4];
  const int32_t* ss[4];
  typename V::Acc init[NV];
  // Dense input: each phase row's 2 taps as one of twice the groups.
  const int taps = j.dense ? 2 : 4, groups = j.dense ? 2 * j.groups : j.groups;
  for (int px = 0; px < 2; ++px) {
    // First interior column of this phase: (ox - pl + crop_left) & 1 == px.
    int ox = lo + ((lo - j.pl + j.a->crop_left + px) & 1);
    if (ox >= hi) continue;
    const int phase = (ay & 1) * 2 + px;
    const WeightOf<V>* pw = p.phase_weights + phase * phase_elems + blk * 4 * j.tap_elems;
    for (int t = 0; t < 4; ++t) ss[t] = TapSums<V>(p, true, phase, blk, t);
    for (int t = 0; t < taps; ++t) ws[t] = pw + t * (4 / taps) * j.tap_elems;
    DotInit<V, NV>(ss, 4, j.coefficient, init);
    DotEpilogue e = e3x3;
    if constexpr (DotTraits<typename V::Conv>::kQuantized) {
      e.multiplier = p.phase_multiplier + phase * p.blocks * V::kNr + blk * V::kNr;
    }
    // Pixels ox, ox + 2, ... (r of them) read low-resolution columns bx, bx + 1, ...
    auto tiles = [&](int r) {
      const int bx = (ox - j.pl + j.a->crop_left) >> 1;
      for (int t = 0; t < taps; ++t) {
        const int ty = t * 2 / taps, tx = t % (taps / 2);
        for (int m = 0; m < r; ++m) xs[t * r + m] = j.a->in.pixel(by + ty, bx + m + tx);
      }
      DotTileUpTo<V, MR, NV>(r, xs, ws, taps, groups, init, e, j.Out(oy, ox, blk), 2 * j.out_pixel);
    };
    for (; ox + 2 * (MR - 1) < hi; ox += 2 * MR) tiles(MR);
    if (ox < hi) tiles((hi - ox + 1) / 2);
  }
}

// The block's epilogue fields.
template <typename V>
inline DotEpilogue BlockEpilogue(const typename V::Conv& p, int blk) {
  DotEpilogue e = {.multiplier = nullptr,
                   .bias = p.bias + blk * V::kNr,
                   .act = p.activation,
                   .slope = p.leaky_slope,
                   .out_float = p.out_float,
                   .inv_scale = 1.0f,
                   .zero_point = 0,
                   .valid = MinOf(V::kNr, p.out_channels - blk * V::kNr)};
  if constexpr (DotTraits<typename V::Conv>::kQuantized) {
    e.multiplier = p.multiplier + blk * V::kNr;
    e.inv_scale = p.out_inv_scale;
    e.zero_point = p.out_zero_point;
  }
  return e;
}

// The border columns (windows that leave the map on the left or right) of the rows in
// [row_begin, row_end) whose windows lie inside the map vertically: those pixels share their taps
// down a column, so each column goes in tiles of MR rows (the same sums as one pixel at a time).
template <typename V, int MR, int NV>
void DotBorderColumns(const DotJob<V>& j, int blk, const DotEpilogue& e, int row_begin,
                      int row_end) {
  const typename V::Conv& p = *j.a->conv;
  const WeightOf<V>* wblk = p.weights + static_cast<ptrdiff_t>(blk) * j.kh * j.kw * j.tap_elems;
  // Rows whose window rows lie inside (InsideColumns' rule, along the rows).
  const ColumnRange rows = InsideColumns(row_end, j.src_h, j.kh, j.sh, j.pt);
  const int first = MaxOf(row_begin, rows.lo), end = rows.hi;
  const ElemOf<V>* xs[kMaxInt8Taps * MR];
  const WeightOf<V>* ws[kMaxInt8Taps];
  const int32_t* ss[kMaxInt8Taps];
  typename V::Acc init[NV];
  auto column = [&](int ox) {
    const int ix0 = ox * j.sw - j.pl;
    for (int oy = first; oy < end; oy += MR) {
      const int r = MinOf(MR, end - oy);
      int n = 0;
      for (int ky = 0; ky < j.kh; ++ky) {
        for (int kx = 0; kx < j.kw; ++kx) {
          const int ix = ix0 + kx;
          if (ix < 0 || ix >= j.src_w) continue;
          for (int m = 0; m < r; ++m) xs[n * r + m] = j.Source((oy + m) * j.sh - j.pt + ky, ix);
          ws[n] = wblk + (ky * j.kw + kx) * j.tap_elems;
          ss[n] = TapSums<V>(p, false, 0, blk, ky * j.kw + kx);
          ++n;
        }
      }
      DotInit<V, NV>(ss, n, j.coefficient, init);
      void* out = j.Out(oy, ox, blk);
      const ptrdiff_t row_step =
          r > 1 ? static_cast<char*>(j.Out(oy + 1, ox, blk)) - static_cast<char*>(out) : 0;
      DotTileUpTo<V, MR, NV>(r, xs, ws, n, j.groups, init, e, out, row_step);
    }
  };
  for (int ox = j.cb; ox < MinOf(j.x_lo, j.ce); ++ox) column(ox);
  for (int ox = MaxOf(j.x_hi, j.cb); ox < j.ce; ++ox) column(ox);
}

// Output rows [row_begin, row_end) of block `blk` with the MR x NV tile.
template <typename V, int MR, int NV>
void DotBlockRows(const DotJob<V>& j, int blk, int row_begin, int row_end) {
  const typename V::Conv& p = *j.a->conv;
  const int taps = j.kh * j.kw;
  const WeightOf<V>* wblk = p.weights + static_cast<ptrdiff_t>(blk) * taps * j.tap_elems;
  const DotEpilogue e = BlockEpilogue<V>(p, blk);

  const ElemOf<V>* xs[kMaxInt8Taps * MR];
  const WeightOf<V>* ws[kMaxInt8Taps];
  const int32_t* ss[kMaxInt8Taps];
  ptrdiff_t tap_offset[kMaxInt8Taps];  // without the upsample: tap n from a pixel's first tap
  int taps_in = 0;
  const bool merge = j.dense && !j.up;  // a window row's taps as one
  const int tile_groups = merge ? j.kw * j.groups : j.groups;
  const ptrdiff_t pixel_step = j.sw * j.a->in.stride();  // one output pixel's window to the next
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
          ws[n] = wblk + (ky * j.kw + kx) * j.tap_elems;
          ss[n] = TapSums<V>(p, false, 0, blk, ky * j.kw + kx);
          ++n;
        }
      }
      typename V::Acc one_init[NV];
      DotInit<V, NV>(ss, n, j.coefficient, one_init);
      DotTile<V, 1, NV>(xs, ws, n, j.groups, one_init, e, j.Out(oy, ox, blk), 0);
    };
    // Pixels [ox, ox + r) of the interior: every kx, the rows inside. Without the upsample each
    // tap lies at one distance from each pixel's first (offsets, computed once a row).
    auto tiles = [&](int ox, int r) {
      int t = 0;
      if (!j.up) {
        const ElemOf<V>* first = j.Source(iy0 + ky_lo, ox * j.sw - j.pl);
        for (int n = 0; n < taps_in; ++n) {
          for (int m = 0; m < r; ++m) xs[t * r + m] = first + m * pixel_step + tap_offset[n];
          ++t;
        }
      } else {
        for (int ky = ky_lo; ky < ky_hi; ++ky) {
          for (int kx = 0; kx < j.kw; ++kx) {
            for (int m = 0; m < r; ++m)
              xs[t * r + m] = j.Source(iy0 + ky, (ox + m) * j.sw - j.pl + kx);
            ++t;
          }
        }
      }
      DotTileUpTo<V, MR, NV>(r, xs, ws, t, tile_groups, init, e, j.Out(oy, ox, blk), j.out_pixel);
    };

    const bool full = ky_lo == 0 && ky_hi == j.kh;  // its border columns: DotBorderColumns
    if (!full) {
      for (int ox = j.cb; ox < MinOf(j.x_lo, j.ce); ++ox) single(ox);
    }
    const int t_lo = MaxOf(j.x_lo, j.cb), t_hi = MinOf(j.x_hi, j.ce);
    if (t_lo < t_hi && j.phases && iy0 >= 0 && iy0 + 3 <= j.src_h) {
      DotPhaseRow<V, MR, NV>(j, blk, e, oy, iy0, t_lo, t_hi);
    } else if (t_lo < t_hi) {
      int n = 0, sums = 0;
      for (int ky = ky_lo; ky < ky_hi; ++ky) {
        for (int kx = 0; kx < j.kw; ++kx) {
          ss[sums++] = TapSums<V>(p, false, 0, blk, ky * j.kw + kx);
          if (merge && kx > 0) continue;  // the row's first tap reads them
          ws[n] = wblk + (ky * j.kw + kx) * j.tap_elems;
          tap_offset[n] = (ky - ky_lo) * j.a->in.row_stride + kx * j.a->in.stride();
          ++n;
        }
      }
      taps_in = n;
      DotInit<V, NV>(ss, sums, j.coefficient, init);
      int ox = t_lo;
      for (; ox + MR <= t_hi; ox += MR) tiles(ox, MR);
      if (ox < t_hi) tiles(ox, t_hi - ox);
    }
    if (!full) {
      for (int ox = MaxOf(j.x_hi, j.cb); ox < j.ce; ++ox) single(ox);
    }
  }
  DotBorderColumns<V, MR, NV>(j, blk, e, row_begin, row_end);
}

// DotBlockRows for nv valid vectors, MR0, Mr... being the tiles' pixels for NV, NV + 1, ...
template <typename V, int NV, int MR0, int... Mr>
void DotBlockRowsFor(int nv, const DotJob<V>& j, int blk, int row_begin, int row_end) {
  if constexpr (sizeof...(Mr) > 0) {
    if (nv > NV) {
      DotBlockRowsFor<V, NV + 1, Mr...>(nv, j, blk, row_begin, row_end);
      return;
    }
  }
  DotBlockRows<V, MR0, NV>(j, blk, row_begin, row_end);
}

// Rows [row_begin, row_end) of blocks [blk_begin, blk_end): the plain convolution, or (up) the
// fused upsample's. Mr...: the tile's pixels for 1, 2, ... kNr / kLanes valid vectors.
template <typename V, int... Mr>
void DotRows(const typename DotTraits<typename V::Conv>::Args& a, bool up, int row_begin,
             int row_end, int blk_begin, int blk_end) {
  using T = DotTraits<typename V::Conv>;
  static_assert(sizeof...(Mr) == V::kNr / V::kLanes, "one tile per valid-vector count");
  const typename V::Conv& p = *a.conv;
  DotJob<V> j;
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
  j.out_w = p.out_float ? a.out_f32.width : T::LowOut(a).width;
  j.groups = T::Groups(p);
  j.tap_elems = static_cast<ptrdiff_t>(j.groups) * T::kGroup * V::kNr;
  j.out_pixel = p.out_float
                    ? static_cast<ptrdiff_t>(a.out_f32.channels) * sizeof(float)
                    : T::LowOut(a).stride() * static_cast<ptrdiff_t>(sizeof(typename T::Elem));
  const ColumnRange inside = InsideColumns(j.out_w, j.src_w, j.kw, j.sw, j.pl);
  j.x_lo = inside.lo;
  j.x_hi = inside.hi;
  j.cb = MaxOf(0, a.col_begin);
  j.ce = MinOf(j.out_w, a.col_end);
  if constexpr (T::kQuantized) j.coefficient = V::ZeroPointCoefficient(p.in_zero_point);
  j.phases = up && p.phase_weights != nullptr;
  j.dense = a.in.stride() == j.groups * T::kGroup;

  for (int blk = blk_begin; blk < blk_end; ++blk) {
    const int valid = MinOf(V::kNr, p.out_channels - blk * V::kNr);
    const int nv = (valid + V::kLanes - 1) / V::kLanes;
    DotBlockRowsFor<V, 1, Mr...>(nv, j, blk, row_begin, row_end);
  }
}

// The kernel table's entries (Int8ConvRowsFn, Bf16ConvRowsFn), with internal linkage as every
// template on V.
template <typename V, int... Mr>
void DotConvRows(const typename DotTraits<typename V::Conv>::Args& a, int row_begin, int row_end,
                 int blk_begin, int blk_end) {
  DotRows<V, Mr...>(a, false, row_begin, row_end, blk_begin, blk_end);
}

template <typename V, int... Mr>
void DotUpConvRows(const typename DotTraits<typename V::Conv>::Args& a, int row_begin, int row_end,
                   int blk_begin, int blk_end) {
  DotRows<V, Mr...>(a, true, row_begin, row_end, blk_begin, blk_end);
}

}  // namespace sfrt::simd
