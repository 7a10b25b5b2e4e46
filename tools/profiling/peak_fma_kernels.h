// The per-ISA loops behind MeasurePeakFma (peak_fma.cc) and MeasurePeakDot (peak_dot.cc). Each
// file is compiled with its ISA's flags (tools/profiling/CMakeLists.txt); calling one the CPU
// cannot run is undefined.
#pragma once

#include <cstdint>

namespace sfrt::profiling::internal {

struct PeakKernel {
  const char* description;
  // 2 x the multiply-accumulates of one round (chains x lanes, or chains x MACs per instruction
  // for the dot-product loops): flops, or integer ops for int8.
  int64_t ops_per_iteration;
  // Runs `iterations` rounds of every chain; returns a value depending on all of them.
  float (*run)(int64_t iterations);
};

// nullptr when the ISA's file is not part of this build.
const PeakKernel* PeakKernelRef();
const PeakKernel* PeakKernelAvx2();
const PeakKernel* PeakKernelAvx512();
const PeakKernel* PeakKernelNeon();
const PeakKernel* PeakKernelAvx512Vnni();       // int8: vpdpbusd
const PeakKernel* PeakKernelAvx512VnniInt16();  // int16: vpdpwssd
const PeakKernel* PeakKernelAvx512Bf16();       // bf16: vdpbf16ps
const PeakKernel* PeakKernelAmxInt8();          // int8: tdpbusd
const PeakKernel* PeakKernelAmxBf16();          // bf16: tdpbf16ps

// G ops/s of `kernel` on `threads` threads (>= 1): a calibration, then the fastest of 20 windows
// over about `seconds` in all (each at least 1 ms).
double MeasureGopsPerSecond(const PeakKernel& kernel, int threads, double seconds);

}  // namespace sfrt::profiling::internal
