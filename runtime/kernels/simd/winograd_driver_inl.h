// The Winograd F(m x m, 3 x 3) passes (kernels/winograd_job.h) shared by every SIMD tier, over
// the same vector vocabulary `V` as conv_driver_inl.h plus Add(a, b), Sub(a, b) and Set(float).
// Transforms are vectorised over channels (NHWC keeps them contiguous); the products reuse the
// direct convolution's register tile (ConvTile with one tap), so each point's matrix product
// runs on the same micro-kernel as the direct convolution. Templates only, for the same reason
// as conv_driver_inl.h (internal linkage per ISA translation unit).
#pragma once

#include <cstddef>

#include "kernels/simd/conv_driver_inl.h"
#include "kernels/winograd_job.h"

namespace sfrt::simd {

// acc + c * x for a transform constant c known at compile time once the loops are unrolled
// (c = 0 is skipped by the callers; 1 and -1 need no multiply).
template <typename V>
inline typename V::Reg WinogradTerm(float c, typename V::Reg x, typename V::Reg acc) {
  if (c == 1.0f) return V::Add(acc, x);
  if (c == -1.0f) return V::Sub(acc, x);
  return V::Fma(V::Set(c), x, acc);
}

// First half of an output transform, for the channels from c on: t = AT m, where m's point
// (k, j) is at src + (k * alpha + j) * point_stride.
template <typename V, typename T>
inline void WinogradOutputColumns(const float* src, ptrdiff_t point_stride, int c,
                                  typename V::Reg (&t)[T::kM][T::kAlpha]) {
  constexpr int kA = T::kAlpha, kM = T::kM;
  using Reg = typename V::Reg;
  const Reg zero = V::Set(0.0f);
#pragma GCC unroll 6
  for (int j = 0; j < kA; ++j) {
    Reg col[kA];
#pragma GCC unroll 6
    for (int k = 0; k < kA; ++k) col[k] = V::Load(src + (k * kA + j) * point_stride + c);
#pragma GCC unroll 4
    for (int i = 0; i < kM; ++i) {
      Reg acc = zero;
#pragma GCC unroll 6
      for (int k = 0; k < kA; ++k) {
        if (T::kAt[i][k] != 0.0f) acc = WinogradTerm<V>(T::kAt[i][k], col[k], acc);
      }
      t[i][j] = acc;
    }
  }
}

// Second half for output pixel column j of row t: act((t A)[j] + bias), stored as the first n
// (<= kLanes) channels at dst.
template <typename V, typename T>
inline void WinogradStoreOutput(const typename V::Reg (&t)[T::kAlpha], int j, typename V::Reg bias,
                                Activation act, float slope, float* dst, int n) {
  typename V::Reg acc = bias;
#pragma GCC unroll 6
  for (int k = 0; k < T::kAlpha; ++k) {
    if (T::kAt[j][k] != 0.0f) acc = WinogradTerm<V>(T::kAt[j][k], t[k], acc);
  }
  if (act == Activation::kLeakyRelu) {
    acc = V::Leaky(acc, slope);
  } else if (act == Activation::kRelu) {
    acc = V::Relu(acc);
  }
  if (n == V::kLanes) {
    V::Store(dst, acc);
  } else {
    V::StorePartial(dst, acc, n);
  }
}

// Pass 1: v[p][tile][c] = (BT d B)[p] for tiles [begin, end).
template <typename V, typename T>
void WinogradInput(const WinogradArgs& a, int begin, int end) {
  constexpr int kA = T::kAlpha, kM = T::kM, kL = V::kLanes;
  using Reg = typename V::Reg;
  const PackedWinograd& w = *a.conv;
  const int cin = w.in_channels;
  const ptrdiff_t tiles = static_cast<ptrdiff_t>(a.tiles_h) * a.tiles_w;
  const ptrdiff_t point_stride = tiles * w.k_stride;
  const Reg zero = V::Set(0.0f);
  for (int tile = begin; tile < end; ++tile) {
    const int ty = tile / a.tiles_w, tx = tile % a.tiles_w;
    const int iy0 = ty * kM - a.pads.top, ix0 = tx * kM - a.pads.left;
    const float* src[kA][kA];  // null: outside the image (zero padding)
    for (int i = 0; i < kA; ++i) {
      for (int j = 0; j < kA; ++j) {
        const int iy = iy0 + i, ix = ix0 + j;
        const bool inside = iy >= 0 && iy < a.in.height && ix >= 0 && ix < a.in.width;
        src[i][j] = inside ? a.in.pixel(iy, ix) : nullptr;
      }
    }
    float* dst = a.v + static_cast<ptrdiff_t>(tile) * w.k_stride;
    for (int c = 0; c < cin; c += kL) {
      const int n = cin - c < kL ? cin - c : kL;
      Reg d[kA][kA];
#pragma GCC unroll 6
      for (int i = 0; i < kA; ++i) {
#pragma GCC unroll 6
        for (int j = 0; j < kA; ++j) {
          const float* s = src[i][j];
          d[i][j] = s == nullptr ? zero : (n == kL ? V::Load(s + c) : V::LoadPartial(s + c, n));
        }
      }
      Reg t[kA][kA];  // BT d
#pragma GCC unroll 6
      for (int i = 0; i < kA; ++i) {
#pragma GCC unroll 6
        for (int j = 0; j < kA; ++j) {
          Reg acc = zero;
#pragma GCC unroll 6
          for (int k = 0; k < kA; ++k) {
            if (T::kBt[i][k] != 0.0f) acc = WinogradTerm<V>(T::kBt[i][k], d[k][j], acc);
          }
          t[i][j] = acc;
        }
      }
#pragma GCC unroll 6
      for (int i = 0; i < kA; ++i) {
#pragma GCC unroll 6
        for (int j = 0; j < kA; ++j) {
          Reg acc = zero;
#pragma GCC unroll 6
          for (int k = 0; k < kA; ++k) {
            if (T::kBt[j][k] != 0.0f) acc = WinogradTerm<V>(T::kBt[j][k], t[i][k], acc);
          }
          V::Store(dst + (i * kA + j) * point_stride + c, acc);
        }
      }
    }
  }
}

// Pass 2: m[p][tile][block] = v[p][tile][:] x weights[p][block] for items [begin, end),
// item = p * blocks + block, on the direct convolution's MR x NV register tile.
template <typename V, int MR, int NV>
void WinogradProduct(const WinogradArgs& a, int begin, int end) {
  constexpr int kNr = NV * V::kLanes;
  const PackedWinograd& w = *a.conv;
  const int cin = w.in_channels;
  const int tiles = a.tiles_h * a.tiles_w;
  const ptrdiff_t ks = w.k_stride, ns = w.n_stride;
  const float* xs[1];
  const float* ws[1];
  for (int item = begin; item < end; ++item) {
    const int p = item / w.blocks, blk = item % w.blocks;
    const float* vp = a.v + static_cast<ptrdiff_t>(p) * tiles * ks;
    float* mp = a.m + static_cast<ptrdiff_t>(p) * tiles * ns + blk * kNr;
    ws[0] = w.weights + (static_cast<ptrdiff_t>(p) * w.blocks + blk) * cin * kNr;
    int t = 0;
    for (; t + MR <= tiles; t += MR) {
      xs[0] = vp + t * ks;
      ConvTile<V, MR, NV>(xs, ws, 1, ks, cin, w.zeros, mp + t * ns, ns, kNr, true, true,
                          Activation::kNone, 0.0f);
    }
    if (t < tiles) {
      xs[0] = vp + t * ks;
      ConvTileUpTo<V, MR - 1, NV>(tiles - t, xs, ws, 1, ks, cin, w.zeros, mp + t * ns, ns, kNr,
                                  true, true, Activation::kNone, 0.0f);
    }
  }
}

// Pass 3: out = act(AT m A + bias) for tiles [begin, end), clipped at the image's edges.
template <typename V, typename T>
void WinogradOutput(const WinogradArgs& a, int begin, int end) {
  constexpr int kA = T::kAlpha, kM = T::kM, kL = V::kLanes;
  using Reg = typename V::Reg;
  const PackedWinograd& w = *a.conv;
  const int cout = w.out_channels;
  const ptrdiff_t tiles = static_cast<ptrdiff_t>(a.tiles_h) * a.tiles_w;
  const ptrdiff_t point_stride = tiles * w.n_stride;
  const Activation act = w.activation;
  const float slope = w.leaky_slope;
  for (int tile = begin; tile < end; ++tile) {
    const int ty = tile / a.tiles_w, tx = tile % a.tiles_w;
    const int oy0 = ty * kM, ox0 = tx * kM;
    const int rows = a.out.height - oy0 < kM ? a.out.height - oy0 : kM;
    const int cols = a.out.width - ox0 < kM ? a.out.width - ox0 : kM;
    const float* src = a.m + static_cast<ptrdiff_t>(tile) * w.n_stride;
    for (int c = 0; c < cout; c += kL) {
      const int n = cout - c < kL ? cout - c : kL;
      Reg t[kM][kA];  // AT m
      WinogradOutputColumns<V, T>(src, point_stride, c, t);
      const Reg bias = V::Load(w.bias + c);
#pragma GCC unroll 4
      for (int i = 0; i < kM; ++i) {
        if (i >= rows) break;
        float* orow = a.out.pixel(oy0 + i, ox0) + c;
#pragma GCC unroll 4
        for (int j = 0; j < kM; ++j) {
          if (j >= cols) break;
          WinogradStoreOutput<V, T>(t[i], j, bias, act, slope,
                                    orow + static_cast<ptrdiff_t>(j) * cout, n);
        }
      }
    }
  }
}

// Pass 3 of the fused upsample-conv (WinogradPhaseTransform): per tile, per phase, the 2x2 P
// positions' outputs = AT m A + bias, activation, each stored at its output pixel when that
// pixel is inside [y_lo, y_hi) x [x_lo, x_hi).
template <typename V>
void WinogradUpOutput(const WinogradArgs& a, int begin, int end) {
  using T = WinogradPhaseTransform;
  constexpr int kA = T::kAlpha, kM = T::kM, kL = V::kLanes;
  using Reg = typename V::Reg;
  const PackedWinograd& w = *a.conv;
  const int cout = w.out_channels;
  const ptrdiff_t tiles = static_cast<ptrdiff_t>(a.tiles_h) * a.tiles_w;
  const ptrdiff_t point_stride = tiles * w.n_stride;
  const Activation act = w.activation;
  const float slope = w.leaky_slope;
  for (int tile = begin; tile < end; ++tile) {
    const int ty = tile / a.tiles_w, tx = tile % a.tiles_w;
    const float* src = a.m + static_cast<ptrdiff_t>(tile) * w.n_stride;
    for (int ph = 0; ph < 4; ++ph) {
      const int py = ph >> 1, px = ph & 1;
      float* dst[kM][kM];  // null: not an interior pixel of this output
      bool any = false;
      for (int i = 0; i < kM; ++i) {
        for (int j = 0; j < kM; ++j) {
          const int b = 2 * ty + i - a.pads.top, c = 2 * tx + j - a.pads.left;
          const int oy = 2 * b + py - a.crop_top + a.up_pad_top;
          const int ox = 2 * c + px - a.crop_left + a.up_pad_left;
          const bool inside = oy >= a.y_lo && oy < a.y_hi && ox >= a.x_lo && ox < a.x_hi;
          dst[i][j] = inside ? a.out.pixel(oy, ox) : nullptr;
          any = any || inside;
        }
      }
      if (!any) continue;
      const float* msrc = src + ph * w.phase_stride;
      for (int c = 0; c < cout; c += kL) {
        const int n = cout - c < kL ? cout - c : kL;
        Reg t[kM][kA];  // AT m
        WinogradOutputColumns<V, T>(msrc, point_stride, c, t);
        const Reg bias = V::Load(w.bias + ph * w.phase_stride + c);
#pragma GCC unroll 2
        for (int i = 0; i < kM; ++i) {
#pragma GCC unroll 2
          for (int j = 0; j < kM; ++j) {
            if (dst[i][j] == nullptr) continue;
            WinogradStoreOutput<V, T>(t[i], j, bias, act, slope, dst[i][j] + c, n);
          }
        }
      }
    }
  }
}

}  // namespace sfrt::simd
