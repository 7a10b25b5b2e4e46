#include "cpu_features.h"
#include "kernels/int8_job.h"
#include "kernels/ref/conv2d_int8_ref.h"

namespace sfrt {

QuantizeKernel QuantizeKernelFor(Isa isa) {
#if SFRT_HAVE_AVX512_VNNI
  if (VectorIsa(isa) == Isa::kAvx512 && avx512::Int8Kernels() != nullptr) {
    return {avx512::QuantizeRows, "quantize_u8__avx512"};
  }
#endif
#if SFRT_HAVE_NEON
  if (isa == Isa::kNeon) return {neon::QuantizeRows, "quantize_u8__neon"};
#endif
  (void)isa;
  return {ref::QuantizeRows, "ref::QuantizeU8"};
}

}  // namespace sfrt
