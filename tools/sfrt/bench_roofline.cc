// `sfrt bench`'s roofline table and JSON (bench_roofline.h).
#include "sfrt/bench_roofline.h"

#include <cmath>
#include <cstdio>

namespace sfrt::tools {
namespace {

namespace prof = sfrt::profiling;
using Json = nlohmann::ordered_json;

using prof::FormatCell;

// Four significant digits: 19.33, 0.001234.
std::string Significant(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.4g", v);
  return buf;
}

// A rate with its unit: "587.2 GMAC/s", "15.0 GB/s", "-".
std::string Rate(double v, const char* unit) {
  return std::isfinite(v) ? prof::FormatFixed(v, 1) + " " + unit : "-";
}

Json Nullable(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

// The peaks line: the units the steps use, and the bandwidth.
std::string PeaksLine(const prof::Roofline& r) {
  std::string line;
  for (prof::ComputeUnit unit :
       {prof::ComputeUnit::kFma, prof::ComputeUnit::kInt8Dot, prof::ComputeUnit::kBf16Dot,
        prof::ComputeUnit::kAmxInt8, prof::ComputeUnit::kAmxBf16}) {
    bool used = false;
    for (const prof::RooflinePoint& p : r.points) used = used || p.unit == unit;
    if (!used) continue;
    line +=
        std::string(prof::ComputeUnitName(unit)) + " " + Rate(r.peaks.Of(unit), "GMAC/s") + ", ";
  }
  return line + "read " + Rate(r.peaks.read_gbytes, "GB/s");
}

}  // namespace

Result<prof::Roofline> PlaceSessionSteps(const Session& session,
                                         const std::vector<prof::StepRow>& rows, int height,
                                         int width, bool quantized_input, double fma_gflops,
                                         prof::PeakCache* cache) {
  Result<std::vector<StepWork>> work = session.Work(height, width, quantized_input);
  if (!work.ok()) return Status::Error(work.message());
  std::vector<std::string> kernels;
  std::vector<double> median_ms;
  std::vector<prof::ComputeUnit> units;
  for (size_t k = 0; k < work->size(); ++k) {
    kernels.push_back(session.steps()[k].kernel);
    median_ms.push_back(k < rows.size() ? rows[k].ms.p50 : NAN);
    units.push_back(prof::KernelUnit(kernels.back(), (*work)[k].macs));
  }
  prof::Peaks peaks;
  peaks.fma_gmacs = fma_gflops / 2;
  if (Status s = cache->Fill(units, session.threads(), &peaks); !s.ok()) return s;
  return prof::PlaceSteps(std::move(work).value(), kernels, median_ms, peaks);
}

std::string FormatRoofline(const std::vector<prof::StepRow>& rows, const prof::Roofline& r,
                           double median_run_ms) {
  std::string out = "peaks: " + PeaksLine(r) + "\n";
  char line[512];
  std::snprintf(line, sizeof(line), "%4s  %-28s %-11s %8s %8s %7s %8s %13s %13s %6s  %s\n", "step",
                "layers", "unit", "GMAC", "MB", "MAC/B", "ms", "achieved", "roof", "% roof",
                "bound");
  out += line;
  for (size_t k = 0; k < r.points.size() && k < rows.size(); ++k) {
    const prof::RooflinePoint& p = r.points[k];
    const StepWork& w = r.work[k];
    const bool memory = p.unit == prof::ComputeUnit::kMemory;
    std::string name = rows[k].label.name;
    if (name.size() > 28) name = name.substr(0, 25) + "...";
    const std::string achieved =
        memory ? Rate(p.achieved_gbytes, "GB/s") : Rate(p.achieved_gmacs, "GMAC/s");
    const std::string roof =
        memory ? Rate(r.peaks.read_gbytes, "GB/s") : Rate(p.roof_gmacs, "GMAC/s");
    const char* bound = memory                         ? "memory"
                        : !std::isfinite(p.roof_gmacs) ? "-"
                        : p.memory_bound               ? "memory"
                                                       : "compute";
    std::snprintf(line, sizeof(line), "%4zu  %-28s %-11s %8s %8s %7s %8s %13s %13s %6s  %s\n", k,
                  name.c_str(), prof::ComputeUnitName(p.unit),
                  memory ? "-" : Significant(static_cast<double>(w.macs) * 1e-9).c_str(),
                  FormatCell(static_cast<double>(w.bytes()) * 1e-6, 2).c_str(),
                  memory ? "-" : FormatCell(p.intensity, 1).c_str(),
                  FormatCell(rows[k].ms.p50, 3).c_str(), achieved.c_str(), roof.c_str(),
                  FormatCell(100 * p.share, 1).c_str(), bound);
    out += line;
  }
  std::snprintf(line, sizeof(line),
                "floor: every step at its roof %s ms; the median run %s ms is %sx it\n",
                FormatCell(r.floor_ms, 3).c_str(), FormatCell(median_run_ms, 3).c_str(),
                FormatCell(median_run_ms / r.floor_ms, 2).c_str());
  out += line;
  std::snprintf(line, sizeof(line),
                "floor: all %s GMAC at the %s peak %s ms; the median run is %sx it\n",
                Significant(static_cast<double>(r.macs) * 1e-9).c_str(),
                prof::ComputeUnitName(r.main_unit), FormatCell(r.main_floor_ms, 3).c_str(),
                FormatCell(median_run_ms / r.main_floor_ms, 2).c_str());
  return out + line;
}

Json RooflineJson(const prof::Roofline& r, double median_run_ms) {
  Json steps = Json::array();
  for (size_t k = 0; k < r.points.size(); ++k) {
    const prof::RooflinePoint& p = r.points[k];
    const StepWork& w = r.work[k];
    const bool memory = p.unit == prof::ComputeUnit::kMemory;
    steps.push_back(
        Json{{"step", k},
             {"unit", prof::ComputeUnitName(p.unit)},
             {"macs", w.macs},
             {"bytes_read", w.bytes_read},
             {"bytes_written", w.bytes_written},
             {"weight_bytes", w.weight_bytes},
             {"intensity_macs_per_byte", memory ? Json(nullptr) : Nullable(p.intensity)},
             {"peak_gmacs", Nullable(p.peak_gmacs)},
             {"roof_gmacs", Nullable(p.roof_gmacs)},
             {"achieved_gmacs", memory ? Json(nullptr) : Nullable(p.achieved_gmacs)},
             {"achieved_gbytes", Nullable(p.achieved_gbytes)},
             {"share_of_roof", Nullable(p.share)},
             {"bound", memory || p.memory_bound ? "memory" : "compute"}});
  }
  const prof::Peaks& k = r.peaks;
  auto peak = [](double v) { return v > 0 ? Json(v) : Json(nullptr); };
  return Json{{"peaks", Json{{"fma_gmacs", peak(k.fma_gmacs)},
                             {"int8_vnni_gmacs", peak(k.int8_gmacs)},
                             {"bf16_avx512_gmacs", peak(k.bf16_gmacs)},
                             {"amx_int8_gmacs", peak(k.amx_int8_gmacs)},
                             {"amx_bf16_gmacs", peak(k.amx_bf16_gmacs)},
                             {"read_gbytes", peak(k.read_gbytes)}}},
              {"macs", r.macs},
              {"main_unit", prof::ComputeUnitName(r.main_unit)},
              {"main_peak_gmacs", peak(r.peaks.Of(r.main_unit))},
              {"main_floor_ms", Nullable(r.main_floor_ms)},
              {"median_over_main_floor", Nullable(median_run_ms / r.main_floor_ms)},
              {"floor_ms", Nullable(r.floor_ms)},
              {"median_over_floor", Nullable(median_run_ms / r.floor_ms)},
              {"steps", steps}};
}

}  // namespace sfrt::tools
