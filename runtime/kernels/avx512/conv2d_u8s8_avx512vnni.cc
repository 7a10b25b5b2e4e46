// AVX-512 VNNI int8 convolution kernels (compiled with -mavx512f -mavx512bw -mavx512vl -mavx512dq
// -mavx512vnni -ffp-contract=off only in this translation unit; runtime/CMakeLists.txt), bit for
// bit equal to ref::Conv2dInt8Rows: the arithmetic is kernels/int8_job.h's.
//
// Blocks of 64 output channels (PackInt8Conv with nr 64). Register tile: MR output pixels x NV
// vectors of 16 int32 channels, NV = the block's valid channels / 16 rounded up, so a layer with
// few output channels computes no empty vectors: 6x4 (24 accumulators, 4 weight vectors, one
// broadcast), 8x3, 8x2 and 8x1. Per tap and group of 4 input channels, each pixel's 4 bytes are
// broadcast and vpdpbusd adds their products with the weight vectors (u8 x s8, exact int32).
// The zero point: sum (x - z) * w = sum x * w - z * sum w, so the accumulators start from
// -z * (the tap_sums of the taps inside the input). Pixels whose window leaves the input go
// through a one-pixel tile with only those taps.
#include <immintrin.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "kernels/int8_job.h"
#include "src/cpu_features.h"

namespace sfrt::avx512 {
namespace {

constexpr int kLanes = 16;
constexpr int kNr = 64;  // output channels per block
constexpr int kMaxNv = kNr / kLanes;

inline int MinOf(int a, int b) { return a < b ? a : b; }
inline int MaxOf(int a, int b) { return a < b ? b : a; }
// floor(a / b) for b > 0.
inline int FloorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

// Four input channels of one pixel in every 32-bit lane.
inline __m512i Broadcast4(const uint8_t* p) {
  int32_t v;
  std::memcpy(&v, p, sizeof(v));
  return _mm512_set1_epi32(v);
}

// The unmasked forms of these intrinsics start from _mm512_undefined_*, which GCC 12 reports
// as -Wmaybe-uninitialized once inlined: the zero-masked forms with every lane set instead.
constexpr __mmask16 kAll = 0xFFFF;
inline __m512 ToFloat(__m512i v) { return _mm512_maskz_cvtepi32_ps(kAll, v); }
inline __m512i ToIntNearest(__m512 v) { return _mm512_maskz_cvtps_epi32(kAll, v); }
inline __m512 Max(__m512 a, __m512 b) { return _mm512_maskz_max_ps(kAll, a, b); }
inline __m512 Min(__m512 a, __m512 b) { return _mm512_maskz_min_ps(kAll, a, b); }
inline __m512i Max(__m512i a, __m512i b) { return _mm512_maskz_max_epi32(kAll, a, b); }
inline __m512i Min(__m512i a, __m512i b) { return _mm512_maskz_min_epi32(kAll, a, b); }

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
// first channel of the block: float or uint8).
template <int NV>
inline void Finish(const __m512i* acc, const Epilogue& e, void* out) {
  const __m512 zero = _mm512_setzero_ps();
#pragma GCC unroll 4
  for (int v = 0; v < NV; ++v) {
    const int left = e.valid - v * kLanes;
    const __mmask16 mask = left >= kLanes ? kAll : static_cast<__mmask16>((1u << left) - 1u);
    __m512 y = ToFloat(acc[v]);
    y = _mm512_mul_ps(y, _mm512_loadu_ps(e.multiplier + v * kLanes));
    y = _mm512_add_ps(y, _mm512_loadu_ps(e.bias + v * kLanes));
    if (e.act == Activation::kLeakyRelu) {
      const __mmask16 negative = _mm512_cmp_ps_mask(y, zero, _CMP_LT_OQ);
      y = _mm512_mask_mul_ps(y, negative, y, _mm512_set1_ps(e.slope));
    } else if (e.act == Activation::kRelu) {
      const __mmask16 positive = _mm512_cmp_ps_mask(y, zero, _CMP_GT_OQ);
      y = _mm512_maskz_mov_ps(positive, y);
    }
    if (e.out_float) {
      _mm512_mask_storeu_ps(static_cast<float*>(out) + v * kLanes, mask, y);
    } else {
      __m512 t = _mm512_mul_ps(y, _mm512_set1_ps(e.inv_scale));
      t = Max(t, _mm512_set1_ps(-512.0f));
      t = Min(t, _mm512_set1_ps(512.0f));
      __m512i q = ToIntNearest(t);  // cvtps2dq: to nearest even under the default MXCSR
      q = _mm512_add_epi32(q, _mm512_set1_epi32(e.zero_point));
      q = Max(q, _mm512_setzero_si512());
      q = Min(q, _mm512_set1_epi32(255));
      _mm512_mask_cvtepi32_storeu_epi8(static_cast<uint8_t*>(out) + v * kLanes, mask, q);
    }
  }
}

// The sums of MR pixels x NV vectors over `taps` taps: xs[t * MR + m] is pixel m's input at tap
// t, ws[t] the tap's packed weights ([groups][kNr][4]), starting from init. Its own function:
// inlined into the epilogue's, GCC 12 spills and copies the accumulators inside the loop.
template <int MR, int NV>
[[gnu::noinline]] void Accumulate(const uint8_t* const* xs, const int8_t* const* ws, int taps,
                                  int groups, const __m512i* init, __m512i* sums) {
  __m512i acc[MR][NV];
#pragma GCC unroll 16
  for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) acc[m][v] = init[v];
  }
  for (int t = 0; t < taps; ++t) {
    const uint8_t* x[MR];
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) x[m] = xs[t * MR + m];
    const int8_t* w = ws[t];
    for (int g = 0; g < groups; ++g) {
      __m512i wv[NV];
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) wv[v] = _mm512_loadu_si512(w + v * 4 * kLanes);
      w += 4 * kNr;
#pragma GCC unroll 16
      for (int m = 0; m < MR; ++m) {
        const __m512i b = Broadcast4(x[m] + 4 * g);
#pragma GCC unroll 4
        for (int v = 0; v < NV; ++v) acc[m][v] = _mm512_dpbusd_epi32(acc[m][v], b, wv[v]);
      }
    }
  }
