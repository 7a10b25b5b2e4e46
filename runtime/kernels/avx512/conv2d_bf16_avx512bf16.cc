// AVX512_BF16 convolution kernels (compiled with -mavx512f -mavx512bw -mavx512vl -mavx512dq
// -mavx512bf16 only in this translation unit; runtime/CMakeLists.txt): the arithmetic is
// kernels/bf16_job.h's, the loops kernels/simd/dot_driver_inl.h's; this file has the vocabulary.
//
// Blocks of 64 output channels (PackBf16Conv with nr 64). Register tiles: MR output pixels x NV
// vectors of 16 float32 channels: 6x4 (24 accumulators, 4 weight vectors, one broadcast), 8x3,
// 8x2 and 8x1. Per tap and pair of input channels, each pixel's pair is broadcast and vdpbf16ps
// adds both products to every lane (the products are exact; the instruction flushes denormal
// inputs and results to zero, well inside the tolerance bf16 has anyway).
#include <immintrin.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "kernels/avx512/dot_epilogue_avx512_inl.h"
#include "kernels/avx512/few_out_avx512_inl.h"
#include "kernels/bf16_job.h"
#include "kernels/simd/dot_driver_inl.h"
#include "src/cpu_features.h"

namespace sfrt::avx512 {
namespace {

// Two bf16 input channels of one pixel in every 32-bit lane.
inline __m512bh BroadcastPair(const uint16_t* p) {
  int32_t v;
  std::memcpy(&v, p, sizeof(v));
  return reinterpret_cast<__m512bh>(_mm512_set1_epi32(v));
}

// The bf16 vocabulary of kernels/simd/dot_driver_inl.h.
struct V {
  using Conv = PackedBf16Conv;
  using Acc = __m512;
  static constexpr int kLanes = 16;
  static constexpr int kNr = 64;  // output channels per block
  static Acc Zero() { return _mm512_setzero_ps(); }

  // The sums of MR pixels x NV vectors (dot_driver_inl.h), in a function of its own so that the
  // accumulators stay in registers (as the VNNI kernel's).
  template <int MR, int NV>
  [[gnu::noinline]] static void Accumulate(const uint16_t* const* xs, const uint16_t* const* ws,
                                           int taps, int groups, const Acc* init, Acc* sums) {
    Acc acc[MR][NV];
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) acc[m][v] = init[v];
    }
    for (int t = 0; t < taps; ++t) {
      const uint16_t* x[MR];
#pragma GCC unroll 16
      for (int m = 0; m < MR; ++m) x[m] = xs[t * MR + m];
      const uint16_t* w = ws[t];
      for (int g = 0; g < groups; ++g) {
        __m512bh wv[NV];
#pragma GCC unroll 4
        for (int v = 0; v < NV; ++v) {
          wv[v] = reinterpret_cast<__m512bh>(_mm512_loadu_si512(w + v * 2 * kLanes));
        }
        w += 2 * kNr;
#pragma GCC unroll 16
        for (int m = 0; m < MR; ++m) {
          const __m512bh b = BroadcastPair(x[m] + 2 * g);
#pragma GCC unroll 4
          for (int v = 0; v < NV; ++v) acc[m][v] = _mm512_dpbf16_ps(acc[m][v], b, wv[v]);
        }
      }
    }
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) sums[m * NV + v] = acc[m][v];
    }
  }

  // Bias, activation and (bf16 output) the rounding to nearest even of one pixel's NV vectors
  // into `out` (the pixel's first channel of the block: float or bf16).
  template <int NV>
  static void Finish(const Acc* acc, const simd::DotEpilogue& e, void* out) {
    FinishBf16<NV>(acc, e, out);
  }
};

// FloatToBf16 of 16 values in integer arithmetic (the same bits: vcvtneps2bf16 would flush
// denormals to zero): bits + 0x7fff + bit 16, upper half; a NaN keeps its upper half, quieted.
inline __m256i ToBf16x16(__m512 v) {
  const __m512i bits = _mm512_castps_si512(v);
  // The zero-masked forms with every lane set: the unmasked ones start from _mm512_undefined_*,
  // which GCC 12 reports as -Wmaybe-uninitialized once inlined.
  const __m512i lsb =
      _mm512_and_si512(_mm512_maskz_srli_epi32(kAll, bits, 16), _mm512_set1_epi32(1));
  __m512i rounded = _mm512_add_epi32(bits, _mm512_add_epi32(lsb, _mm512_set1_epi32(0x7fff)));
  const __mmask16 nan = _mm512_cmp_ps_mask(v, v, _CMP_UNORD_Q);
  rounded = _mm512_mask_or_epi32(rounded, nan, bits, _mm512_set1_epi32(0x400000));
  return _mm512_maskz_cvtepi32_epi16(kAll, _mm512_maskz_srli_epi32(kAll, rounded, 16));
}

