#include "cpu_features.h"
#include "kernels/int8_job.h"

namespace sfrt {

// The int8 kernels exist for AVX-512 VNNI only; every other ISA uses the reference.
const IsaInt8Kernels* Int8KernelsFor(Isa isa) {
#if SFRT_HAVE_AVX512_VNNI
  if (isa == Isa::kAvx512 && HostCpuFeatures().avx512_vnni) return avx512::Int8Kernels();
#else
  (void)isa;
#endif
  return nullptr;
}

}  // namespace sfrt
