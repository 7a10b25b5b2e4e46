#include "profiling/cpu_extensions.h"

#include <cstdint>
#include <cstdio>
#include <utility>

#if defined(__x86_64__)
#include <cpuid.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#define SFRT_PROFILING_X86 1
#endif

namespace sfrt::profiling::internal {
namespace {

#if defined(SFRT_PROFILING_X86)

constexpr uint64_t kXcr0Zmm = 0xe6;  // SSE, AVX, opmask, ZMM_Hi256, Hi16_ZMM
constexpr uint64_t kXcr0Tile = (1ull << 17) | (1ull << 18);  // XTILECFG, XTILEDATA
constexpr int kArchReqXcompPerm = 0x1023;                    // asm/prctl.h
constexpr int kXfeatureXtiledata = 18;

struct Leaf {
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
};

// CPUID (leaf, subleaf); all zero when the leaf is above the CPU's highest.
Leaf Cpuid(unsigned leaf, unsigned subleaf) {
  Leaf r;
  if (!__get_cpuid_count(leaf, subleaf, &r.eax, &r.ebx, &r.ecx, &r.edx)) return Leaf{};
  return r;
}

bool Bit(unsigned reg, int bit) { return ((reg >> bit) & 1u) != 0; }

// XCR0, or 0 when the OS has not set CR4.OSXSAVE (XGETBV would fault).
uint64_t Xcr0() {
  if (!Bit(Cpuid(1, 0).ecx, 27)) return 0;
  uint32_t eax = 0, edx = 0;
  __asm__ volatile("xgetbv" : "=a"(eax), "=d"(edx) : "c"(0));
  return (static_cast<uint64_t>(edx) << 32) | eax;
}

std::string Hex(uint64_t v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%#llx", static_cast<unsigned long long>(v));
  return buf;
}

// AVX512F and the OS's ZMM state, which both zmm loops need.
std::string ZmmMissing() {
  if (!Bit(Cpuid(7, 0).ebx, 16)) return "CPUID.(EAX=7,ECX=0):EBX.AVX512F[bit 16] = 0";
  const uint64_t xcr0 = Xcr0();
  if ((xcr0 & kXcr0Zmm) != kXcr0Zmm) {
    return "the OS does not enable the ZMM state: XCR0 = " + Hex(xcr0) + ", needs " + Hex(kXcr0Zmm);
  }
  return "";
}

std::string DetectVnni() {
  if (std::string zmm = ZmmMissing(); !zmm.empty()) return zmm;
  if (!Bit(Cpuid(7, 0).ecx, 11)) return "CPUID.(EAX=7,ECX=0):ECX.AVX512_VNNI[bit 11] = 0";
  return "";
}

std::string DetectBf16() {
  if (std::string zmm = ZmmMissing(); !zmm.empty()) return zmm;
  // Subleaf 1 exists when subleaf 0's EAX (the highest subleaf) is at least 1.
  if (Cpuid(7, 0).eax < 1 || !Bit(Cpuid(7, 1).eax, 5)) {
    return "CPUID.(EAX=7,ECX=1):EAX.AVX512_BF16[bit 5] = 0";
  }
  return "";
}

std::string DetectAmx() {
  const Leaf l7 = Cpuid(7, 0);
  std::string missing;
  for (auto [bit, name] : {std::pair{24, "AMX-TILE"}, {25, "AMX-INT8"}, {22, "AMX-BF16"}}) {
    if (Bit(l7.edx, bit)) continue;
    missing +=
        std::string(missing.empty() ? "" : ", ") + name + "[bit " + std::to_string(bit) + "]";
  }
  if (!missing.empty()) return "CPUID.(EAX=7,ECX=0):EDX lacks " + missing;
  const uint64_t xcr0 = Xcr0();
  if ((xcr0 & kXcr0Tile) != kXcr0Tile) {
    return "the OS does not enable the tile state: XCR0 = " + Hex(xcr0) +
           ", needs bits 17-18 (XTILECFG, XTILEDATA)";
  }
  if (__get_cpuid_max(0, nullptr) < 0x1d || Cpuid(0x1d, 0).eax == 0) {
    return "CPUID leaf 0x1D lists no tile palette";
  }
  if (syscall(SYS_arch_prctl, kArchReqXcompPerm, kXfeatureXtiledata) != 0) {
    return std::string("arch_prctl(ARCH_REQ_XCOMP_PERM, XFEATURE_XTILEDATA) failed: ") +
           std::strerror(errno);
  }
  return "";
}

#else

constexpr char kNotX86[] = "not an x86-64 CPU";
std::string DetectVnni() { return kNotX86; }
std::string DetectBf16() { return kNotX86; }
std::string DetectAmx() { return kNotX86; }

#endif

}  // namespace

std::string Avx512VnniMissing() {
  static const std::string missing = DetectVnni();
  return missing;
}

std::string Avx512Bf16Missing() {
  static const std::string missing = DetectBf16();
  return missing;
}

std::string AmxMissing() {
  static const std::string missing = DetectAmx();
  return missing;
}

}  // namespace sfrt::profiling::internal
