// NEON int8 convolution kernels with sdot (Armv8.2 dotprod; compiled with
// -march=armv8.2-a+dotprod -ffp-contract=off only in this translation unit;
// runtime/CMakeLists.txt), bit for bit equal to ref::Conv2dInt8Rows. The loops are
// kernels/simd/dot_driver_inl.h's, the vocabulary conv2d_u8s8_neon_dot_inl.h's.
//
// sdot multiplies signed by signed bytes, and activations are uint8: the input goes in as
// x - 128 (its top bit flipped, as int8), and the zero point's correction absorbs the shift:
//   sum (x - z) * w = sum (x - 128) * w + (128 - z) * sum w
// over the taps inside the input, so the accumulators start from (128 - z) * their tap_sums.
// Input channels past in_channels (within cin4) have zero weights: whatever x - 128 they read
// adds nothing.
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

namespace sfrt::neon {
namespace {

struct Sdot {
  using X = int8x16_t;
  static X Prepare(uint8x16_t x) { return vreinterpretq_s8_u8(veorq_u8(x, vdupq_n_u8(0x80))); }
  template <int L>
  static int32x4_t Dot(int32x4_t acc, int8x16_t w, X x) {
    return vdotq_laneq_s32(acc, w, x, L);
  }
  static int32_t ZeroPointCoefficient(int zero_point) { return 128 - zero_point; }
};

using V = NeonDotInt8<Sdot>;

}  // namespace

const IsaInt8Kernels* Int8KernelsSdot() {
  // The tiles' pixels for 1, 2, 3 and 4 valid vectors: 8x1, 8x2, 6x3, 5x4.
  static constexpr IsaInt8Kernels kKernels = {
      V::kNr, simd::DotConvRows<V, 8, 8, 6, 5>, simd::DotUpConvRows<V, 8, 8, 6, 5>,
      "conv2d_u8s8__neon_sdot_5x16", "upconv2d_u8s8__neon_sdot_5x16"};
  return (getauxval(AT_HWCAP) & HWCAP_ASIMDDP) != 0 ? &kKernels : nullptr;
}

const IsaInt8Kernels* Int8Kernels() {
  if (const IsaInt8Kernels* usdot = Int8KernelsUsdot()) return usdot;
  return Int8KernelsSdot();
}

}  // namespace sfrt::neon