#pragma GCC unroll 16
  for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) sums[m * NV + v] = acc[m][v];
  }
}

// Accumulate, then the epilogue; pixel m's output is out + m * out_step bytes.
template <int MR, int NV>
inline void Tile(const uint8_t* const* xs, const int8_t* const* ws, int taps, int groups,
                 const __m512i* init, const Epilogue& e, void* out, ptrdiff_t out_step) {
  __m512i sums[MR * NV];
  Accumulate<MR, NV>(xs, ws, taps, groups, init, sums);
#pragma GCC unroll 16
  for (int m = 0; m < MR; ++m) {
    Finish<NV>(sums + m * NV, e, static_cast<char*>(out) + m * out_step);
  }
}

// Tile with r pixels for a run-time r in [1, MR] (a row's leftover pixels).
template <int MR, int NV>
inline void TileUpTo(int r, const uint8_t* const* xs, const int8_t* const* ws, int taps, int groups,
                     const __m512i* init, const Epilogue& e, void* out, ptrdiff_t out_step) {
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
  int zero_point = 0;
  bool phases = false;  // the fused upsample's interior from the phase kernels

  const uint8_t* Source(int y, int x) const {
    if (!up) return a->in.pixel(y, x);
    return a->in.pixel((y + a->crop_top) / 2, (x + a->crop_left) / 2);
  }
  void* Out(int oy, int ox, int blk) const {
    if (a->conv->out_float) return a->out_f32.pixel(oy, ox) + blk * kNr;
    return a->out_u8.pixel(oy, ox) + blk * kNr;
  }
};

// -z * (sum of the tap_sums of taps[0, n)) for NV vectors.
template <int NV>
inline void ZeroPointInit(const int32_t* const* sums, int n, int zero_point, __m512i* init) {
  __m512i s[NV];
#pragma GCC unroll 4
  for (int v = 0; v < NV; ++v) s[v] = _mm512_setzero_si512();
  for (int t = 0; t < n; ++t) {
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v)
      s[v] = _mm512_add_epi32(s[v], _mm512_loadu_si512(sums[t] + v * kLanes));
  }
  const __m512i nz = _mm512_set1_epi32(-zero_point);
#pragma GCC unroll 4
  for (int v = 0; v < NV; ++v) init[v] = _mm512_mullo_epi32(s[v], nz);
}

// The interior pixels of output row oy (whose 3x3 window lies inside C, first tap on C row
// iy0) from the 2x2 kernels of their phases over the low-resolution map (int8_job.h): per
// column phase, every second output pixel, reading consecutive low-resolution pixels.
template <int MR, int NV>
void PhaseRow(const Job& j, int blk, const Epilogue& e3x3, int oy, int iy0) {
  const PackedInt8Conv& p = *j.a->conv;
  const int ay = iy0 + j.a->crop_top;
  const int by = ay >> 1;
  const ptrdiff_t phase_bytes = static_cast<ptrdiff_t>(p.blocks) * 4 * j.tap_bytes;
  const ptrdiff_t phase_sums = static_cast<ptrdiff_t>(p.blocks) * 4 * kNr;
  const uint8_t* xs[4 * MR];
  const int8_t* ws[4];
  const int32_t* ss[4];
  __m512i init[NV];
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
    ZeroPointInit<NV>(ss, 4, j.zero_point, init);
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
void BlockRows(const Job& j, int blk, int row_begin, int row_end) {
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
  __m512i init[NV];
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
      __m512i one_init[NV];
      ZeroPointInit<NV>(ss, n, j.zero_point, one_init);
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
      ZeroPointInit<NV>(ss, n, j.zero_point, init);
      int ox = j.x_lo;
      for (; ox + MR <= j.x_hi; ox += MR) tiles(ox, MR);
      if (ox < j.x_hi) tiles(ox, j.x_hi - ox);
    }
    for (int ox = j.x_hi; ox < j.out_w; ++ox) single(ox);
  }
}

