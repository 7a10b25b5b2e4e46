// The roofline of a planned step (roofline.h).
#include "profiling/roofline.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "profiling/peak_bandwidth.h"
#include "sfrt/vocabulary/names.h"

namespace sfrt::profiling {
namespace {

// Kernel names (runtime/kernels, step_planner.cc) by the unit they run on: the first row whose
// every part the name contains decides. Scalar int8 and bf16 (ref::...Int8, ref::...Bf16), the
// AMX emulation and the NEON dot products have no peak loop: they fall through to kUnmeasured,
// as does any name this table does not know.
struct UnitRow {
  std::string_view part;
  std::string_view also;  // "" or a second part the name must contain
  ComputeUnit unit;
};
constexpr UnitRow kUnitRows[] = {
    {"__amx_emulated", "", ComputeUnit::kUnmeasured},
    {"u8s8__avx512amx", "", ComputeUnit::kAmxInt8},
    {"bf16__avx512amx", "", ComputeUnit::kAmxBf16},
    {"u8s8__avx512vnni", "", ComputeUnit::kInt8Dot},
    {"bf16__avx512bf16", "", ComputeUnit::kBf16Dot},
    {"_f32__", "", ComputeUnit::kFma},
    {"winograd", "", ComputeUnit::kFma},
    {"ref::", "Int8", ComputeUnit::kUnmeasured},
    {"ref::", "Bf16", ComputeUnit::kUnmeasured},
    {"ref::", "", ComputeUnit::kFma},  // the float32 reference layers
};

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

const char* ComputeUnitName(ComputeUnit unit) {
  return vocabulary::NameOf(kComputeUnitNames, unit);
}

ComputeUnit KernelUnit(std::string_view kernel, uint64_t macs) {
  if (macs == 0) return ComputeUnit::kMemory;
  for (const UnitRow& row : kUnitRows) {
    if (kernel.find(row.part) == std::string_view::npos) continue;
    if (!row.also.empty() && kernel.find(row.also) == std::string_view::npos) continue;
    return row.unit;
  }
  return ComputeUnit::kUnmeasured;
}

double Peaks::Of(ComputeUnit unit) const {
  switch (unit) {
    case ComputeUnit::kFma:
      return fma_gmacs;
    case ComputeUnit::kInt8Dot:
      return int8_gmacs;
    case ComputeUnit::kBf16Dot:
      return bf16_gmacs;
    case ComputeUnit::kAmxInt8:
      return amx_int8_gmacs;
    case ComputeUnit::kAmxBf16:
      return amx_bf16_gmacs;
    case ComputeUnit::kMemory:
    case ComputeUnit::kUnmeasured:
      return 0;
  }
  return 0;
}

RooflinePoint PlaceStep(const StepWork& work, ComputeUnit unit, double median_ms,
                        const Peaks& peaks) {
  RooflinePoint p;
  p.unit = unit;
  const double seconds = median_ms * 1e-3;
  const double bytes = static_cast<double>(work.bytes());
  const double macs = static_cast<double>(work.macs);
  p.achieved_gbytes = seconds > 0 ? bytes / seconds * 1e-9 : kNaN;
  p.achieved_gmacs = seconds > 0 ? macs / seconds * 1e-9 : kNaN;
  const double bandwidth = peaks.read_gbytes > 0 ? peaks.read_gbytes : kNaN;
  if (unit == ComputeUnit::kMemory) {
    p.peak_gmacs = kNaN;
    p.roof_gmacs = kNaN;
    if (bytes == 0) p.achieved_gbytes = kNaN;  // a view: nothing moves, nothing to measure
    p.share = p.achieved_gbytes / bandwidth;
    p.memory_bound = true;
    return p;
  }
  p.intensity = bytes > 0 ? macs / bytes : kNaN;
  const double peak = peaks.Of(unit);
  p.peak_gmacs = peak > 0 ? peak : kNaN;
  const double memory_roof = p.intensity * bandwidth;
  // The lower of the two roofs; without the unit's peak the roof is unknown, without the
  // bandwidth it is the peak (a NaN compares false either way, so memory_bound stays false).
  p.memory_bound = memory_roof < p.peak_gmacs;
  p.roof_gmacs = std::isnan(memory_roof)    ? p.peak_gmacs
                 : std::isnan(p.peak_gmacs) ? kNaN  // no peak: the roof is not known
                                            : std::min(memory_roof, p.peak_gmacs);
  p.share = p.achieved_gmacs / p.roof_gmacs;
  return p;
}

Roofline PlaceSteps(std::vector<StepWork> work, std::span<const std::string> kernels,
                    std::span<const double> median_ms, const Peaks& peaks) {
  Roofline r;
  r.peaks = peaks;
  std::map<ComputeUnit, uint64_t> by_unit;
  for (size_t k = 0; k < work.size(); ++k) {
    const ComputeUnit unit = KernelUnit(k < kernels.size() ? kernels[k] : "", work[k].macs);
    const double ms = k < median_ms.size() ? median_ms[k] : kNaN;
    r.points.push_back(PlaceStep(work[k], unit, ms, peaks));
    r.macs += work[k].macs;
    by_unit[unit] += work[k].macs;
    const RooflinePoint& p = r.points.back();
    r.floor_ms += unit == ComputeUnit::kMemory
                      ? static_cast<double>(work[k].bytes()) / (peaks.read_gbytes * 1e6)
                      : static_cast<double>(work[k].macs) / (p.roof_gmacs * 1e6);
  }
  uint64_t most = 0;
  for (const auto& [unit, macs] : by_unit) {
    if (unit != ComputeUnit::kMemory && macs > most) {
      most = macs;
      r.main_unit = unit;
    }
  }
  const double main_peak = peaks.Of(r.main_unit);
  r.main_floor_ms = main_peak > 0 ? static_cast<double>(r.macs) / (main_peak * 1e6) : kNaN;
  r.work = std::move(work);
  return r;
}

Result<double> PeakCache::Dot(DotType type, int threads) {
  const std::pair<int, int> key{static_cast<int>(type), threads};
  if (auto it = measured_.find(key); it != measured_.end()) return it->second;
  Result<PeakDot> peak = MeasurePeakDot(type, threads, seconds_);
  if (!peak.ok()) return Status::Error(peak.message());
  measured_[key] = peak->gmacs;
  return peak->gmacs;
}

Result<double> PeakCache::Bandwidth(int threads) {
  const std::pair<int, int> key{-1, threads};
  if (auto it = measured_.find(key); it != measured_.end()) return it->second;
  Result<PeakBandwidth> peak = MeasureReadBandwidth(threads, seconds_);
  if (!peak.ok()) return Status::Error(peak.message());
  measured_[key] = peak->gbytes_per_second;
  return peak->gbytes_per_second;
}

Status PeakCache::Fill(std::span<const ComputeUnit> units, int threads, Peaks* peaks) {
  struct Need {
    ComputeUnit unit;
    DotType type;
    double Peaks::*field;
  };
  constexpr Need kNeeds[] = {
      {ComputeUnit::kInt8Dot, DotType::kInt8, &Peaks::int8_gmacs},
      {ComputeUnit::kBf16Dot, DotType::kBf16, &Peaks::bf16_gmacs},
      {ComputeUnit::kAmxInt8, DotType::kAmxInt8, &Peaks::amx_int8_gmacs},
      {ComputeUnit::kAmxBf16, DotType::kAmxBf16, &Peaks::amx_bf16_gmacs},
  };
  for (const Need& need : kNeeds) {
    if (std::find(units.begin(), units.end(), need.unit) == units.end()) continue;
    Result<double> gmacs = Dot(need.type, threads);
    if (!gmacs.ok()) return Status::Error(gmacs.message());
    peaks->*need.field = *gmacs;
  }
  Result<double> bandwidth = Bandwidth(threads);
  if (!bandwidth.ok()) return Status::Error(bandwidth.message());
  peaks->read_gbytes = *bandwidth;
  return Status::Ok();
}

}  // namespace sfrt::profiling
