// What the host CPU and OS let the runtime execute, detected once (thread-safe, no allocation
// after the first call).
//   x86-64: CPUID leaves 1, 7, 7.1 and 0x1D for the instruction sets, XGETBV(XCR0) for the register
//   state
//           the OS saves on context switches (YMM for AVX2; opmask + ZMM for AVX-512).
//   aarch64: getauxval(AT_HWCAP) & HWCAP_ASIMD.
#pragma once

#include "sfrt/isa.h"

namespace sfrt {

struct CpuFeatures {
  bool avx2_fma = false;     // AVX2 and FMA, with YMM state enabled by the OS
  bool avx512 = false;       // AVX-512 F, BW, VL and DQ, with opmask and ZMM state enabled
  bool avx512_vnni = false;  // avx512 and AVX512_VNNI (vpdpbusd)
  bool avx512_bf16 = false;  // avx512 and AVX512_BF16 (vdpbf16ps, vcvtneps2bf16)
  // avx512_vnni, AMX-TILE and AMX-INT8 (CPUID 7.0 EDX bits 24-25), the tile state enabled by the
  // OS (XCR0 bits 17-18), palette 1 in CPUID leaf 0x1D with 8 tiles of 16 rows x 64 bytes (some
  // hypervisors advertise AMX with no palette), and the tile data permission granted by Linux
  // (arch_prctl ARCH_REQ_XCOMP_PERM, requested once here).
  bool amx_int8 = false;
  bool amx_bf16 = false;  // as amx_int8, with avx512_bf16 and AMX-BF16 (CPUID 7.0 EDX bit 22)
  bool neon = false;      // aarch64 Advanced SIMD
};

const CpuFeatures& HostCpuFeatures();

// The ISA whose float32 (and conversion) kernels a session on `isa` uses: kAvx512 for
// kAvx512Amx (AMX adds int8 and bf16 convolutions only), `isa` itself otherwise.
inline Isa VectorIsa(Isa isa) { return isa == Isa::kAvx512Amx ? Isa::kAvx512 : isa; }

}  // namespace sfrt
