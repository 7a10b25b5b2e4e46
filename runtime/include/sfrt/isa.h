// Instruction sets the runtime has kernels for, and which of them this CPU can run.
//
// A Session picks one ISA at Create (SessionOptions::isa; kAuto: the best the CPU runs) and
// keeps its kernels as function pointers. kRef is the scalar reference path and always
// available. (The `sfrt` tool maps its SFRT_ISA variable onto SessionOptions::isa; the library
// itself reads no environment.)
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

namespace sfrt {

enum class Isa {
  kAuto,    // SessionOptions only: BestIsa()
  kRef,     // scalar reference kernels (the oracle)
  kAvx2,    // x86-64 AVX2 + FMA
  kAvx512,  // x86-64 AVX-512 F/BW/VL/DQ (with the OS saving ZMM state)
  kNeon,    // aarch64 Advanced SIMD
  // x86-64 AVX-512 with AMX tiles (AMX-TILE with AMX-INT8 or AMX-BF16, the OS's tile state, tile
  // palette 1, Linux's tile-data permission): kAvx512's kernels, and int8 / bf16 convolutions on
  // the tiles (tdpbusd / tdpbf16ps) where the CPU has them.
  kAvx512Amx,
};

// The ISAs' names, declared once, in the order messages and help texts list them.
struct IsaWord {
  Isa isa;
  const char* name;
};
inline constexpr std::array<IsaWord, 6> kIsaWords = {{{Isa::kAuto, "auto"},
                                                      {Isa::kRef, "ref"},
                                                      {Isa::kAvx2, "avx2"},
                                                      {Isa::kAvx512, "avx512"},
                                                      {Isa::kAvx512Amx, "avx512amx"},
                                                      {Isa::kNeon, "neon"}}};
// "auto", "ref", "avx2", "avx512", "avx512amx", "neon" (kIsaWords).
const char* IsaName(Isa isa);
// Parses the names above (exactly, lower case); false for anything else.
bool ParseIsa(std::string_view name, Isa* isa);
// The names joined by `separator`, "auto" first or left out: "auto, ref, avx2, avx512,
// avx512amx, neon", for messages and help texts.
std::string IsaNameList(bool with_auto, std::string_view separator = ", ");
// True when this build has kernels for `isa` and this CPU (and OS) can execute them.
bool IsaSupported(Isa isa);
// Every supported ISA, kRef first, best last.
std::vector<Isa> SupportedIsas();
// The last entry of SupportedIsas().
Isa BestIsa();
// "ref, avx2, avx512": the supported ISAs as text, for messages.
std::string SupportedIsaList();

// True when a session on `isa` (kAuto: BestIsa()) runs int8 convolutions on SIMD int8 kernels:
// avx512 on a CPU with AVX-512 VNNI, avx512amx, neon on a CPU with the dot-product extension.
// Otherwise (and on kRef) its int8 layers run on the scalar reference kernel: the same results,
// slower.
bool Int8KernelsAvailable(Isa isa);

// True when a session on `isa` (kAuto: BestIsa()) runs bf16 convolutions on SIMD bf16 kernels:
// avx512 on a CPU with AVX512_BF16, avx512amx, neon on a CPU with the BF16 extension (Armv8.6
// bfdot).
// Otherwise its bf16 layers run on the scalar reference kernel: results within float32 rounding
// of the sums, much slower.
bool Bf16KernelsAvailable(Isa isa);

}  // namespace sfrt
