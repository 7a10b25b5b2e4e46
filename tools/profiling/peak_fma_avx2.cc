// AVX2 + FMA peak loop: 12 independent ymm chains of vfmadd (of 16 ymm registers; two hold the
// multiplier and addend).
#include <immintrin.h>

#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling::internal {
namespace {

constexpr int kChains = 12;

float Run(int64_t iterations) {
  const __m256 m = _mm256_set1_ps(0.999999f);
  const __m256 c = _mm256_set1_ps(1e-6f);
  __m256 acc[kChains];
#pragma GCC unroll 12
  for (int j = 0; j < kChains; ++j) acc[j] = _mm256_set1_ps(0.01f * static_cast<float>(j + 1));
  for (int64_t i = 0; i < iterations; ++i) {
#pragma GCC unroll 12
    for (int j = 0; j < kChains; ++j) {
      acc[j] = _mm256_fmadd_ps(acc[j], m, c);
      __asm__("" : "+v"(acc[j]));  // in a register, not merged or reordered (no instruction)
    }
  }
  __m256 sum = acc[0];
#pragma GCC unroll 12
  for (int j = 1; j < kChains; ++j) sum = _mm256_add_ps(sum, acc[j]);
  alignas(32) float lanes[8];
  _mm256_store_ps(lanes, sum);
  float total = 0;
  for (float v : lanes) total += v;
  return total;
}

}  // namespace

const PeakKernel* PeakKernelAvx2() {
  static const PeakKernel kernel = {"avx2: 12 ymm chains x 8 lanes, vfmadd", 2 * kChains * 8, Run};
  return &kernel;
}

}  // namespace sfrt::profiling::internal
