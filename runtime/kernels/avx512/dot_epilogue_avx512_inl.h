// The AVX-512 epilogues of the dot-product kernels, shared by the translation units that finish
// int8 or bf16 sums in zmm registers: the VNNI and AVX512_BF16 kernels (one pixel's vectors of
// their register tiles) and the AMX kernels (one pixel's row of their C tiles). Each includer
// compiles them with its own flags into its own anonymous namespace, so no two translation
// units built with different flags share their code. The int8 epilogue is int8_job.h's
// Int8Dequantize then Int8Quantize lane by lane (bit for bit: -ffp-contract=off, no FMA); the
// bf16 one is bias, activation and the rounding to bf16 (vcvtneps2bf16), and exists where the
// includer is compiled with AVX512_BF16.
#pragma once

#include <immintrin.h>

#include <cstdint>

#include "kernels/simd/dot_driver_inl.h"

namespace sfrt::avx512 {
namespace {

// The unmasked forms of these intrinsics start from _mm512_undefined_*, which GCC 12 reports
// as -Wmaybe-uninitialized once inlined: the zero-masked forms with every lane set instead.
constexpr __mmask16 kAll = 0xFFFF;
constexpr int kEpilogueLanes = 16;
inline __m512 ToFloat(__m512i v) { return _mm512_maskz_cvtepi32_ps(kAll, v); }
inline __m512i ToIntNearest(__m512 v) { return _mm512_maskz_cvtps_epi32(kAll, v); }
inline __m512 Max(__m512 a, __m512 b) { return _mm512_maskz_max_ps(kAll, a, b); }
inline __m512 Min(__m512 a, __m512 b) { return _mm512_maskz_min_ps(kAll, a, b); }
inline __m512i Max(__m512i a, __m512i b) { return _mm512_maskz_max_epi32(kAll, a, b); }
inline __m512i Min(__m512i a, __m512i b) { return _mm512_maskz_min_epi32(kAll, a, b); }

// Vector v's lanes among the block's e.valid channels (none past them).
inline __mmask16 ValidLanes(const simd::DotEpilogue& e, int v) {
  const int left = e.valid - v * kEpilogueLanes;
  if (left <= 0) return 0;
  return left >= kEpilogueLanes ? kAll : static_cast<__mmask16>((1u << left) - 1u);
}

// Bias and activation of 16 float32 lanes.
inline __m512 BiasActivation(__m512 y, const simd::DotEpilogue& e, int v) {
  y = _mm512_add_ps(y, _mm512_loadu_ps(e.bias + v * kEpilogueLanes));
  const __m512 zero = _mm512_setzero_ps();
  if (e.act == Activation::kLeakyRelu) {
    const __mmask16 negative = _mm512_cmp_ps_mask(y, zero, _CMP_LT_OQ);
    y = _mm512_mask_mul_ps(y, negative, y, _mm512_set1_ps(e.slope));
  } else if (e.act == Activation::kRelu) {
    const __mmask16 positive = _mm512_cmp_ps_mask(y, zero, _CMP_GT_OQ);
    y = _mm512_maskz_mov_ps(positive, y);
  }
  return y;
}

// Int8Dequantize of 16 int32 sums with lanes [v * 16, v * 16 + 16) of e.multiplier and e.bias.
inline __m512 DequantizeLanes(__m512i acc, const simd::DotEpilogue& e, int v) {
  const __m512 y = _mm512_mul_ps(ToFloat(acc), _mm512_loadu_ps(e.multiplier + v * kEpilogueLanes));
  return BiasActivation(y, e, v);
}

// Int8Quantize of 16 float32 lanes (as int32 0..255).
inline __m512i QuantizeLanes(__m512 y, const simd::DotEpilogue& e) {
  __m512 t = _mm512_mul_ps(y, _mm512_set1_ps(e.inv_scale));
  t = Max(t, _mm512_set1_ps(-512.0f));
  t = Min(t, _mm512_set1_ps(512.0f));
  __m512i q = ToIntNearest(t);  // cvtps2dq: to nearest even under the default MXCSR
  q = _mm512_add_epi32(q, _mm512_set1_epi32(e.zero_point));
  q = Max(q, _mm512_setzero_si512());
  return Min(q, _mm512_set1_epi32(255));
}

// Int8Dequantize / Int8Quantize of one pixel's NV vectors of int32 sums into `out` (the pixel's
// first channel of the block: float or uint8).
template <int NV>
inline void FinishU8s8(const __m512i* acc, const simd::DotEpilogue& e, void* out) {
#pragma GCC unroll 4
  for (int v = 0; v < NV; ++v) {
    const __mmask16 mask = ValidLanes(e, v);
    const __m512 y = DequantizeLanes(acc[v], e, v);
    if (e.out_float) {
      _mm512_mask_storeu_ps(static_cast<float*>(out) + v * kEpilogueLanes, mask, y);
    } else {
      _mm512_mask_cvtepi32_storeu_epi8(static_cast<uint8_t*>(out) + v * kEpilogueLanes, mask,
                                       QuantizeLanes(y, e));
    }
  }
}

#ifdef __AVX512BF16__
// Bias, activation and (bf16 output) the rounding to nearest even of one pixel's NV vectors of
// float32 sums into `out` (the pixel's first channel of the block: float or bf16).
template <int NV>
inline void FinishBf16(const __m512* acc, const simd::DotEpilogue& e, void* out) {
#pragma GCC unroll 4
  for (int v = 0; v < NV; ++v) {
    const __mmask16 mask = ValidLanes(e, v);
    const __m512 y = BiasActivation(acc[v], e, v);
    if (e.out_float) {
      _mm512_mask_storeu_ps(static_cast<float*>(out) + v * kEpilogueLanes, mask, y);
    } else {
      const __m256i h = reinterpret_cast<__m256i>(_mm512_cvtneps_pbh(y));
      _mm256_mask_storeu_epi16(static_cast<uint16_t*>(out) + v * kEpilogueLanes, mask, h);
    }
  }
}
#endif

}  // namespace
}  // namespace sfrt::avx512
