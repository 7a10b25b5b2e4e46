// Peak int8 and bf16 dot-product throughput of this CPU per thread count, beside the fp32 FMA
// peak (peak_fma.h), measured the same way: independent accumulator chains held in registers,
// enough to cover latency x pipes, the fastest of 20 windows over about `seconds`, no privileges.
// - int8: vpdpbusd on zmm (AVX-512 VNNI), 64 u8 x s8 multiply-accumulates per instruction into
//   int32 lanes, as the runtime's int8 convolutions use it;
// - int16: vpdpwssd on zmm (AVX-512 VNNI), 32 s16 x s16 multiply-accumulates per instruction, the
//   rate integer Winograd would get (its transformed operands need more than 8 bits);
// - bf16: vdpbf16ps on zmm (AVX512_BF16), 32 bf16 multiply-accumulates per instruction into
//   fp32 lanes;
// - amx_int8 / amx_bf16: tdpbusd / tdpbf16ps on 6 C tiles (16384 / 8192 multiply-accumulates per
//   instruction), as the runtime's avx512amx kernels use them.
// Rates count 2 ops per multiply-accumulate (GOP/s for the integer types, GFLOP/s for bf16), as
// GFLOP/s does for the fp32 FMA.
#pragma once

#include <string>

#include "sfrt/status.h"

namespace sfrt::profiling {

enum class DotType { kInt8, kInt16, kBf16, kAmxInt8, kAmxBf16 };

// "int8", "int16", "bf16", "amx_int8", "amx_bf16".
const char* DotTypeName(DotType type);

struct PeakDot {
  DotType type = DotType::kInt8;
  int threads = 1;
  double gops = 0;     // all threads together, 2 ops per MAC: integer ops or flops (bf16)
  double gmacs = 0;    // multiply-accumulates: gops / 2
  std::string kernel;  // what ran, e.g. "avx512_vnni: 24 zmm chains x 64 u8s8 MACs, vpdpbusd"
};

// "" when this build and CPU run the type's loop, else why not (e.g. "not in this build" or the
// CPUID or XCR0 check that failed).
std::string PeakDotUnavailable(DotType type);

// Measures for about `seconds` (at least 20 ms) after a short calibration. Fails, with
// PeakDotUnavailable's reason, when this build or CPU cannot run the loop, or when threads < 1.
Result<PeakDot> MeasurePeakDot(DotType type, int threads, double seconds);

// True for kInt8, kInt16 and kAmxInt8 (integer ops), false for the bf16 types (flops).
bool DotTypeIsInteger(DotType type);

// "" when AMX could run in this process (AMX-TILE, AMX-INT8, AMX-BF16, the OS's tile state, a
// tile palette, and Linux's permission for XTILEDATA, which this asks for), else the check that
// failed.
std::string AmxUnavailable();

}  // namespace sfrt::profiling
