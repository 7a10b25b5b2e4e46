// Peak fp32 FMA throughput of this CPU, per ISA and thread count: the ceiling that `sfrt bench`
// reports each configuration's effective GFLOP/s against ("% of peak").
//
// Each thread runs a loop of independent multiply-add chains held in vector registers (AVX-512:
// 24 zmm, AVX2: 12 ymm, NEON: 24 q registers; enough to cover the FMA latency times the number
// of FMA pipes), so the loop is bound by FMA issue alone. "ref" measures the baseline ISA the
// scalar reference kernels are compiled for (128-bit vectors, multiply then add: SSE2 on
// x86-64, NEON on aarch64), the most a compiler could get out of them.
// The measurement takes about `seconds` in 20 windows and keeps the fastest, so a machine shared
// with other work still reads close to the hardware's rate when some windows run undisturbed
// (and reads low, never high, when none do); it needs no privileges and no pinning.
#pragma once

#include <string>

#include "sfrt/isa.h"
#include "sfrt/status.h"

namespace sfrt::profiling {

struct PeakFma {
  Isa isa = Isa::kRef;
  int threads = 1;
  double gflops = 0;   // all threads together, 2 flops per lane and FMA
  std::string kernel;  // what ran, e.g. "avx512: 24 zmm chains x 16 lanes, vfmadd"
};

// Measures for about `seconds` (at least 20 ms) after a short calibration. Fails when this build or
// CPU cannot run `isa` (kAuto means BestIsa()) or threads < 1.
Result<PeakFma> MeasurePeakFma(Isa isa, int threads, double seconds);

}  // namespace sfrt::profiling
