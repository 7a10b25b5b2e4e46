#include "cpu_features.h"

#include <cstdint>

#include "sfrt/isa.h"

#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#include <sys/syscall.h>
#include <unistd.h>
#define SFRT_X86 1
#elif defined(__aarch64__)
#include <asm/hwcap.h>
#include <sys/auxv.h>
#endif

namespace sfrt {
namespace {

#if defined(SFRT_X86)
uint64_t ReadXcr0() {
  uint32_t eax = 0, edx = 0;
  __asm__ volatile("xgetbv" : "=a"(eax), "=d"(edx) : "c"(0));
  return (static_cast<uint64_t>(edx) << 32) | eax;
}
#endif

#if defined(SFRT_X86)
// AMX-TILE, the OS's tile state, palette 1 as the kernels use it, and Linux's
// permission to use the tile data (granted once per process; a denial leaves AMX off).
bool AmxUsable() {
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (!__get_cpuid_count(7, 0, &eax, &ebx, &ecx, &edx)) return false;
  if (((edx >> 24) & 1) == 0) return false;                     // AMX-TILE
  constexpr uint64_t kTileState = (1ull << 17) | (1ull << 18);  // XTILECFG, XTILEDATA
  if ((ReadXcr0() & kTileState) != kTileState) return false;
  if (__get_cpuid_max(0, nullptr) < 0x1d) return false;
  __cpuid_count(0x1d, 0, eax, ebx, ecx, edx);
  if (eax < 1) return false;  // the highest palette: none
  __cpuid_count(0x1d, 1, eax, ebx, ecx, edx);
  const unsigned max_names = ebx >> 16, bytes_per_row = ebx & 0xffff, max_rows = ecx & 0xffff;
  if (max_names < 8 || bytes_per_row < 64 || max_rows < 16) return false;
  constexpr long kArchReqXcompPerm = 0x1023;
  constexpr long kXfeatureXtiledata = 18;
  return syscall(SYS_arch_prctl, kArchReqXcompPerm, kXfeatureXtiledata) == 0;
}
#endif

CpuFeatures Detect() {
  CpuFeatures f;
#if defined(SFRT_X86)
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (!__get_cpuid(1, &eax, &ebx, &ecx, &edx)) return f;
  const bool osxsave = (ecx >> 27) & 1;
  const bool avx = (ecx >> 28) & 1;
  const bool fma = (ecx >> 12) & 1;
  if (!osxsave || !avx) return f;
  const uint64_t xcr0 = ReadXcr0();
  const bool ymm_state = (xcr0 & 0x6) == 0x6;    // SSE + AVX state
  const bool zmm_state = (xcr0 & 0xe6) == 0xe6;  // + opmask, ZMM_Hi256, Hi16_ZMM
  if (!__get_cpuid_count(7, 0, &eax, &ebx, &ecx, &edx)) return f;
  const bool avx2 = (ebx >> 5) & 1;
  const bool avx512f = (ebx >> 16) & 1;
  const bool avx512dq = (ebx >> 17) & 1;
  const bool avx512bw = (ebx >> 30) & 1;
  const bool avx512vl = (ebx >> 31) & 1;
  const bool avx512vnni = (ecx >> 11) & 1;
  const unsigned edx7 = edx;  // AMX-BF16 (bit 22), AMX-TILE (24), AMX-INT8 (25)
  f.avx2_fma = avx2 && fma && ymm_state;
  f.avx512 = f.avx2_fma && avx512f && avx512dq && avx512bw && avx512vl && zmm_state;
  f.avx512_vnni = f.avx512 && avx512vnni;
  unsigned max_sub = 0;
  if (__get_cpuid_count(7, 0, &max_sub, &ebx, &ecx, &edx) && max_sub >= 1 &&
      __get_cpuid_count(7, 1, &eax, &ebx, &ecx, &edx)) {
    f.avx512_bf16 = f.avx512 && ((eax >> 5) & 1);
  }
  // AmxUsable asks Linux for the tile permission: once, whichever precision needs it.
  const bool amx = f.avx512 && AmxUsable();
  f.amx_int8 = amx && f.avx512_vnni && ((edx7 >> 25) & 1);
  f.amx_bf16 = amx && f.avx512_bf16 && ((edx7 >> 22) & 1);
#elif defined(__aarch64__)
  f.neon = (getauxval(AT_HWCAP) & HWCAP_ASIMD) != 0;
#endif
  return f;
}

// Whether this build compiled kernels for an ISA (runtime/CMakeLists.txt sets these).
bool Compiled(Isa isa) {
  switch (isa) {
    case Isa::kRef:
      return true;
    case Isa::kAvx2:
      return SFRT_HAVE_AVX2 != 0;
    case Isa::kAvx512:
      return SFRT_HAVE_AVX512 != 0;
    case Isa::kNeon:
      return SFRT_HAVE_NEON != 0;
    case Isa::kAvx512Amx:
      return SFRT_HAVE_AVX512 != 0 && SFRT_HAVE_AVX512_AMX != 0;
    case Isa::kAuto:
      return false;
  }
  return false;
}

}  // namespace

const CpuFeatures& HostCpuFeatures() {
  static const CpuFeatures features = Detect();
  return features;
}

const char* IsaName(Isa isa) {
  for (const IsaWord& word : kIsaWords) {
    if (word.isa == isa) return word.name;
  }
  return "?";
}

bool ParseIsa(std::string_view name, Isa* isa) {
  for (const IsaWord& word : kIsaWords) {
    if (name == word.name) {
      *isa = word.isa;
      return true;
    }
  }
  return false;
}

std::string IsaNameList(bool with_auto, std::string_view separator) {
  std::string out;
  for (const IsaWord& word : kIsaWords) {
    if (word.isa == Isa::kAuto && !with_auto) continue;
    if (!out.empty()) out += separator;
    out += word.name;
  }
  return out;
}

bool IsaSupported(Isa isa) {
  if (!Compiled(isa)) return false;
  const CpuFeatures& f = HostCpuFeatures();
  switch (isa) {
    case Isa::kRef:
      return true;
    case Isa::kAvx2:
      return f.avx2_fma;
    case Isa::kAvx512:
      return f.avx512;
    case Isa::kNeon:
      return f.neon;
    case Isa::kAvx512Amx:
      return f.avx512 && (f.amx_int8 || f.amx_bf16);
    case Isa::kAuto:
      return false;
  }
  return false;
}

std::vector<Isa> SupportedIsas() {
  std::vector<Isa> out;
  for (Isa isa : {Isa::kRef, Isa::kNeon, Isa::kAvx2, Isa::kAvx512, Isa::kAvx512Amx}) {
    if (IsaSupported(isa)) out.push_back(isa);
  }
  return out;
}

Isa BestIsa() { return SupportedIsas().back(); }

std::string SupportedIsaList() {
  std::string out;
  for (Isa isa : SupportedIsas()) {
    if (!out.empty()) out += ", ";
    out += IsaName(isa);
  }
  return out;
}

}  // namespace sfrt
