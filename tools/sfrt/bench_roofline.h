// `sfrt bench`'s roofline: each configuration's steps placed against the peaks measured in the
// same process (profiling/roofline.h), as a table and as JSON.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "profiling/roofline.h"
#include "sfrt/pipeline/stats.h"
#include "sfrt/session.h"

namespace sfrt::tools {

// Places `session`'s steps at height x width, their medians from `rows` (StepTable), against
// the peaks at the session's thread count: `fma_gflops` (measured for its ISA) and what `cache`
// measures for the units its kernels use; `quantized_input`: the runs were RunQuantized's.
Result<profiling::Roofline> PlaceSessionSteps(const Session& session,
                                              const std::vector<profiling::StepRow>& rows,
                                              int height, int width, bool quantized_input,
                                              double fma_gflops, profiling::PeakCache* cache);

// The table: a row per step in run order (unit, GMAC, MB moved, MACs per byte, median ms, the
// achieved rate, the roof, the share of it, which roof binds), then the floors against
// `median_run_ms`.
std::string FormatRoofline(const std::vector<profiling::StepRow>& rows,
                           const profiling::Roofline& roofline, double median_run_ms);

// The same for --json: peaks, the main unit and its peak, floors, and per step (index-aligned with
// "steps") the work and its point. Unmeasured rates are null.
nlohmann::ordered_json RooflineJson(const profiling::Roofline& roofline, double median_run_ms);

}  // namespace sfrt::tools
