#include "cpu_features.h"
#include "kernels/bf16_job.h"
#include "kernels/ref/conv2d_bf16_ref.h"

namespace sfrt {

#if !SFRT_HAVE_AVX512_AMX
// A build without the AMX kernels: there are none.
const IsaBf16Kernels* avx512::Bf16KernelsAmx() { return nullptr; }
#endif

bool Bf16KernelsAvailable(Isa isa) {
  return Bf16KernelsFor(isa == Isa::kAuto ? BestIsa() : isa) != nullptr;
}

// The bf16 kernels exist for AMX (avx512amx; with AVX512_BF16 for what the tiles leave, and
// AVX512_BF16 alone on an AMX CPU without AMX-BF16), AVX512_BF16 and
// NEON with the BF16 extension (bfdot); every other ISA uses the reference.
const IsaBf16Kernels* Bf16KernelsFor(Isa isa) {
#if SFRT_HAVE_AVX512_AMX
  if (isa == Isa::kAvx512Amx && HostCpuFeatures().amx_bf16) return avx512::Bf16KernelsAmx();
#endif
#if SFRT_HAVE_AVX512_BF16
  if (VectorIsa(isa) == Isa::kAvx512) return avx512::Bf16Kernels();
#endif
#if SFRT_HAVE_NEON_BF16
  if (isa == Isa::kNeon && HostCpuFeatures().neon) return neon::Bf16Kernels();
#endif
  (void)isa;
  return nullptr;
}

ToBf16Kernel ToBf16KernelFor(Isa isa) {
  if (Bf16KernelsFor(isa) != nullptr) {
#if SFRT_HAVE_AVX512_BF16
    if (VectorIsa(isa) == Isa::kAvx512) return {avx512::ToBf16Rows, "to_bf16__avx512"};
#endif
#if SFRT_HAVE_NEON_BF16
    if (isa == Isa::kNeon) return {neon::ToBf16Rows, "to_bf16__neon"};
#endif
  }
  return {ref::ToBf16Rows, "ref::ToBf16"};
}

}  // namespace sfrt
