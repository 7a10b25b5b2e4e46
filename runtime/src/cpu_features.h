// What the host CPU and OS let the runtime execute, detected once (thread-safe, no allocation
// after the first call).
//   x86-64: CPUID leaves 1, 7 and 7.1 for the instruction sets, XGETBV(XCR0) for the register state
//           the OS saves on context switches (YMM for AVX2; opmask + ZMM for AVX-512).
//   aarch64: getauxval(AT_HWCAP) & HWCAP_ASIMD.
#pragma once

namespace sfrt {

struct CpuFeatures {
  bool avx2_fma = false;     // AVX2 and FMA, with YMM state enabled by the OS
  bool avx512 = false;       // AVX-512 F, BW, VL and DQ, with opmask and ZMM state enabled
  bool avx512_vnni = false;  // avx512 and AVX512_VNNI (vpdpbusd)
  bool avx512_bf16 = false;  // avx512 and AVX512_BF16 (vdpbf16ps, vcvtneps2bf16)
  bool neon = false;         // aarch64 Advanced SIMD
};

const CpuFeatures& HostCpuFeatures();

}  // namespace sfrt
