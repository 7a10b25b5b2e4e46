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

// The activation of 16 float32 lanes.
inline __m512 Activate(__m512 y, const simd::DotEpilogue& e) {
  const __m512 zero = _mm512_setzero_ps();
  if (e.act == Activation::kLeakyRelu) {
    const __mmask16 negative = _mm512_cmp_ps_mask(y, zero, _CMP_LT_OQ);
    y = _mm512_mask_mul_ps(y, negative, y, _mm512_set1_ps(e.slope));
  } else if (e.act == Activation::kRelu) {
    y = Max(y, zero);  // y > 0 ? y : +0 (vmaxps returns its second operand unless y is greater)
  }
  return y;
}

// Bias and activation of 16 float32 lanes.
inline __m512 BiasActivation(__m512 y, const simd::DotEpilogue& e, int v) {
  return Activate(_mm512_add_ps(y, _mm512_loadu_ps(e.bias + v * kEpilogueLanes)), e);
}

// Int8Dequantize before its activation: 16 int32 sums times lanes [v * 16, v * 16 + 16) of
// e.multiplier, plus those of e.bias.
inline __m512 ScaleAndBias(__m512i acc, const simd::DotEpilogue& e, int v) {
  const __m512 y = _mm512_mul_ps(ToFloat(acc), _mm512_loadu_ps(e.multiplier + v * kEpilogueLanes));
  return _mm512_add_ps(y, _mm512_loadu_ps(e.bias + v * kEpilogueLanes));
}

// Int8Dequantize of 16 int32 sums with lanes [v * 16, v * 16 + 16) of e.multiplier and e.bias.
inline __m512 DequantizeLanes(__m512i acc, const simd::DotEpilogue& e, int v) {
  return Activate(ScaleAndBias(acc, e, v), e);
}

// Int8Quantize of 16 float32 lanes before its clamp to 0..255 (int32 in -512 + zero_point ..
// 512 + zero_point): for callers whose store saturates (PackBytes).
inline __m512i QuantizeLanesUnclamped(__m512 y, const simd::DotEpilogue& e) {
  __m512 t = _mm512_mul_ps(y, _mm512_set1_ps(e.inv_scale));
  t = Max(t, _mm512_set1_ps(-512.0f));
  t = Min(t, _mm512_set1_ps(512.0f));
  const __m512i q = ToIntNearest(t);  // cvtps2dq: to nearest even under the default MXCSR
  return _mm512_add_epi32(q, _mm512_set1_epi32(e.zero_point));
}

// Int8Quantize of 16 float32 lanes (as int32 0..255).
inline __m512i QuantizeLanes(__m512 y, const simd::DotEpilogue& e) {
  return Min(Max(QuantizeLanesUnclamped(y, e), _mm512_setzero_si512()), _mm512_set1_epi32(255));
}

// Whether ReluQuantizeLanes gives Int8Dequantize's then QuantizeLanesUnclamped's values.
inline bool ReluFolds(const simd::DotEpilogue& e) {
  return e.act == Activation::kRelu && e.inv_scale > 0.0f;
}

// Int8Dequantize with ReLU then QuantizeLanesUnclamped, for ReluFolds(e): with inv_scale > 0,
// y * inv_scale has y's sign, so ReLU's max(y, 0) and the clamp's max(t, -512) are one
// max(y * inv_scale, 0), the same values (y <= 0, -0 and NaN give +0 as ReLU's +0 does).
inline __m512i ReluQuantizeLanes(__m512i acc, const simd::DotEpilogue& e, int v) {
  const __m512 y = ScaleAndBias(acc, e, v);
  __m512 t = Max(_mm512_mul_ps(y, _mm512_set1_ps(e.inv_scale)), _mm512_setzero_ps());
  t = Min(t, _mm512_set1_ps(512.0f));
  return _mm512_add_epi32(ToIntNearest(t), _mm512_set1_epi32(e.zero_point));
}

// Bytes v * 16 + i = lane i of q[v], clamped to 0..255, for NV <= 4 vectors of int32 in
// -32768..32767 (the bytes from NV * 16 on zero): two saturating packs (int32 to int16, exact
// here; int16 to uint8, the clamp) put q[v]'s lanes 4L..4L+3 at dword 4L + v, and a dword
// permutation puts them at 4v + L.
template <int NV>
inline __m512i PackBytes(const __m512i* q) {
  static_assert(NV >= 1 && NV <= 4);
  const __m512i zero = _mm512_setzero_si512();
  const __m512i q1 = NV > 1 ? q[1] : zero, q2 = NV > 2 ? q[2] : zero, q3 = NV > 3 ? q[3] : zero;
  constexpr __mmask32 kAll32 = ~__mmask32{0};
  constexpr __mmask64 kAll64 = ~__mmask64{0};
  const __m512i bytes = _mm512_maskz_packus_epi16(
      kAll64, _mm512_maskz_packs_epi32(kAll32, q[0], q1), _mm512_maskz_packs_epi32(kAll32, q2, q3));
  const __m512i order = _mm512_setr_epi32(0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15);
  return _mm512_maskz_permutexvar_epi32(kAll, order, bytes);
}

// Int8Dequantize / Int8Quantize of one pixel's NV vectors of int32 sums into `out` (the pixel's
// first channel of the block: float or uint8; uint8 in one store of its e.valid bytes).
template <int NV>
inline void FinishU8s8(const __m512i* acc, const simd::DotEpilogue& e, void* out) {
  if (e.out_float) {
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) {
      _mm512_mask_storeu_ps(static_cast<float*>(out) + v * kEpilogueLanes, ValidLanes(e, v),
                            DequantizeLanes(acc[v], e, v));
    }
    return;
  }
  __m512i q[NV];  // PackBytes clamps them to 0..255
  if (ReluFolds(e)) {
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) q[v] = ReluQuantizeLanes(acc[v], e, v);
  } else {
#pragma GCC unroll 4
    for (int v = 0; v < NV; ++v) q[v] = QuantizeLanesUnclamped(DequantizeLanes(acc[v], e, v), e);
  }
  const __m512i packed = PackBytes<NV>(q);
  if (NV == 4 && e.valid >= 64) {
    _mm512_storeu_si512(out, packed);
    return;
  }
  const int bytes = e.valid < NV * kEpilogueLanes ? e.valid : NV * kEpilogueLanes;
  _mm512_mask_storeu_epi8(out, (__mmask64{1} << bytes) - 1, packed);
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
