// AVX-512 VNNI peak loop: 24 independent zmm chains of vpdpbusd (of 32 zmm registers). Each
// instruction multiplies 64 u8 x s8 pairs and adds them, 4 to a lane, into 16 int32 lanes.
#include <immintrin.h>

#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling::internal {
namespace {

constexpr int kChains = 24;
constexpr int kMacsPerInstruction = 64;

float Run(int64_t iterations) {
  const __m512i a = _mm512_set1_epi8(3);   // u8
  const __m512i b = _mm512_set1_epi8(-2);  // s8
  __m512i acc[kChains];
#pragma GCC unroll 24
  for (int j = 0; j < kChains; ++j) acc[j] = _mm512_set1_epi32(j);
  for (int64_t i = 0; i < iterations; ++i) {
#pragma GCC unroll 24
    for (int j = 0; j < kChains; ++j) {
      acc[j] = _mm512_dpbusd_epi32(acc[j], a, b);  // wraps, never saturates: no overflow check
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

}  // namespace

const PeakKernel* PeakKernelAvx512Vnni() {
  static const PeakKernel kernel = {"avx512_vnni: 24 zmm chains x 64 u8s8 MACs, vpdpbusd",
                                    2 * kChains * kMacsPerInstruction, Run};
  return &kernel;
}

}  // namespace sfrt::profiling::internal
