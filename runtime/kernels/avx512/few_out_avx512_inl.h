// The few-output convolutions of the AVX-512 dot-product kernels (the 64->3 output layer):
// written once over a precision F that the VNNI (int8) and AVX512_BF16 translation units each
// define and compile with their own flags, in their own anonymous namespace (as
// dot_epilogue_avx512_inl.h). A 64-output-channel tile would leave 61 of its 64 lanes empty, so
// these vectorise over input channels instead: one 64-byte load of a pixel's channels per dot
// product, one accumulator per (pixel, output channel), reduced across lanes at the end.
//
// Where a pixel's window lies inside the input, eight pixels at a time for up to 3 channels, four
// for 4 (FewOutTile): one accumulator per (pixel, channel), then per four pixels one reduction
// of 16 vectors (SumEachVector), lane 4 * j + o being pixel j's channel o, and a vector
// epilogue. Elsewhere one pixel at a time (FewOutPixel) over the taps inside the input.
//
// F provides: Conv and Args (the packed convolution and a kernel call), Elem and Weight (what
// the input and few_weights hold), Acc (the accumulator vector), In (what a dot product takes),
// kPerLoad (channels per 64-byte load), OutWidth(a), Zero(), LoadX(x, left) (min(left,
// kPerLoad) channels, the rest zero), LoadW(w), Dot(acc, x, w), SumEachVector(const Acc[16]),
// FinishPixel(a, oy, ox, acc, inside) (the InsideTaps were the taps inside the input), a Quad
// epilogue prepared once per call by Prepare(conv, quad), and FinishQuad<CO>(a, oy, ox, sums,
// quad).
#pragma once

#include <immintrin.h>

#include <cstddef>
#include <cstdint>

#include "kernels/avx512/dot_epilogue_avx512_inl.h"
#include "kernels/simd/dot_driver_inl.h"

namespace sfrt::avx512 {
namespace {

inline constexpr int kFewOutMaxChannels = 4;  // lanes 4 * pixel + channel of one vector
// How far ahead of a tile's first pixel the last row of its window is prefetched (that row is the
// one the output row above did not read: it comes from memory).
inline constexpr size_t kFewOutPrefetchBytes = 8192;

// Lane i of the result: the sum of v[i]'s 16 lanes, `add` being the lane-wise sum on the bits
// (int32 or float32). The zero-masked shuffles for GCC 12, as in dot_epilogue_avx512_inl.h.
template <typename AddFn>
inline __m512i SumEachVectorBits(const __m512i* v, AddFn add) {
  constexpr __mmask8 kAll8 = 0xFF;
  __m512i pairs[8];  // per 128-bit lane: v[2i] and v[2i+1], two partial sums each
#pragma GCC unroll 8
  for (int i = 0; i < 8; ++i) {
    pairs[i] = add(_mm512_maskz_unpacklo_epi32(kAll, v[2 * i], v[2 * i + 1]),
                   _mm512_maskz_unpackhi_epi32(kAll, v[2 * i], v[2 * i + 1]));
  }
  __m512i quads[4];  // per 128-bit lane: v[4i] .. v[4i + 3], one partial sum each
#pragma GCC unroll 4
  for (int i = 0; i < 4; ++i) {
    quads[i] = add(_mm512_maskz_unpacklo_epi64(kAll8, pairs[2 * i], pairs[2 * i + 1]),
                   _mm512_maskz_unpackhi_epi64(kAll8, pairs[2 * i], pairs[2 * i + 1]));
  }
  // Then across the 128-bit lanes: even lanes plus odd lanes, twice.
  constexpr int kEven = 0x88, kOdd = 0xDD;
  const __m512i low = add(_mm512_maskz_shuffle_i32x4(kAll, quads[0], quads[1], kEven),
                          _mm512_maskz_shuffle_i32x4(kAll, quads[0], quads[1], kOdd));
  const __m512i high = add(_mm512_maskz_shuffle_i32x4(kAll, quads[2], quads[3], kEven),
                           _mm512_maskz_shuffle_i32x4(kAll, quads[2], quads[3], kOdd));
  return add(_mm512_maskz_shuffle_i32x4(kAll, low, high, kEven),
             _mm512_maskz_shuffle_i32x4(kAll, low, high, kOdd));
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

// One input-channel chunk of FewOutTile at one tap: `left` channels from x (min(left,
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

// Pixels ox .. ox + P - 1 of row oy (P a multiple of 4), every tap inside the input; CO output
// channels. One base pointer per tap, the pixels at fixed distances from it; the input
// channels in whole loads, then a masked one for what is left.
template <typename F, int CO, int P>
void FewOutTile(const typename F::Args& a, int oy, int ox, const typename F::Quad& quad) {
  static_assert(P % 4 == 0 && P * CO + CO + 1 <= 32, "the tile's registers: 32 zmm");
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
#pragma GCC unroll 2
  for (int q = 0; q < P / 4; ++q) {
    typename F::Acc lanes[16];  // [pixel * 4 + output], the outputs from CO on zero
#pragma GCC unroll 16
    for (int i = 0; i < 16; ++i) lanes[i] = i % 4 < CO ? acc[4 * q + i / 4][i % 4] : F::Zero();
    F::template FinishQuad<CO>(a, oy, ox + 4 * q, F::SumEachVector(lanes), quad);
  }
}

// Pixels a tile of FewOutTile holds for CO output channels: 8 for up to 3 (24 accumulators, 3
// weight vectors and one input: 28 of the 32 zmm), 4 for 4 (a multiple of the four pixels that one
// reduction takes).
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
  typename F::Quad quad;
  F::Prepare(p, quad);
  for (int oy = row_begin; oy < row_end; ++oy) {
    const int iy0 = oy * p.stride_h - a.pads.top;
    const bool rows_inside = iy0 >= 0 && iy0 + p.kernel_h <= a.in.height;
    int ox = x_begin;
    while (ox < x_end) {
      const bool inside = rows_inside && ox >= inside_lo;
      if (inside && ox + kPixels <= tile_end) {
        FewOutTile<F, CO, kPixels>(a, oy, ox, quad);
        ox += kPixels;
      } else if (inside && ox + 4 <= tile_end) {
        FewOutTile<F, CO, 4>(a, oy, ox, quad);
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

// Stores lanes 4 * j .. 4 * j + CO - 1 of y as pixel j's channels, for the 4 float32 pixels
// from (oy, ox) of `out`.
template <int CO, typename View>
inline void StoreQuadFloat(const View& out, int oy, int ox, __m512 y) {
  constexpr __mmask16 kOutputs = (1u << CO) - 1u;
#pragma GCC unroll 4
  for (int j = 0; j < 4; ++j) {
    _mm512_mask_storeu_ps(out.pixel(oy, ox + j), kOutputs,
                          _mm512_maskz_compress_ps(static_cast<__mmask16>(0xFu << (4 * j)), y));
  }
}

}  // namespace
}  // namespace sfrt::avx512
