// AVX-512 quantisation of float32 rows to uint8 (built with the VNNI kernels' flags,
// -ffp-contract=off), the same bytes as Int8Quantize: one multiply, a clamp to [-512, 512],
// conversion rounding half to even (cvtps2dq under the default MXCSR), the zero point added and
// a clamp to 0..255.
#include <immintrin.h>

#include <cstdint>

#include "kernels/int8_job.h"

namespace sfrt::avx512 {
namespace {

// Zero-masked forms with every lane set: GCC 12 reports the unmasked forms' undefined start
// value as -Wmaybe-uninitialized once inlined.
constexpr __mmask16 kAll = 0xFFFF;

inline __m128i Quantize16(__m512 x, __m512 inv, __m512i zp, __mmask16 lanes) {
  __m512 t = _mm512_maskz_mul_ps(lanes, x, inv);
  t = _mm512_maskz_max_ps(kAll, t, _mm512_set1_ps(-512.0f));
  t = _mm512_maskz_min_ps(kAll, t, _mm512_set1_ps(512.0f));
  __m512i q = _mm512_add_epi32(_mm512_maskz_cvtps_epi32(kAll, t), zp);
  q = _mm512_maskz_max_epi32(kAll, q, _mm512_setzero_si512());
  q = _mm512_maskz_min_epi32(kAll, q, _mm512_set1_epi32(255));
  return _mm512_maskz_cvtepi32_epi8(kAll, q);
}

}  // namespace

void QuantizeRows(const ConstTensorView& in, float inv_scale, int zero_point, const ByteView& out,
                  int row_begin, int row_end) {
  const __m512 inv = _mm512_set1_ps(inv_scale);
  const __m512i zp = _mm512_set1_epi32(zero_point);
  const ptrdiff_t n = static_cast<ptrdiff_t>(in.width) * in.channels;  // a row is dense
  for (int y = row_begin; y < row_end; ++y) {
    const float* src = in.pixel(y, 0);
    uint8_t* dst = out.pixel(y, 0);
    ptrdiff_t i = 0;
    for (; i + 16 <= n; i += 16) {
      _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + i),
                       Quantize16(_mm512_loadu_ps(src + i), inv, zp, kAll));
    }
    if (i < n) {
      const __mmask16 m = static_cast<__mmask16>((1u << (n - i)) - 1u);
      _mm_mask_storeu_epi8(dst + i, m, Quantize16(_mm512_maskz_loadu_ps(m, src + i), inv, zp, m));
    }
  }
}

}  // namespace sfrt::avx512