// The bf16 precision of kernels/avx512/few_out_avx512_inl.h: pairs of bf16 products by
// vdpbf16ps into float32 sums, then bias, activation and (bf16 output) the rounding.
struct FewOutBf16 {
  using Conv = PackedBf16Conv;
  using Args = Bf16ConvArgs;
  using Elem = uint16_t;
  using Weight = uint16_t;
  using Acc = __m512;
  using In = __m512bh;
  static constexpr int kPerLoad = 32;
  static int OutWidth(const Args& a) {
    return a.conv->out_float ? a.out_f32.width : a.out_bf16.width;
  }
  static Acc Zero() { return _mm512_setzero_ps(); }
  static In LoadX(const uint16_t* x, int left) {
    const __mmask32 m = left >= 32 ? ~__mmask32{0} : (__mmask32{1} << left) - 1;
    return reinterpret_cast<__m512bh>(_mm512_maskz_loadu_epi16(m, x));
  }
  static In LoadW(const uint16_t* w) { return reinterpret_cast<__m512bh>(_mm512_loadu_si512(w)); }
  static Acc Dot(Acc acc, In x, In w) { return _mm512_dpbf16_ps(acc, x, w); }
  template <int K>
  static Acc SumEachVector(const Acc* v) {
    __m512i bits[K];
#pragma GCC unroll 16
    for (int i = 0; i < K; ++i) bits[i] = _mm512_castps_si512(v[i]);
    return _mm512_castsi512_ps(SumEachVectorBits<K>(bits, [](__m512i x, __m512i y) {
      return _mm512_castps_si512(_mm512_add_ps(_mm512_castsi512_ps(x), _mm512_castsi512_ps(y)));
    }));
  }

  // One pixel: the scalar epilogue (Bf16Epilogue, FloatToBf16).
  static void FinishPixel(const Args& a, int oy, int ox, const Acc* acc, const InsideTaps&) {
    const Conv& p = *a.conv;
    for (int o = 0; o < p.out_channels; ++o) {
      alignas(64) float lanes[V::kLanes];
      _mm512_store_ps(lanes, acc[o]);
      float sum = 0.0f;
      for (int l = 0; l < V::kLanes; ++l) sum += lanes[l];
      const float y = Bf16Epilogue(sum, p.bias[o], p.activation, p.leaky_slope);
      if (p.out_float) {
        a.out_f32.pixel(oy, ox)[o] = y;
      } else {
        a.out_bf16.pixel(oy, ox)[o] = FloatToBf16(y);
      }
    }
  }

  // A tile's values: value i is channel i % CO.
  struct Values {
    alignas(64) float bias[kFewOutValues] = {};
    simd::DotEpilogue e{};
  };
  static void Prepare(const Conv& p, Values& q) {
    for (int i = 0; i < kFewOutValues; ++i) q.bias[i] = p.bias[i % p.out_channels];
    q.e = {nullptr, q.bias, p.activation, p.leaky_slope, p.out_float, 0.0f, 0, kFewOutValues};
  }
  template <int CO>
  static void FinishValues(const Args& a, int oy, int ox, int chunk, int count, Acc sums,
                           const Values& q) {
    const __m512 y = BiasActivation(sums, q.e, chunk);
    if (a.conv->out_float) {
      StoreValues<CO>(a.out_f32.pixel(oy, ox), a.out_f32.channels, chunk, count,
                      [y](float* d, __mmask16 m) { _mm512_mask_storeu_ps(d, m, y); });
      return;
    }
    const __m256i h = ToBf16x16(y);
    StoreValues<CO>(a.out_bf16.pixel(oy, ox), a.out_bf16.stride(), chunk, count,
                    [h](uint16_t* d, __mmask16 m) { _mm256_mask_storeu_epi16(d, m, h); });
  }
};
static_assert(kBf16FewOutChannels <= kFewOutMaxChannels);

void ConvRows(const Bf16ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  if (a.conv->few_weights != nullptr) {
    if (blk_begin == 0 && blk_end > 0) FewOutRows<FewOutBf16>(a, row_begin, row_end);
    return;
  }
  simd::DotConvRows<V, 8, 8, 8, 6>(a, row_begin, row_end, blk_begin, blk_end);
}

}  // namespace

void ToBf16Rows(const ConstTensorView& in, const Bf16View& out, int row_begin, int row_end) {
  const ptrdiff_t n = static_cast<ptrdiff_t>(in.width) * in.channels;  // a row is dense
  for (int y = row_begin; y < row_end; ++y) {
    const float* src = in.pixel(y, 0);
    uint16_t* dst = out.pixel(y, 0);
    ptrdiff_t i = 0;
    for (; i + 16 <= n; i += 16) {
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(dst + i), ToBf16x16(_mm512_loadu_ps(src + i)));
    }
    if (i < n) {
      const __mmask16 m = static_cast<__mmask16>((1u << (n - i)) - 1u);
      _mm256_mask_storeu_epi16(dst + i, m, ToBf16x16(_mm512_maskz_loadu_ps(m, src + i)));
    }
  }
}

const IsaBf16Kernels* Bf16Kernels() {
  static constexpr IsaBf16Kernels kKernels = {V::kNr,
                                              ConvRows,
                                              simd::DotUpConvRows<V, 8, 8, 8, 6>,
                                              "conv2d_bf16__avx512bf16_6x64",
                                              "upconv2d_bf16__avx512bf16_6x64",
                                              "conv2d_fewout_bf16__avx512bf16_8x3"};
  const CpuFeatures& f = HostCpuFeatures();
  return f.avx512 && f.avx512_bf16 ? &kKernels : nullptr;
}

}  // namespace sfrt::avx512
