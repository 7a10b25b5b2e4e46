// AVX-512 VNNI int8 convolution kernels (compiled with -mavx512f -mavx512bw -mavx512vl -mavx512dq
// -mavx512vnni -ffp-contract=off only in this translation unit; runtime/CMakeLists.txt), bit for
// bit equal to ref::Conv2dInt8Rows: the arithmetic is kernels/int8_job.h's. The loops are
// kernels/simd/dot_driver_inl.h's; this file has the vocabulary V, the tiles and the few-output
// kernel.
//
// Blocks of 64 output channels (PackInt8Conv with nr 64). Register tiles: MR output pixels x NV
// vectors of 16 int32 channels: 6x4 (24 accumulators, 4 weight vectors, one broadcast), 8x3, 8x2
// and 8x1. Per tap and group of 4 input channels, each pixel's 4 bytes are broadcast and vpdpbusd
// adds their products with the weight vectors (u8 x s8, exact int32). The zero point:
// sum (x - z) * w = sum x * w - z * sum w, so the accumulators start from -z * the tap_sums.
#include <immintrin.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "kernels/avx512/dot_epilogue_avx512_inl.h"
#include "kernels/int8_job.h"
#include "kernels/simd/dot_driver_inl.h"
#include "src/cpu_features.h"

namespace sfrt::avx512 {
namespace {

// Four input channels of one pixel in every 32-bit lane.
inline __m512i Broadcast4(const uint8_t* p) {
  int32_t v;
  std::memcpy(&v, p, sizeof(v));
  return _mm512_set1_epi32(v);
}

// The int8 vocabulary of kernels/simd/dot_driver_inl.h.
struct V {
  using Conv = PackedInt8Conv;
  using Acc = __m512i;
  static constexpr int kLanes = 16;
  static constexpr int kNr = 64;  // output channels per block
  static Acc Zero() { return _mm512_setzero_si512(); }
  static Acc Load(const int32_t* p) { return _mm512_loadu_si512(p); }
  static Acc Add(Acc a, Acc b) { return _mm512_add_epi32(a, b); }
  static Acc MulScalar(Acc a, int32_t c) { return _mm512_mullo_epi32(a, _mm512_set1_epi32(c)); }
  static int32_t ZeroPointCoefficient(int zero_point) { return -zero_point; }

