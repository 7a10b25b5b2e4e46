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
// int32 sum per pixel; the scalar epilogue (the same Int8Dequantize / Int8Quantize). Columns
// [col_begin, col_end) of each row.
void FewOutRows(const Int8ConvArgs& a, int row_begin, int row_end) {
  const PackedInt8Conv& p = *a.conv;
  const int cin = p.in_channels, cout = p.out_channels;
  const int out_w = p.out_float ? a.out_f32.width : a.out_u8.width;
  const int x_begin = simd::MaxOf(0, a.col_begin), x_end = simd::MinOf(out_w, a.col_end);
  const int in_h = a.in.height, in_w = a.in.width;
  const ptrdiff_t row_bytes = static_cast<ptrdiff_t>(cout) * p.few_ci_stride;
  for (int oy = row_begin; oy < row_end; ++oy) {
    const int iy0 = oy * p.stride_h - a.pads.top;
    for (int ox = x_begin; ox < x_end; ++ox) {
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
        alignas(64) int32_t lanes[V::kLanes];
        _mm512_store_si512(lanes, acc[o]);
        int32_t sum = -p.in_zero_point * zsum[o];
        for (int l = 0; l < V::kLanes; ++l) sum += lanes[l];
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
  static constexpr IsaInt8Kernels kKernels = {V::kNr, ConvRows, simd::DotUpConvRows<V, 8, 8, 8, 6>,
                                              "conv2d_u8s8__avx512vnni_6x64",
                                              "upconv2d_u8s8__avx512vnni_6x64"};
  const CpuFeatures& f = HostCpuFeatures();
  return f.avx512 && f.avx512_vnni ? &kKernels : nullptr;
}

}  // namespace sfrt::avx512
