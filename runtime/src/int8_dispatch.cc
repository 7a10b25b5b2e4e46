#include "cpu_features.h"
#include "kernels/int8_job.h"
#if SFRT_HAVE_NEON_DOT
#include "kernels/neon/int8_neon.h"
#endif

namespace sfrt {

#if !SFRT_HAVE_AVX512_AMX
// A build without the AMX kernels (not x86-64, or a compiler without AMX): there are none.
const IsaInt8Kernels* avx512::Int8KernelsAmx() { return nullptr; }
avx512::AmxTileFinishFn avx512::AmxTileFinish() { return nullptr; }
#endif

bool Int8KernelsAvailable(Isa isa) {
  return Int8KernelsFor(isa == Isa::kAuto ? BestIsa() : isa) != nullptr;
}

// The int8 kernels exist for AMX (avx512amx; with AVX-512 VNNI for what the tiles leave, and
// AVX-512 VNNI alone on an AMX CPU without AMX-INT8), AVX-512 VNNI and NEON with the dot-product
// extensions (sdot, or sudot with i8mm); every other ISA uses the reference.
const IsaInt8Kernels* Int8KernelsFor(Isa isa) {
#if SFRT_HAVE_AVX512_AMX
  if (isa == Isa::kAvx512Amx && HostCpuFeatures().amx_int8) return avx512::Int8KernelsAmx();
#endif
#if SFRT_HAVE_AVX512_VNNI
  if (VectorIsa(isa) == Isa::kAvx512 && HostCpuFeatures().avx512_vnni) {
    return avx512::Int8Kernels();
  }
#endif
#if SFRT_HAVE_NEON_DOT
  if (isa == Isa::kNeon && HostCpuFeatures().neon) return neon::Int8Kernels();
#endif
  (void)isa;
  return nullptr;
}

}  // namespace sfrt
