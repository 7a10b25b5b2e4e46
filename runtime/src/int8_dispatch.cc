#include "cpu_features.h"
#include "kernels/int8_job.h"
#if SFRT_HAVE_NEON_DOT
#include "kernels/neon/int8_neon.h"
#endif

namespace sfrt {

bool Int8KernelsAvailable(Isa isa) {
  return Int8KernelsFor(isa == Isa::kAuto ? BestIsa() : isa) != nullptr;
}

// The int8 kernels exist for AVX-512 VNNI and for NEON with the dot-product extensions (sdot,
// or sudot with i8mm); every other ISA uses the reference.
const IsaInt8Kernels* Int8KernelsFor(Isa isa) {
#if SFRT_HAVE_AVX512_VNNI
  if (isa == Isa::kAvx512 && HostCpuFeatures().avx512_vnni) return avx512::Int8Kernels();
#endif
#if SFRT_HAVE_NEON_DOT
  if (isa == Isa::kNeon && HostCpuFeatures().neon) return neon::Int8Kernels();
#endif
  (void)isa;
  return nullptr;
}

}  // namespace sfrt
