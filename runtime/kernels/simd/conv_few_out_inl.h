// Convolutions with very few output channels (SceneEDNet's 64 -> 3 output layer), shared by every
// SIMD tier over the vector vocabulary of conv_driver_inl.h plus ReduceAdd(Reg) -> float.
// The output-channel-blocked tile would fill most of its lanes with padding (3 of 8 or 16), so
// here the vectors run over input channels instead: per tap, R pixels x CO outputs accumulate
// x[pixel][ci..ci+L) * w[tap][co][ci..ci+L), and each accumulator is summed across its lanes
// once per pixel at the end. Weights: PackedConv::few_weights, [taps][CO][few_ci_stride], zero
// beyond in_channels. Templates only (internal linkage per ISA translation unit).
#pragma once

#include <cstddef>
#include <type_traits>

#include "kernels/conv_job.h"
#include "kernels/simd/conv_driver_inl.h"

namespace sfrt::simd {

template <typename V, int R, int CO>
inline void FewOutTile(const float* const* xs, const float* const* ws, int taps, ptrdiff_t x_step,
                       int cin, int ci_stride, const float* bias, float* out, ptrdiff_t out_step,
                       Activation act, float slope) {
  constexpr int kL = V::kLanes;
  using Reg = typename V::Reg;
  Reg acc[R][CO];
#pragma GCC unroll 8
  for (int m = 0; m < R; ++m) {
#pragma GCC unroll 4
    for (int co = 0; co < CO; ++co) acc[m][co] = V::Set(0.0f);
  }
  // One chunk of kL input channels (the last one partial: n < kL lanes, the rest loaded as 0).
  auto chunk = [&](const float* x, const float* w, int c, auto partial, int n) {
    Reg wv[CO];
#pragma GCC unroll 4
    for (int co = 0; co < CO; ++co) wv[co] = V::Load(w + co * ci_stride + c);
#pragma GCC unroll 8
    for (int m = 0; m < R; ++m) {
      const float* src = x + m * x_step + c;
      Reg xv;
      if constexpr (decltype(partial)::value) {
        xv = V::LoadPartial(src, n);
      } else {
        xv = V::Load(src);
      }
#pragma GCC unroll 4
      for (int co = 0; co < CO; ++co) acc[m][co] = V::Fma(xv, wv[co], acc[m][co]);
    }
  };
  // The full chunks in a loop of their own: with the partial load's mask inside it, R x CO
  // accumulators + CO weights + 1 input that fill the registers exactly (AVX2's 4 x 3 of 16)
  // spilled an accumulator, a load-FMA-store chain through the stack on every chunk.
  const int full = cin - cin % kL;
  for (int t = 0; t < taps; ++t) {
    for (int c = 0; c < full; c += kL) chunk(xs[t], ws[t], c, std::false_type{}, kL);
    if (full < cin) chunk(xs[t], ws[t], full, std::true_type{}, cin - full);
  }
#pragma GCC unroll 8
  for (int m = 0; m < R; ++m) {
#pragma GCC unroll 4
    for (int co = 0; co < CO; ++co) {
      float r = V::ReduceAdd(acc[m][co]) + bias[co];
      if (act == Activation::kLeakyRelu) {
        r = r > 0.0f ? r : r * slope;
      } else if (act == Activation::kRelu) {
        r = r > 0.0f ? r : 0.0f;
      }
      out[m * out_step + co] = r;
    }
  }
}

template <typename V, int R, int CO>
inline void FewOutTileUpTo(int r, const float* const* xs, const float* const* ws, int taps,
                           ptrdiff_t x_step, int cin, int ci_stride, const float* bias, float* out,
                           ptrdiff_t out_step, Activation act, float slope) {
  if constexpr (R > 1) {
    if (r < R) {
      FewOutTileUpTo<V, R - 1, CO>(r, xs, ws, taps, x_step, cin, ci_stride, bias, out, out_step,
                                   act, slope);
      return;
    }
  }
  FewOutTile<V, R, CO>(xs, ws, taps, x_step, cin, ci_stride, bias, out, out_step, act, slope);
}

// Output rows [row_begin, row_end) of a convolution with exactly CO output channels (one block).
// With Ahead > 0, each tile first prefetches the last row of its window Ahead bytes ahead: the row
// the output row above did not read, which comes from memory.
template <typename V, int MR, int CO, size_t Ahead>
void FewOutRows(const ConvArgs& a, int row_begin, int row_end) {
  const PackedConv& p = *a.conv;
  const int cin = p.in_channels, cs = p.few_ci_stride;
  const int kh = p.kernel_h, kw = p.kernel_w, sh = p.stride_h, sw = p.stride_w;
  const ptrdiff_t tap_floats = static_cast<ptrdiff_t>(CO) * cs;
  const int pt = a.pads.top, pl = a.pads.left;
  const int in_h = a.in.height, in_w = a.in.width, out_w = a.out.width;
  const Activation act = p.activation;
  const float slope = p.leaky_slope;
  const ColumnRange inside = InsideColumns(out_w, in_w, kw, sw, pl);
  const int x_lo = inside.lo, x_hi = inside.hi;
  const ptrdiff_t x_step = static_cast<ptrdiff_t>(sw) * cin;
  const float* xs[kMaxConvTaps];
  const float* ws[kMaxConvTaps];
  for (int oy = row_begin; oy < row_end; ++oy) {
    const int iy0 = oy * sh - pt;
    const int ky_lo = MaxOf(0, -iy0);
    const int ky_hi = MinOf(kh, in_h - iy0);
    float* orow = a.out.pixel(oy, 0);
    auto single = [&](int ox) {
      int n = 0;
      const int ix0 = ox * sw - pl;
      for (int ky = ky_lo; ky < ky_hi; ++ky) {
        for (int kx = 0; kx < kw; ++kx) {
          const int ix = ix0 + kx;
          if (ix < 0 || ix >= in_w) continue;
          xs[n] = a.in.pixel(iy0 + ky, ix);
          ws[n] = p.few_weights + (ky * kw + kx) * tap_floats;
          ++n;
        }
      }
      FewOutTile<V, 1, CO>(xs, ws, n, 0, cin, cs, p.bias, orow + static_cast<ptrdiff_t>(ox) * CO, 0,
                           act, slope);
    };
    for (int ox = 0; ox < x_lo; ++ox) single(ox);
    int ox = x_lo;
    if (ox < x_hi) {
      int n = 0;
      for (int ky = ky_lo; ky < ky_hi; ++ky) {
        for (int kx = 0; kx < kw; ++kx) ws[n++] = p.few_weights + (ky * kw + kx) * tap_floats;
      }
      for (; ox < x_hi; ox += MR) {
        int t = 0;
        const int ix0 = ox * sw - pl;
        if constexpr (Ahead > 0) {
          PrefetchAhead(a.in.pixel(iy0 + ky_hi - 1, ix0), Ahead, MR * x_step * sizeof(float));
        }
        for (int ky = ky_lo; ky < ky_hi; ++ky) {
          for (int kx = 0; kx < kw; ++kx) xs[t++] = a.in.pixel(iy0 + ky, ix0 + kx);
        }
        FewOutTileUpTo<V, MR, CO>(MinOf(MR, x_hi - ox), xs, ws, n, x_step, cin, cs, p.bias,
                                  orow + static_cast<ptrdiff_t>(ox) * CO, CO, act, slope);
      }
      ox = x_hi;
    }
    for (; ox < out_w; ++ox) single(ox);
  }
}

// Pixels per tile for CO outputs: at most MR, and no more than the R x CO accumulators, CO
// weights and one input that fit V's registers (a spilled accumulator costs a store and a
// reload on every chunk of every tap).
template <typename V, int MR, int CO>
constexpr int FewOutPixels() {
  constexpr int fit = (V::kRegs - CO - 1) / CO;
  return fit < MR ? fit : MR;
}

// ConvRowsFn for 1..kFewOutChannels output channels, up to MR pixels a tile, prefetching Ahead
// bytes ahead (0: not at all; FewOutRows).
template <typename V, int MR, size_t Ahead>
void FewOutConvRows(const ConvArgs& a, int row_begin, int row_end, int, int) {
  switch (a.conv->out_channels) {
    case 1:
      FewOutRows<V, FewOutPixels<V, MR, 1>(), 1, Ahead>(a, row_begin, row_end);
      break;
    case 2:
      FewOutRows<V, FewOutPixels<V, MR, 2>(), 2, Ahead>(a, row_begin, row_end);
      break;
    case 3:
      FewOutRows<V, FewOutPixels<V, MR, 3>(), 3, Ahead>(a, row_begin, row_end);
      break;
    default:
      FewOutRows<V, FewOutPixels<V, MR, 4>(), 4, Ahead>(a, row_begin, row_end);
      break;
  }
}

}  // namespace sfrt::simd
