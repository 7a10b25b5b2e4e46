// NEON peak loop: 24 independent q-register chains of fmla (of 32 vector registers).
#include <arm_neon.h>

#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling::internal {
namespace {

constexpr int kChains = 24;

float Run(int64_t iterations) {
  const float32x4_t m = vdupq_n_f32(0.999999f);
  const float32x4_t c = vdupq_n_f32(1e-6f);
  float32x4_t acc[kChains];
#pragma GCC unroll 24
  for (int j = 0; j < kChains; ++j) acc[j] = vdupq_n_f32(0.01f * static_cast<float>(j + 1));
  for (int64_t i = 0; i < iterations; ++i) {
#pragma GCC unroll 24
    for (int j = 0; j < kChains; ++j) {
      acc[j] = vfmaq_f32(c, acc[j], m);
      __asm__("" : "+w"(acc[j]));  // in a register, not merged or reordered (no instruction)
    }
  }
  float32x4_t sum = acc[0];
#pragma GCC unroll 24
  for (int j = 1; j < kChains; ++j) sum = vaddq_f32(sum, acc[j]);
  return vaddvq_f32(sum);
}

}  // namespace

const PeakKernel* PeakKernelNeon() {
  static const PeakKernel kernel = {"neon: 24 q-register chains x 4 lanes, fmla", 2 * kChains * 4,
                                    Run};
  return &kernel;
}

}  // namespace sfrt::profiling::internal
