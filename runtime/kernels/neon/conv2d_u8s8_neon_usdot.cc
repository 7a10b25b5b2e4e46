// NEON int8 convolution kernels with the i8mm mixed-sign dot product (Armv8.6 FEAT_I8MM;
// compiled with -march=armv8.2-a+dotprod+i8mm -ffp-contract=off only in this translation unit;
// runtime/CMakeLists.txt; run only where HWCAP2_I8MM says so), bit for bit equal to
// ref::Conv2dInt8Rows. The loops are kernels/simd/dot_driver_inl.h's, the vocabulary
// conv2d_u8s8_neon_dot_inl.h's.
//
// sudot by element multiplies the signed weights by 4 unsigned input bytes of one lane, so the
// input goes in as it is: sum (x - z) * w = sum x * w - z * sum w over the taps inside the
// input, and the accumulators start from -z * their tap_sums (as the AVX-512 VNNI kernel's).
#include <arm_neon.h>
#include <sys/auxv.h>

#include <cstdint>

#include "kernels/int8_job.h"
#include "kernels/neon/conv2d_u8s8_neon_dot_inl.h"
#include "kernels/neon/int8_neon.h"
#include "kernels/simd/dot_driver_inl.h"

#ifndef HWCAP_ASIMDDP
#define HWCAP_ASIMDDP (1 << 20)
#endif
#ifndef HWCAP2_I8MM
#define HWCAP2_I8MM (1 << 13)
#endif

namespace sfrt::neon {
namespace {

struct Usdot {
  using X = uint8x16_t;
  static X Prepare(uint8x16_t x) { return x; }
  template <int L>
  static int32x4_t Dot(int32x4_t acc, int8x16_t w, X x) {
    return vsudotq_laneq_s32(acc, w, x, L);
  }
  static int32_t ZeroPointCoefficient(int zero_point) { return -zero_point; }
};

using V = NeonDotInt8<Usdot>;

}  // namespace

const IsaInt8Kernels* Int8KernelsUsdot() {
  // The tiles' pixels for 1, 2, 3 and 4 valid vectors: 8x1, 8x2, 6x3, 5x4.
  static constexpr IsaInt8Kernels kKernels = {
      V::kNr, simd::DotConvRows<V, 8, 8, 6, 5>, simd::DotUpConvRows<V, 8, 8, 6, 5>,
      "conv2d_u8s8__neon_usdot_5x16", "upconv2d_u8s8__neon_usdot_5x16"};
  const bool dot = (getauxval(AT_HWCAP) & HWCAP_ASIMDDP) != 0;
  const bool i8mm = (getauxval(AT_HWCAP2) & HWCAP2_I8MM) != 0;
  return dot && i8mm ? &kKernels : nullptr;
}

}  // namespace sfrt::neon