// A convolution with few outputs (p.few_weights; the 64->3 output layer): vectorised over input
// channels instead, 64 per vpdpbusd, one accumulator per output channel, reduced to an exact
// int32 sum per pixel; the scalar epilogue (the same Int8Dequantize / Int8Quantize).
void FewOutRows(const Int8ConvArgs& a, int row_begin, int row_end) {
  const PackedInt8Conv& p = *a.conv;
  const int cin = p.in_channels, cout = p.out_channels;
  const int out_w = p.out_float ? a.out_f32.width : a.out_u8.width;
  const int in_h = a.in.height, in_w = a.in.width;
  const ptrdiff_t row_bytes = static_cast<ptrdiff_t>(cout) * p.few_ci_stride;
  for (int oy = row_begin; oy < row_end; ++oy) {
    const int iy0 = oy * p.stride_h - a.pads.top;
    for (int ox = 0; ox < out_w; ++ox) {
      const int ix0 = ox * p.stride_w - a.pads.left;
      __m512i acc[kInt8FewOutChannels];
      int32_t zsum[kInt8FewOutChannels] = {};
      for (int o = 0; o < cout; ++o) acc[o] = _mm512_setzero_si512();
      for (int ky = 0; ky < p.kernel_h; ++ky) {
        const int iy = iy0 + ky;
        if (iy < 0 || iy >= in_h) continue;
        for (int kx = 0; kx < p.kernel_w; ++kx) {
          const int ix = ix0 + kx;
          if (ix < 0 || ix >= in_w) continue;
          const int t = ky * p.kernel_w + kx;
          const uint8_t* x = a.in.pixel(iy, ix);
          const int8_t* w = p.few_weights + t * row_bytes;
          for (int c = 0; c < cin; c += 64) {
            const int left = cin - c;
            const __mmask64 m = left >= 64 ? ~__mmask64{0} : (__mmask64{1} << left) - 1;
            const __m512i xv = _mm512_maskz_loadu_epi8(m, x + c);
            for (int o = 0; o < cout; ++o) {
              acc[o] =
                  _mm512_dpbusd_epi32(acc[o], xv, _mm512_loadu_si512(w + o * p.few_ci_stride + c));
            }
          }
          for (int o = 0; o < cout; ++o) zsum[o] += p.tap_sums[t * p.nr + o];
        }
      }
      for (int o = 0; o < cout; ++o) {
        alignas(64) int32_t lanes[kLanes];
        _mm512_store_si512(lanes, acc[o]);
        int32_t sum = -p.in_zero_point * zsum[o];
        for (int l = 0; l < kLanes; ++l) sum += lanes[l];
        const float y =
            Int8Dequantize(sum, p.multiplier[o], p.bias[o], p.activation, p.leaky_slope);
        if (p.out_float) {
          a.out_f32.pixel(oy, ox)[o] = y;
        } else {
          a.out_u8.pixel(oy, ox)[o] = Int8Quantize(y, p.out_inv_scale, p.out_zero_point);
        }
      }
    }
  }
}

void Rows(const Int8ConvArgs& a, bool up, int row_begin, int row_end, int blk_begin, int blk_end) {
  const PackedInt8Conv& p = *a.conv;
  if (!up && p.few_weights != nullptr) {
    if (blk_begin == 0 && blk_end > 0) FewOutRows(a, row_begin, row_end);
    return;
  }
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
  j.zero_point = p.in_zero_point;
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
        BlockRows<8, 3>(j, blk, row_begin, row_end);
        break;
      default:
        BlockRows<6, kMaxNv>(j, blk, row_begin, row_end);
        break;
    }
  }
}

void ConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  Rows(a, false, row_begin, row_end, blk_begin, blk_end);
}

void UpConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  Rows(a, true, row_begin, row_end, blk_begin, blk_end);
}

}  // namespace

const IsaInt8Kernels* Int8Kernels() {
  static constexpr IsaInt8Kernels kKernels = {
      kNr, ConvRows, UpConvRows, "conv2d_u8s8__avx512vnni_6x64", "upconv2d_u8s8__avx512vnni_6x64"};
  const CpuFeatures& f = HostCpuFeatures();
  return f.avx512 && f.avx512_vnni ? &kKernels : nullptr;
}

}  // namespace sfrt::avx512
