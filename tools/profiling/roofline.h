// The roofline of a planned step: where its achieved rate stands against the roof of the unit it
// runs on, for `sfrt bench`.
//
// A step's unit is read from its kernel's name (the runtime names kernels by precision, ISA and
// tile: conv2d_u8s8__avx512amx_16x64 runs on AMX int8), one table, KernelUnit(). Its roof is the
// lower of the unit's measured peak and its arithmetic intensity (multiply-accumulates per byte
// it must move, Session::Work) times the measured memory read bandwidth; a step that computes
// nothing (a quantise, an upsampling, a copy) has the bandwidth alone as its roof. Every peak is
// measured on this machine at the step's thread count (peak_fma.h, peak_dot.h, peak_bandwidth.h),
// never assumed.
#pragma once

#include <array>
#include <map>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "profiling/peak_dot.h"
#include "sfrt/session.h"

namespace sfrt::profiling {

enum class ComputeUnit {
  kMemory,      // moves data only: the roof is the read bandwidth
  kFma,         // fp32 FMA of the session's ISA (Winograd included: its products)
  kInt8Dot,     // vpdpbusd, AVX-512 VNNI
  kBf16Dot,     // vdpbf16ps, AVX512_BF16
  kAmxInt8,     // tdpbusd
  kAmxBf16,     // tdpbf16ps
  kUnmeasured,  // a unit no peak loop measures (scalar int8/bf16, the AMX emulation, NEON dots)
};
inline constexpr std::array<const char*, 7> kComputeUnitNames = {
    "memory", "fma", "int8 vnni", "bf16 avx512", "amx int8", "amx bf16", "unmeasured"};
const char* ComputeUnitName(ComputeUnit unit);

// The unit `kernel` (PlannedStep::kernel) runs on; kMemory when the step does no
// multiply-accumulates (`macs` == 0).
ComputeUnit KernelUnit(std::string_view kernel, uint64_t macs);

// What was measured at one thread count: each unit's peak in GMAC/s (fp32 FMA: GFLOP/s / 2) and
// the read bandwidth in GB/s; 0 where not measured.
struct Peaks {
  double fma_gmacs = 0;
  double int8_gmacs = 0;
  double bf16_gmacs = 0;
  double amx_int8_gmacs = 0;
  double amx_bf16_gmacs = 0;
  double read_gbytes = 0;
  double Of(ComputeUnit unit) const;  // GMAC/s; 0 for kMemory and kUnmeasured
};

// One step on the roofline. Rates are NaN where their peak was not measured.
struct RooflinePoint {
  ComputeUnit unit = ComputeUnit::kMemory;
  double intensity = 0;        // MACs per byte moved (0 for a memory step)
  double peak_gmacs = 0;       // the unit's peak
  double roof_gmacs = 0;       // min(peak, intensity x bandwidth); NaN for a memory step
  double achieved_gmacs = 0;   // MACs / median time
  double achieved_gbytes = 0;  // bytes moved / median time (NaN for a view, which moves none)
  // The achieved rate over the roof: achieved_gmacs / roof_gmacs for a step that computes,
  // achieved_gbytes / the read bandwidth for a memory step.
  double share = 0;
  bool memory_bound = false;  // the bandwidth roof is the lower one
};

RooflinePoint PlaceStep(const StepWork& work, ComputeUnit unit, double median_ms,
                        const Peaks& peaks);

// A session's steps on the roofline at one input size.
struct Roofline {
  Peaks peaks;
  std::vector<StepWork> work;         // per step (Session::Work)
  std::vector<RooflinePoint> points;  // per step
  uint64_t macs = 0;                  // every step's, summed
  // The unit that does most of the multiply-accumulates, and the floor the issue tracker quotes:
  // all of `macs` at its peak.
  ComputeUnit main_unit = ComputeUnit::kMemory;
  double main_floor_ms = 0;
  // Each step's work at its own roof, summed (NaN when some step's roof is unknown).
  double floor_ms = 0;
};

// `kernels` and `median_ms` per step, as `work`.
Roofline PlaceSteps(std::vector<StepWork> work, std::span<const std::string> kernels,
                    std::span<const double> median_ms, const Peaks& peaks);

// The peaks a roofline needs, each measured once per thread count however many sessions ask
// (about `seconds` a measurement).
class PeakCache {
 public:
  explicit PeakCache(double seconds) : seconds_(seconds) {}
  // Fills the fields of `peaks` that the units in `units` need, and the read bandwidth; the FMA
  // peak is the caller's (measured for its ISA). Fails with the measurement's error.
  Status Fill(std::span<const ComputeUnit> units, int threads, Peaks* peaks);

 private:
  Result<double> Dot(DotType type, int threads);
  Result<double> Bandwidth(int threads);
  double seconds_;
  std::map<std::pair<int, int>, double> measured_;  // (what, threads) -> GMAC/s or GB/s
};

}  // namespace sfrt::profiling