  // The sums of MR pixels x NV vectors (dot_driver_inl.h). Its own function: inlined into the
  // epilogue's, GCC 12 spills and copies the accumulators inside the loop.
  template <int MR, int NV>
  [[gnu::noinline]] static void Accumulate(const uint8_t* const* xs, const int8_t* const* ws,
                                           int taps, int groups, const Acc* init, Acc* sums) {
    Acc acc[MR][NV];
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
        Acc wv[NV];
#pragma GCC unroll 4
        for (int v = 0; v < NV; ++v) wv[v] = _mm512_loadu_si512(w + v * 4 * kLanes);
        w += 4 * kNr;
#pragma GCC unroll 16
        for (int m = 0; m < MR; ++m) {
          const Acc b = Broadcast4(x[m] + 4 * g);
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

  // Lane-wise Int8Dequantize / Int8Quantize of one pixel's NV vectors into `out` (the pixel's
  // first channel of the block: float or uint8).
  template <int NV>
  static void Finish(const Acc* acc, const simd::DotEpilogue& e, void* out) {
    FinishU8s8<NV>(acc, e, out);
  }
};

// A convolution with few outputs (p.few_weights; the 64->3 output layer): vectorised over input
// channels instead, 64 per vpdpbusd, one accumulator per output channel, reduced to an exact
// int32 sum per pixel, then int8_job.h's epilogue. Where every tap is inside the input, four
// pixels at a time (FewOutQuad); elsewhere one (FewOutPixel), skipping the taps outside.

// One pixel: the taps inside the input, the zero-point correction of those taps, the scalar
// epilogue.
void FewOutPixel(const Int8ConvArgs& a, int oy, int ox) {
  const PackedInt8Conv& p = *a.conv;
  const int cin = p.in_channels, cout = p.out_channels;
  const ptrdiff_t row_bytes = static_cast<ptrdiff_t>(cout) * p.few_ci_stride;
  const int iy0 = oy * p.stride_h - a.pads.top;
  const int ix0 = ox * p.stride_w - a.pads.left;
  __m512i acc[kInt8FewOutChannels];
  int32_t zsum[kInt8FewOutChannels] = {};
  for (int o = 0; o < cout; ++o) acc[o] = _mm512_setzero_si512();
  for (int ky = 0; ky < p.kernel_h; ++ky) {
    const int iy = iy0 + ky;
    if (iy < 0 || iy >= a.in.height) continue;
    for (int kx = 0; kx < p.kernel_w; ++kx) {
      const int ix = ix0 + kx;
      if (ix < 0 || ix >= a.in.width) continue;
      const int t = ky * p.kernel_w + kx;
      const uint8_t* x = a.in.pixel(iy, ix);
      const int8_t* w = p.few_weights + t * row_bytes;
      for (int c = 0; c < cin; c += 64) {
        const int left = cin - c;
        const __mmask64 m = left >= 64 ? ~__mmask64{0} : (__mmask64{1} << left) - 1;
        const __m512i xv = _mm512_maskz_loadu_epi8(m, x + c);
        for (int o = 0; o < cout; ++o) {
          acc[o] = _mm512_dpbusd_epi32(acc[o], xv, _mm512_loadu_si512(w + o * p.few_ci_stride + c));
        }
      }
      for (int o = 0; o < cout; ++o) zsum[o] += p.tap_sums[t * p.nr + o];
    }
  }
  for (int o = 0; o < cout; ++o) {
    alignas(64) int32_t lanes[V::kLanes];
    _mm512_store_si512(lanes, acc[o]);
    int32_t sum = -p.in_zero_point * zsum[o];
    for (int l = 0; l < V::kLanes; ++l) sum += lanes[l];
    const float y = Int8Dequantize(sum, p.multiplier[o], p.bias[o], p.activation, p.leaky_slope);
    if (p.out_float) {
      a.out_f32.pixel(oy, ox)[o] = y;
    } else {
      a.out_u8.pixel(oy, ox)[o] = Int8Quantize(y, p.out_inv_scale, p.out_zero_point);
    }
  }
}

// Lane i of the result: the sum of v[i]'s 16 lanes (exact, wrapping as int32 does). The
// zero-masked forms for GCC 12, as in dot_epilogue_avx512_inl.h.
inline __m512i SumEachVector(const __m512i* v) {
  constexpr __mmask8 kAll8 = 0xFF;
  __m512i pairs[8];  // per 128-bit lane: v[2i] and v[2i+1], two partial sums each
#pragma GCC unroll 8
  for (int i = 0; i < 8; ++i) {
    pairs[i] = _mm512_add_epi32(_mm512_maskz_unpacklo_epi32(kAll, v[2 * i], v[2 * i + 1]),
                                _mm512_maskz_unpackhi_epi32(kAll, v[2 * i], v[2 * i + 1]));
  }
  __m512i quads[4];  // per 128-bit lane: v[4i] .. v[4i + 3], one partial sum each
#pragma GCC unroll 4
  for (int i = 0; i < 4; ++i) {
    quads[i] = _mm512_add_epi32(_mm512_maskz_unpacklo_epi64(kAll8, pairs[2 * i], pairs[2 * i + 1]),
                                _mm512_maskz_unpackhi_epi64(kAll8, pairs[2 * i], pairs[2 * i + 1]));
  }
  // Then across the 128-bit lanes: even lanes plus odd lanes, twice.
  constexpr int kEven = 0x88, kOdd = 0xDD;
  const __m512i low = _mm512_add_epi32(_mm512_maskz_shuffle_i32x4(kAll, quads[0], quads[1], kEven),
                                       _mm512_maskz_shuffle_i32x4(kAll, quads[0], quads[1], kOdd));
  const __m512i high = _mm512_add_epi32(_mm512_maskz_shuffle_i32x4(kAll, quads[2], quads[3], kEven),
                                        _mm512_maskz_shuffle_i32x4(kAll, quads[2], quads[3], kOdd));
  return _mm512_add_epi32(_mm512_maskz_shuffle_i32x4(kAll, low, high, kEven),
                          _mm512_maskz_shuffle_i32x4(kAll, low, high, kOdd));
}

// The epilogue of four pixels: lane 4 * j + o is pixel j's output channel o.
struct FewOutEpilogue {
  alignas(64) float multiplier[16] = {};
  alignas(64) float bias[16] = {};
  alignas(64) int32_t zero_fix[16] = {};  // -z * the sum of every tap's tap_sums
  simd::DotEpilogue e{};
};

void PrepareFewOutEpilogue(const PackedInt8Conv& p, FewOutEpilogue& f) {
  const int taps = p.kernel_h * p.kernel_w;
  for (int i = 0; i < 16; ++i) {
    const int o = i % 4;
    if (o >= p.out_channels) continue;
    f.multiplier[i] = p.multiplier[o];
    f.bias[i] = p.bias[o];
    int32_t zsum = 0;
    for (int t = 0; t < taps; ++t) zsum += p.tap_sums[t * p.nr + o];
    f.zero_fix[i] = -p.in_zero_point * zsum;
  }
  f.e = {f.multiplier, f.bias,          p.activation,     p.leaky_slope,
         p.out_float,  p.out_inv_scale, p.out_zero_point, 16};
}

constexpr int kFewOutPrefetchBytes = 1024;

// Pixels ox .. ox + 3 of row oy, every tap inside the input; CO output channels.
template <int CO>
void FewOutQuad(const Int8ConvArgs& a, int oy, int ox, const FewOutEpilogue& f) {
  const PackedInt8Conv& p = *a.conv;
  const int cin = p.in_channels;
  const ptrdiff_t row_bytes = static_cast<ptrdiff_t>(CO) * p.few_ci_stride;
  const int iy0 = oy * p.stride_h - a.pads.top;
  const int ix0 = ox * p.stride_w - a.pads.left;
  __m512i acc[16];  // [pixel * 4 + output]
#pragma GCC unroll 16
  for (int i = 0; i < 16; ++i) acc[i] = _mm512_setzero_si512();
  for (int ky = 0; ky < p.kernel_h; ++ky) {
    for (int kx = 0; kx < p.kernel_w; ++kx) {
      const uint8_t* x[4];
#pragma GCC unroll 4
      for (int j = 0; j < 4; ++j) x[j] = a.in.pixel(iy0 + ky, ix0 + kx + j * p.stride_w);
      const int8_t* w = p.few_weights + (ky * p.kernel_w + kx) * row_bytes;
      if (kx == 0) {
        const char* ahead = reinterpret_cast<const char*>(x[0]) + kFewOutPrefetchBytes;
        for (int b = 0; b < 4 * p.stride_w * cin; b += 64) _mm_prefetch(ahead + b, _MM_HINT_T0);
      }
      for (int c = 0; c < cin; c += 64) {
        const int left = cin - c;
        const __mmask64 m = left >= 64 ? ~__mmask64{0} : (__mmask64{1} << left) - 1;
        __m512i wv[CO];
#pragma GCC unroll 4
        for (int o = 0; o < CO; ++o) wv[o] = _mm512_loadu_si512(w + o * p.few_ci_stride + c);
#pragma GCC unroll 4
        for (int j = 0; j < 4; ++j) {
          const __m512i xv = _mm512_maskz_loadu_epi8(m, x[j] + c);
#pragma GCC unroll 4
          for (int o = 0; o < CO; ++o) {
            acc[j * 4 + o] = _mm512_dpbusd_epi32(acc[j * 4 + o], xv, wv[o]);
          }
        }
      }
    }
  }
  const __m512i sums = _mm512_add_epi32(SumEachVector(acc), _mm512_load_si512(f.zero_fix));
  const __m512 y = DequantizeLanes(sums, f.e, 0);
  constexpr __mmask16 kOutputs = (1u << CO) - 1u;
  if (p.out_float) {
#pragma GCC unroll 4
    for (int j = 0; j < 4; ++j) {
      _mm512_mask_storeu_ps(a.out_f32.pixel(oy, ox + j), kOutputs,
                            _mm512_maskz_compress_ps(static_cast<__mmask16>(0xFu << (4 * j)), y));
    }
  } else {
    const __m512i q = QuantizeLanes(y, f.e);
#pragma GCC unroll 4
    for (int j = 0; j < 4; ++j) {
      _mm512_mask_cvtepi32_storeu_epi8(
          a.out_u8.pixel(oy, ox + j), kOutputs,
          _mm512_maskz_compress_epi32(static_cast<__mmask16>(0xFu << (4 * j)), q));
    }
  }
}

template <int CO>
void FewOutRowsOf(const Int8ConvArgs& a, int row_begin, int row_end) {
  const PackedInt8Conv& p = *a.conv;
  const int out_w = p.out_float ? a.out_f32.width : a.out_u8.width;
  const int x_begin = simd::MaxOf(0, a.col_begin), x_end = simd::MinOf(out_w, a.col_end);
  // Columns whose window is inside the input: [inside_lo, inside_hi).
  const int inside_lo = (a.pads.left + p.stride_w - 1) / p.stride_w;
  const int last = a.in.width - p.kernel_w + a.pads.left;  // the last window's first column
  const int inside_hi = last < 0 ? inside_lo : simd::MaxOf(inside_lo, last / p.stride_w + 1);
  const int quad_end = simd::MinOf(inside_hi, x_end);
  FewOutEpilogue f;
  PrepareFewOutEpilogue(p, f);
  for (int oy = row_begin; oy < row_end; ++oy) {
    const int iy0 = oy * p.stride_h - a.pads.top;
    const bool rows_inside = iy0 >= 0 && iy0 + p.kernel_h <= a.in.height;
    int ox = x_begin;
    while (ox < x_end) {
      if (rows_inside && ox >= inside_lo && ox + 4 <= quad_end) {
        FewOutQuad<CO>(a, oy, ox, f);
        ox += 4;
      } else {
        FewOutPixel(a, oy, ox);
        ++ox;
      }
    }
  }
}

void FewOutRows(const Int8ConvArgs& a, int row_begin, int row_end) {
  static_assert(kInt8FewOutChannels == 4, "FewOutQuad's lanes hold 4 pixels x 4 channels");
  switch (a.conv->out_channels) {
    case 1:
      FewOutRowsOf<1>(a, row_begin, row_end);
      break;
    case 2:
      FewOutRowsOf<2>(a, row_begin, row_end);
      break;
    case 3:
      FewOutRowsOf<3>(a, row_begin, row_end);
      break;
    default:
      FewOutRowsOf<4>(a, row_begin, row_end);
      break;
  }
}

// The tiles' pixels for 1, 2, 3 and 4 valid vectors: 8x1, 8x2, 8x3, 6x4.
void ConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  if (a.conv->few_weights != nullptr) {
    if (blk_begin == 0 && blk_end > 0) FewOutRows(a, row_begin, row_end);
    return;
  }
  simd::DotConvRows<V, 8, 8, 8, 6>(a, row_begin, row_end, blk_begin, blk_end);
}

}  // namespace

const IsaInt8Kernels* Int8Kernels() {
  static constexpr IsaInt8Kernels kKernels = {V::kNr,
                                              ConvRows,
                                              simd::DotUpConvRows<V, 8, 8, 8, 6>,
                                              "conv2d_u8s8__avx512vnni_6x64",
                                              "upconv2d_u8s8__avx512vnni_6x64",
                                              "conv2d_fewout_u8s8__avx512vnni_4x4"};
  const CpuFeatures& f = HostCpuFeatures();
  return f.avx512 && f.avx512_vnni ? &kKernels : nullptr;
}

}  // namespace sfrt::avx512
