// The few-output convolutions of the AVX-512 dot-product kernels (the 64->3 output layer):
// written once over a precision F that the VNNI (int8) and AVX512_BF16 translation units each
// define and compile with their own flags, in their own anonymous namespace (as
// dot_epilogue_avx512_inl.h). A 64-output-channel tile would leave 61 of its 64 lanes empty, so
// these vectorise over input channels instead: one 64-byte load of a pixel's channels per dot
// product, one accumulator per (pixel, output channel), reduced across lanes at the end.
//
// Where a pixel's window lies inside the input, eight pixels at a time for up to 3 channels, four
// for 4 (FewOutTile): one accumulator per (pixel, channel), then the tile's P * CO values in
// pixel-major order (value CO * j + o is pixel j's channel o, as the output stores them) reduced
// 16 at a time (SumEachVector<K>, K = 16, 8 or 4 vectors), a vector epilogue over each 16 and one
// store where the output's pixels are dense. Elsewhere one pixel at a time (FewOutPixel) over the
// taps inside the input.
//
// F provides: Conv and Args (the packed convolution and a kernel call), Elem and Weight (what
// the input and few_weights hold), Acc (the accumulator vector), In (what a dot product takes),
// kPerLoad (channels per 64-byte load), OutWidth(a), Zero(), LoadX(x, left) (min(left,
// kPerLoad) channels, the rest zero), LoadW(w), Dot(acc, x, w), SumEachVector<K>(const Acc[K]),
// FinishPixel(a, oy, ox, acc, inside) (the InsideTaps were the taps inside the input), and the
// tile's epilogue: Values (the per-channel constants for kFewOutValues values, value i being
// channel i % CO), prepared once per call by Prepare(conv, values), and FinishValues<CO>(a, oy,
// ox, chunk, count, sums, values) for values 16 * chunk .. + count of the tile at (oy, ox).
#pragma once

#include <immintrin.h>

#include <cstddef>
#include <cstdint>

#include "kernels/avx512/dot_epilogue_avx512_inl.h"
#include "kernels/simd/dot_driver_inl.h"

