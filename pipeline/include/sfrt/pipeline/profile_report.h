// Reports of a `sfrt run --profile` run (issue #6), written from a FrameProfiler after the
// pipeline has stopped, and `sfrt report compare` of two such runs.
//
// Files (all written to a temporary name and renamed):
//   profile.json        format "sfrt-profile" version 1: run facts, per-stage and end-to-end
//                       p50/p90/p99/max/mean (ms), per-step (layer) statistics, deadline misses,
//                       the profiling overhead (estimated per frame, and the A/B comparison when
//                       one was run)
//   frames.csv          one row per frame: window, frame numbers, CLOCK_MONOTONIC timestamps of
//                       every stage, the stage and end-to-end durations (ms), the miss flag and
//                       the duration of every step (ms)
//   trace.json          Chrome trace event format ({"traceEvents": [...]}, loads in Perfetto and
//                       chrome://tracing): one track (tid) per stage, one complete event per
//                       frame and stage, the steps as events nested inside each infer event,
//                       deadline misses as instant events on the output track
//   latency_hist.png    histogram of end-to-end latency, budget as a vertical line
//   latency_series.png  end-to-end and infer latency per frame, budget as a horizontal line
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "sfrt/pipeline/profiler.h"
#include "sfrt/status.h"

namespace sfrt::pipeline {

// The same input run twice in one process, without and with profiling (medians, ms).
struct OverheadComparison {
  int64_t frames_without = 0;
  int64_t frames_with = 0;
  double e2e_p50_without_ms = 0;
  double e2e_p50_with_ms = 0;
  double infer_p50_without_ms = 0;
  double infer_p50_with_ms = 0;
};

struct ProfileReportInfo {
  std::string dir;  // must exist
  double budget_ms = 0;
  std::string model_path;
  std::string precision;  // e.g. "fp32", "fp16 weights"; "" = not shown
  std::string source;     // one-line description
  std::string stopped_by;
  std::optional<OverheadComparison> ab;
};

struct ProfileReportFiles {
  std::string json, csv, trace, histogram_png, series_png;
};

// Writes the five files into info.dir and, when `table` is not null, the console table
// (per stage and end to end: p50/p90/p99/max; the slowest steps; the overhead). Fails when the
// profiler recorded no frame or a file cannot be written; the message names the file.
Result<ProfileReportFiles> WriteProfileReports(const FrameProfiler& profiler,
                                               const ProfileReportInfo& info, std::string* table);

// The plots' second title line: model file name, ISA, precision, input size (HxW), threads.
std::string ProfilePlotSubtitle(const FrameProfiler& profiler, const ProfileReportInfo& info);

// Where a line's label goes (its full text box, pixels) so that the line never crosses it and it
// stays inside the plot area `plot`: beside a vertical line at x = `line_x` (left of it when it
// fits, else right), at the top of the plot; above a horizontal line at y = `line_y` at the right
// of the plot (below it when there is no room above). The line is `line_width` pixels wide.
cv::Rect LabelBesideVerticalLine(const std::string& text, int line_x, int line_width,
                                 const cv::Rect& plot);
cv::Rect LabelBesideHorizontalLine(const std::string& text, int line_y, int line_width,
                                   const cv::Rect& plot);

// `sfrt report compare A B`: per stage and per step, p50 of A and B and the change in ms and
// percent, sorted by the largest absolute change. Fails (naming the file and what is wrong) on
// a file that is not valid JSON or not an "sfrt-profile" report.
Result<std::string> CompareProfileFiles(const std::string& a_path, const std::string& b_path);

}  // namespace sfrt::pipeline
