// The per-ISA loops behind MeasurePeakFma (peak_fma.cc). Each file is compiled with its ISA's
// flags (tools/profiling/CMakeLists.txt); calling one the CPU cannot run is undefined.
#pragma once

#include <cstdint>

namespace sfrt::profiling::internal {

struct PeakKernel {
  const char* description;
  int64_t flops_per_iteration;  // 2 x chains x lanes
  // Runs `iterations` rounds of every chain; returns a value depending on all of them.
  float (*run)(int64_t iterations);
};

// nullptr when the ISA's file is not part of this build.
const PeakKernel* PeakKernelRef();
const PeakKernel* PeakKernelAvx2();
const PeakKernel* PeakKernelAvx512();
const PeakKernel* PeakKernelNeon();

}  // namespace sfrt::profiling::internal
