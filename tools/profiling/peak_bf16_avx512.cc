// AVX512_BF16 peak loop: 24 independent zmm chains of vdpbf16ps (of 32 zmm registers). Each
// instruction multiplies 32 bf16 pairs and adds them, 2 to a lane, into 16 fp32 lanes.
#include <immintrin.h>

#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling::internal {
namespace {

constexpr int kChains = 24;
constexpr int kMacsPerInstruction = 32;

float Run(int64_t iterations) {
  // 2^-10 x 2^-10, twice per lane: each chain grows by 2^-19 a round, far from overflow and
  // never denormal.
  const __m512 x = _mm512_set1_ps(0x1p-10f);
  const __m512bh a = _mm512_cvtne2ps_pbh(x, x);
  const __m512bh b = _mm512_cvtne2ps_pbh(x, x);
  __m512 acc[kChains];
#pragma GCC unroll 24
  for (int j = 0; j < kChains; ++j) acc[j] = _mm512_set1_ps(0.01f * static_cast<float>(j + 1));
  for (int64_t i = 0; i < iterations; ++i) {
#pragma GCC unroll 24
    for (int j = 0; j < kChains; ++j) {
      acc[j] = _mm512_dpbf16_ps(acc[j], a, b);
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

const PeakKernel* PeakKernelAvx512Bf16() {
  static const PeakKernel kernel = {"avx512_bf16: 24 zmm chains x 32 bf16 MACs, vdpbf16ps",
                                    2 * kChains * kMacsPerInstruction, Run};
  return &kernel;
}

}  // namespace sfrt::profiling::internal