namespace sfrt::avx512 {
namespace {

inline constexpr int kFewOutMaxChannels = 4;  // the most output channels these kernels take
// How far ahead of a tile's first pixel the last row of its window is prefetched (that row is the
// one the output row above did not read: it comes from memory).
inline constexpr size_t kFewOutPrefetchBytes = 8192;

// The values a tile's epilogue covers: P * CO (up to 8 x 3).
inline constexpr int kFewOutValues = 32;

// Lane i of the result: the sum of v[i]'s 16 lanes, for K = 16, 8 or 4 vectors (the lanes from K
// on repeat the first K), `add` being the lane-wise sum on the bits (int32 or float32). Every
// K adds each vector's lanes in the same order. The zero-masked shuffles for GCC 12, as in
// dot_epilogue_avx512_inl.h.
template <int K, typename AddFn>
inline __m512i SumEachVectorBits(const __m512i* v, AddFn add) {
  static_assert(K == 16 || K == 8 || K == 4);
  constexpr __mmask8 kAll8 = 0xFF;
  __m512i pairs[K / 2];  // per 128-bit lane: v[2i] and v[2i+1], two partial sums each
#pragma GCC unroll 8
  for (int i = 0; i < K / 2; ++i) {
    pairs[i] = add(_mm512_maskz_unpacklo_epi32(kAll, v[2 * i], v[2 * i + 1]),
                   _mm512_maskz_unpackhi_epi32(kAll, v[2 * i], v[2 * i + 1]));
  }
  __m512i quads[K / 4];  // per 128-bit lane: v[4i] .. v[4i + 3], one partial sum each
#pragma GCC unroll 4
  for (int i = 0; i < K / 4; ++i) {
    quads[i] = add(_mm512_maskz_unpacklo_epi64(kAll8, pairs[2 * i], pairs[2 * i + 1]),
                   _mm512_maskz_unpackhi_epi64(kAll8, pairs[2 * i], pairs[2 * i + 1]));
  }
  // Then across the 128-bit lanes: even lanes plus odd lanes, twice.
  constexpr int kEven = 0x88, kOdd = 0xDD;
  const auto across = [&](__m512i x, __m512i y) {
    return add(_mm512_maskz_shuffle_i32x4(kAll, x, y, kEven),
               _mm512_maskz_shuffle_i32x4(kAll, x, y, kOdd));
  };
  if constexpr (K == 16) {
    return across(across(quads[0], quads[1]), across(quads[2], quads[3]));
  } else {
    const __m512i halves = across(quads[0], quads[K / 4 - 1]);
    return across(halves, halves);
  }
}

// The taps of one pixel's window that lie inside the input: [ky0, ky1) x [kx0, kx1).
struct InsideTaps {
  int ky0, ky1, kx0, kx1;
};

template <typename F>
void FewOutPixel(const typename F::Args& a, int oy, int ox) {
  const typename F::Conv& p = *a.conv;
  const int cin = p.in_channels, cout = p.out_channels;
  const ptrdiff_t row = static_cast<ptrdiff_t>(cout) * p.few_ci_stride;
  const int iy0 = oy * p.stride_h - a.pads.top;
  const int ix0 = ox * p.stride_w - a.pads.left;
  const InsideTaps in{simd::MaxOf(0, -iy0), simd::MinOf(p.kernel_h, a.in.height - iy0),
                      simd::MaxOf(0, -ix0), simd::MinOf(p.kernel_w, a.in.width - ix0)};
  typename F::Acc acc[kFewOutMaxChannels];
  for (int o = 0; o < cout; ++o) acc[o] = F::Zero();
  for (int ky = in.ky0; ky < in.ky1; ++ky) {
    for (int kx = in.kx0; kx < in.kx1; ++kx) {
      const typename F::Elem* x = a.in.pixel(iy0 + ky, ix0 + kx);
      const typename F::Weight* w = p.few_weights + (ky * p.kernel_w + kx) * row;
      for (int c = 0; c < cin; c += F::kPerLoad) {
        const typename F::In xv = F::LoadX(x + c, cin - c);
        for (int o = 0; o < cout; ++o) {
          acc[o] = F::Dot(acc[o], xv, F::LoadW(w + o * p.few_ci_stride + c));
        }
      }
    }
  }
  F::FinishPixel(a, oy, ox, acc, in);
}

// One input-channel chunk of FewOutAccumulate at one tap: `left` channels from x (min(left,
// kPerLoad)) of each of the P pixels, `next` elements apart, against CO weight rows from w.
template <typename F, int CO, int P>
inline void FewOutChunk(typename F::Acc (&acc)[P][CO], const typename F::Elem* x, ptrdiff_t next,
                        const typename F::Weight* w, int w_stride, int left) {
  typename F::In wv[CO];
#pragma GCC unroll 4
  for (int o = 0; o < CO; ++o) wv[o] = F::LoadW(w + o * w_stride);
#pragma GCC unroll 8
  for (int j = 0; j < P; ++j) {
    const typename F::In xv = F::LoadX(x + j * next, left);
#pragma GCC unroll 4
    for (int o = 0; o < CO; ++o) acc[j][o] = F::Dot(acc[j][o], xv, wv[o]);
  }
}

// Values 16 * C .. 16 * C + 15 of a tile's P * CO (value CO * j + o: pixel j's channel o), those
// that exist: reduced, then F's epilogue.
template <typename F, int CO, int P, int C>
inline void FewOutFinish(const typename F::Args& a, int oy, int ox, const typename F::Acc* sums,
                         const typename F::Values& values) {
  constexpr int kFirst = 16 * C, kCount = P * CO - kFirst < 16 ? P * CO - kFirst : 16;
  constexpr int K = kCount > 8 ? 16 : kCount > 4 ? 8 : 4;
  typename F::Acc lanes[K];
#pragma GCC unroll 16
  for (int i = 0; i < K; ++i) {
    lanes[i] = i < kCount ? sums[kFirst + i] : F::Zero();
  }
  F::template FinishValues<CO>(a, oy, ox, C, kCount, F::template SumEachVector<K>(lanes), values);
}

// The sums of pixels ox .. ox + P - 1 of row oy, every tap inside the input, CO output channels,
// into sums[CO * j + o] (pixel j, channel o). One base pointer per tap, the pixels at fixed
// distances from it; the input channels in whole loads, then a masked one for what is left. Its
// own function: inlined with the epilogue, GCC 12 spills the accumulators inside the loop.
template <typename F, int CO, int P>
[[gnu::noinline]] void FewOutAccumulate(const typename F::Args& a, int oy, int ox,
                                        typename F::Acc* sums) {
  static_assert(P * CO + CO + 1 <= 32, "the tile's registers: 32 zmm");
  const typename F::Conv& p = *a.conv;
  const int cin = p.in_channels, w_stride = p.few_ci_stride;
  const int whole = cin - cin % F::kPerLoad;          // channels in whole loads
  const ptrdiff_t next = p.stride_w * a.in.stride();  // one pixel's window to the next's
  const ptrdiff_t tap_weights = static_cast<ptrdiff_t>(CO) * w_stride;
  const typename F::Elem* x_row =
      a.in.pixel(oy * p.stride_h - a.pads.top, ox * p.stride_w - a.pads.left);
  const typename F::Weight* w = p.few_weights;
  typename F::Acc acc[P][CO];
#pragma GCC unroll 8
  for (int j = 0; j < P; ++j) {
#pragma GCC unroll 4
    for (int o = 0; o < CO; ++o) acc[j][o] = F::Zero();
  }
  simd::PrefetchAhead(x_row + (p.kernel_h - 1) * a.in.row_stride, kFewOutPrefetchBytes,
                      P * next * sizeof(typename F::Elem));
  for (int ky = 0; ky < p.kernel_h; ++ky, x_row += a.in.row_stride) {
    const typename F::Elem* x = x_row;
    for (int kx = 0; kx < p.kernel_w; ++kx, x += a.in.stride(), w += tap_weights) {
      for (int c = 0; c < whole; c += F::kPerLoad) {
        FewOutChunk<F, CO, P>(acc, x + c, next, w + c, w_stride, F::kPerLoad);
      }
      if (whole < cin)
        FewOutChunk<F, CO, P>(acc, x + whole, next, w + whole, w_stride, cin - whole);
    }
  }
#pragma GCC unroll 8
  for (int j = 0; j < P; ++j) {
#pragma GCC unroll 4
    for (int o = 0; o < CO; ++o) sums[CO * j + o] = acc[j][o];
  }
}

// Pixels ox .. ox + P - 1 of row oy (P a multiple of 4), every tap inside the input; CO output
// channels.
template <typename F, int CO, int P>
void FewOutTile(const typename F::Args& a, int oy, int ox, const typename F::Values& values) {
  static_assert(P % 4 == 0 && P * CO <= kFewOutValues);
  typename F::Acc sums[P * CO];
  FewOutAccumulate<F, CO, P>(a, oy, ox, sums);
  FewOutFinish<F, CO, P, 0>(a, oy, ox, sums, values);
  if constexpr (P * CO > 16) FewOutFinish<F, CO, P, 1>(a, oy, ox, sums, values);
}

// Pixels a tile of FewOutTile holds for CO output channels: 8 for up to 3 (24 accumulators, 3
// weight vectors and one input: 28 of the 32 zmm), 4 for 4 (16 values: one reduction).
template <int CO>
inline constexpr int kFewOutTilePixels = CO <= 3 ? 8 : 4;

template <typename F, int CO>
void FewOutRowsOf(const typename F::Args& a, int row_begin, int row_end) {
  const typename F::Conv& p = *a.conv;
  const int out_w = F::OutWidth(a);
  const int x_begin = simd::MaxOf(0, a.col_begin), x_end = simd::MinOf(out_w, a.col_end);
  // Columns whose window is inside the input: [inside_lo, inside_hi).
  const int inside_lo = (a.pads.left + p.stride_w - 1) / p.stride_w;
  const int last = a.in.width - p.kernel_w + a.pads.left;  // the last window's first column
  const int inside_hi = last < 0 ? inside_lo : simd::MaxOf(inside_lo, last / p.stride_w + 1);
  const int tile_end = simd::MinOf(inside_hi, x_end);
  constexpr int kPixels = kFewOutTilePixels<CO>;
  typename F::Values values;
  F::Prepare(p, values);
  for (int oy = row_begin; oy < row_end; ++oy) {
    const int iy0 = oy * p.stride_h - a.pads.top;
    const bool rows_inside = iy0 >= 0 && iy0 + p.kernel_h <= a.in.height;
    int ox = x_begin;
    while (ox < x_end) {
      const bool inside = rows_inside && ox >= inside_lo;
      if (inside && ox + kPixels <= tile_end) {
        FewOutTile<F, CO, kPixels>(a, oy, ox, values);
        ox += kPixels;
      } else if (inside && ox + 4 <= tile_end) {
        FewOutTile<F, CO, 4>(a, oy, ox, values);
        ox += 4;
      } else {
        FewOutPixel<F>(a, oy, ox);
        ++ox;
      }
    }
  }
}

// Rows [row_begin, row_end) of a convolution with 1..kFewOutMaxChannels outputs and
// few_weights (its one block: callers pass only block 0's calls).
template <typename F>
void FewOutRows(const typename F::Args& a, int row_begin, int row_end) {
  switch (a.conv->out_channels) {
    case 1:
      FewOutRowsOf<F, 1>(a, row_begin, row_end);
      break;
    case 2:
      FewOutRowsOf<F, 2>(a, row_begin, row_end);
      break;
    case 3:
      FewOutRowsOf<F, 3>(a, row_begin, row_end);
      break;
    default:
      FewOutRowsOf<F, 4>(a, row_begin, row_end);
      break;
  }
}

// Stores `count` lanes of a tile's values from value 16 * chunk, value i being pixel i / CO's
// channel i % CO from `first` (the tile's first pixel), its pixels pixel_stride elements apart.
// store(dst, mask) writes the lanes of `mask` from dst on, lane 0 at dst. One store where the
// pixels are dense; else through a copy, lane by lane.
template <int CO, typename T, typename StoreFn>
inline void StoreValues(T* first, ptrdiff_t pixel_stride, int chunk, int count, StoreFn store) {
  const __mmask16 lanes = count >= 16 ? kAll : static_cast<__mmask16>((1u << count) - 1u);
  if (pixel_stride == CO) {
    store(first + 16 * chunk, lanes);
    return;
  }
  alignas(64) T copy[16];
  store(copy, lanes);
  for (int i = 0; i < count; ++i) {
    const int v = 16 * chunk + i;
    first[(v / CO) * pixel_stride + v % CO] = copy[i];
  }
}

}  // namespace
}  // namespace sfrt::avx512
