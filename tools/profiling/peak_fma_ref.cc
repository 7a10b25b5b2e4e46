// Baseline-ISA peak loop: GCC/Clang 128-bit vector extension, multiply then add (no -m flags:
// SSE2 on x86-64, NEON on aarch64). 12 chains fit x86-64's 16 xmm registers.
#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling::internal {
namespace {

typedef float V4 __attribute__((vector_size(16)));

// An empty asm that takes and returns the chain in a vector register: the compiler can neither
// keep it in memory nor merge or reassociate chains. Emits no instruction.
inline void KeepInRegister(V4& v) {
#if defined(__x86_64__) || defined(__i386__)
  __asm__("" : "+x"(v));
#elif defined(__aarch64__)
  __asm__("" : "+w"(v));
#else
  __asm__("" : "+m"(v));
#endif
}
constexpr int kChains = 12;

float Run(int64_t iterations) {
  const V4 m = {0.999999f, 0.999999f, 0.999999f, 0.999999f};
  const V4 c = {1e-6f, 1e-6f, 1e-6f, 1e-6f};
  V4 acc[kChains];
#pragma GCC unroll 12
  for (int j = 0; j < kChains; ++j) {
    const float v = 0.01f * static_cast<float>(j + 1);
    acc[j] = V4{v, v, v, v};
  }
  for (int64_t i = 0; i < iterations; ++i) {
#pragma GCC unroll 12
    for (int j = 0; j < kChains; ++j) {
      acc[j] = acc[j] * m + c;
      KeepInRegister(acc[j]);
    }
  }
  V4 sum = acc[0];
#pragma GCC unroll 12
  for (int j = 1; j < kChains; ++j) sum += acc[j];
  return sum[0] + sum[1] + sum[2] + sum[3];
}

}  // namespace

const PeakKernel* PeakKernelRef() {
  static const PeakKernel kernel = {"ref: baseline 128-bit vectors, 12 chains x 4 lanes, mul+add",
                                    2 * kChains * 4, Run};
  return &kernel;
}

}  // namespace sfrt::profiling::internal
