// The x86 extensions behind the int8, bf16 and AMX peaks (peak_dot.h), read with CPUID and XGETBV
// the way runtime/src/cpu_features.cc reads AVX-512 (whose header the tools may not include), plus
// the bits the runtime does not need yet: AVX512_BF16 and AMX. Each answer is "" when the
// extension can run in this process, else the first check that failed, e.g.
// "CPUID.(EAX=7,ECX=0):ECX.AVX512_VNNI[bit 11] = 0". On other architectures every answer says
// so.
#pragma once

#include <string>

namespace sfrt::profiling::internal {

// vpdpbusd on zmm: AVX512F and AVX512_VNNI, and the OS saves the ZMM state (XCR0 bits 1-2, 5-7).
std::string Avx512VnniMissing();

// vdpbf16ps on zmm: AVX512F and AVX512_BF16 (CPUID leaf 7 subleaf 1), ZMM state as above.
std::string Avx512Bf16Missing();

// AMX-TILE, AMX-INT8 and AMX-BF16; the OS enables XTILECFG and XTILEDATA (XCR0 bits 17-18); CPUID
// leaf 0x1D lists at least one tile palette; and Linux grants this process XTILEDATA
// (arch_prctl(ARCH_REQ_XCOMP_PERM, 18), asked once, only when every other check passed).
std::string AmxMissing();

}  // namespace sfrt::profiling::internal
