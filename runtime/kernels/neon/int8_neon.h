// The NEON int8 convolution kernels (kernels/int8_job.h) with the dot-product instructions:
// conv2d_u8s8_neon_dot.cc (sdot on x - 128, Armv8.2 dotprod) and conv2d_u8s8_neon_usdot.cc
// (sudot by element, unsigned x signed, Armv8.6 i8mm). Built on aarch64 only (SFRT_HAVE_NEON_DOT).
#pragma once

#include "kernels/int8_job.h"

namespace sfrt::neon {

// The best of the two that this CPU runs (usdot, else sdot), or null without dotprod.
const IsaInt8Kernels* Int8Kernels();

// Each variant on its own, for the tests: null when the CPU lacks its extension (HWCAP_ASIMDDP;
// HWCAP2_I8MM and HWCAP_ASIMDDP).
const IsaInt8Kernels* Int8KernelsSdot();
const IsaInt8Kernels* Int8KernelsUsdot();

}  // namespace sfrt::neon
