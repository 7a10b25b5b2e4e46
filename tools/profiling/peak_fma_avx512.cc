// AVX-512F peak loop: 24 independent zmm chains of vfmadd (of 32 zmm registers).
#include <immintrin.h>

#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling::internal {
namespace {

constexpr int kChains = 24;

float Run(int64_t iterations) {
  const __m512 m = _mm512_set1_ps(0.999999f);
  const __m512 c = _mm512_set1_ps(1e-6f);
  __m512 acc[kChains];
#pragma GCC unroll 24
  for (int j = 0; j < kChains; ++j) acc[j] = _mm512_set1_ps(0.01f * static_cast<float>(j + 1));
  for (int64_t i = 0; i < iterations; ++i) {
#pragma GCC unroll 24
    for (int j = 0; j < kChains; ++j) {
      acc[j] = _mm512_fmadd_ps(acc[j], m, c);
      __asm__("" : "+v"(acc[j]));  // in a register, not merged or reordered (no instruction)
    }
  }
  __m512 sum = acc[0];
#pragma GCC unroll 24
  for (int j = 1; j < kChains; ++j) sum = _mm512_add_ps(sum, acc[j]);
  alignas(64) float lanes[16];  // not _mm512_reduce_add_ps: GCC 12 warns inside it
  _mm512_store_ps(lanes, sum);
  float total = 0;
  for (float v : lanes) total += v;
  return total;
}

}  // namespace

const PeakKernel* PeakKernelAvx512() {
  static const PeakKernel kernel = {"avx512: 24 zmm chains x 16 lanes, vfmadd", 2 * kChains * 16,
                                    Run};
  return &kernel;
}

}  // namespace sfrt::profiling::internal
