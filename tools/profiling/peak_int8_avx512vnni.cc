// AVX-512 VNNI peak loops: 24 independent zmm chains (of 32 zmm registers) of vpdpbusd, which
// multiplies 64 u8 x s8 pairs and adds them, 4 to a lane, into 16 int32 lanes, or of vpdpwssd,
// 32 s16 x s16 pairs, 2 to a lane (the products exact integer Winograd transforms would need).
#include <immintrin.h>

#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling::internal {
namespace {

constexpr int kChains = 24;

// Dot(acc, a, b): one dot-product instruction.
template <typename Dot>
float Run(int64_t iterations, __m512i a, __m512i b, Dot dot) {
  __m512i acc[kChains];
#pragma GCC unroll 24
  for (int j = 0; j < kChains; ++j) acc[j] = _mm512_set1_epi32(j);
  for (int64_t i = 0; i < iterations; ++i) {
#pragma GCC unroll 24
    for (int j = 0; j < kChains; ++j) {
      acc[j] = dot(acc[j], a, b);  // wraps, never saturates: no overflow check
      __asm__("" : "+v"(acc[j]));  // in a register, not merged or reordered (no instruction)
    }
  }
  __m512i sum = acc[0];
#pragma GCC unroll 24
  for (int j = 1; j < kChains; ++j) sum = _mm512_xor_si512(sum, acc[j]);
  alignas(64) int32_t lanes[16];
  _mm512_store_si512(lanes, sum);
  int32_t total = 0;
  for (int32_t v : lanes) total ^= v;
  return static_cast<float>(total);
}

float RunU8s8(int64_t iterations) {
  return Run(iterations, _mm512_set1_epi8(3), _mm512_set1_epi8(-2),
             [](__m512i acc, __m512i a, __m512i b) { return _mm512_dpbusd_epi32(acc, a, b); });
}

float RunS16s16(int64_t iterations) {
  return Run(iterations, _mm512_set1_epi16(300), _mm512_set1_epi16(-200),
             [](__m512i acc, __m512i a, __m512i b) { return _mm512_dpwssd_epi32(acc, a, b); });
}

}  // namespace

const PeakKernel* PeakKernelAvx512Vnni() {
  static const PeakKernel kernel = {"avx512_vnni: 24 zmm chains x 64 u8s8 MACs, vpdpbusd",
                                    2 * kChains * 64, RunU8s8};
  return &kernel;
}

const PeakKernel* PeakKernelAvx512VnniInt16() {
  static const PeakKernel kernel = {"avx512_vnni: 24 zmm chains x 32 s16s16 MACs, vpdpwssd",
                                    2 * kChains * 32, RunS16s16};
  return &kernel;
}

}  // namespace sfrt::profiling::internal
