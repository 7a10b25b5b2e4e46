// Latency statistics and per-layer (per planned step) aggregation, shared by `sfrt bench` and
// `sfrt run --profile`.
//
// Percentiles interpolate linearly between the closest ranks (NumPy's default, Hyndman & Fan
// type 7): the q-quantile of n sorted values is at position q * (n - 1). With few samples the
// high percentiles are therefore interpolations towards the maximum (p99.9 of 20 runs lies
// between the two slowest), never values that were not bracketed by a measurement.
// Standard deviations are population ones (divide by n), as numpy.std.
//
// Nothing here reads a clock: callers measure, this library summarises. Only the functions that
// build tables allocate; RunningStats and StepRecorder::Add (within its capacity) do not.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace sfrt {
class Session;
}  // namespace sfrt

namespace sfrt::profiling {

// The q-quantile (q in [0, 1], clamped) of `sorted`, which must be in ascending order.
// NaN when `sorted` is empty.
double PercentileOfSorted(std::span<const double> sorted, double q);
// The same for values in any order (sorts a copy).
double Percentile(std::vector<double> values, double q);

// The latest `capacity` values of one series, in memory allocated and touched once (at
// construction), so a run of any length keeps a constant resident size; Add() never allocates.
// Percentiles of a long run describe its latest values (all of them up to `capacity`).
class LatestValues {
 public:
  static constexpr size_t kDefaultCapacity = size_t{1} << 16;
  explicit LatestValues(size_t capacity = kDefaultCapacity) : values_(capacity, -1.0) {}
  void Add(double v) { values_[added_++ % values_.size()] = v; }
  std::vector<double> Values() const {
    return {values_.begin(),
            values_.begin() + static_cast<std::ptrdiff_t>(std::min(added_, values_.size()))};
  }

 private:
  std::vector<double> values_;
  size_t added_ = 0;
};

// Summary of one series (milliseconds, by convention). All zero when count == 0.
struct Summary {
  size_t count = 0;
  double min = 0;
  double max = 0;
  double mean = 0;
  double stddev = 0;  // population
  double p50 = 0;
  double p90 = 0;
  double p99 = 0;
  double p999 = 0;
  // The value at `percent` (0..100, e.g. 99.9): one of the fields above when it matches
  // (50, 90, 99, 99.9, 100 = max, 0 = min), otherwise NaN (use Percentile for others).
  double At(double percent) const;
};
Summary Summarize(std::span<const double> values);

// Count, min, max, mean and standard deviation of a stream without storing it (Welford's
// update, numerically stable). No allocation.
class RunningStats {
 public:
  void Add(double value);
  size_t count() const { return count_; }
  double min() const { return min_; }    // +inf when empty
  double max() const { return max_; }    // -inf when empty
  double mean() const { return mean_; }  // 0 when empty
  double variance() const;               // population; 0 when fewer than 2 values
  double stddev() const;

 private:
  size_t count_ = 0;
  double min_ = std::numeric_limits<double>::infinity();
  double max_ = -std::numeric_limits<double>::infinity();
  double mean_ = 0;
  double m2_ = 0;
};

// `v` with `digits` decimals, as printf's %.*f: FormatFixed(3.14159, 2) == "3.14".
std::string FormatFixed(double v, int digits);
// As FormatFixed, and "-" for a value that is not finite (a rate nothing measured): tables' cells.
std::string FormatCell(double v, int digits);

// Parses a percentile as a user writes it: "p99", "p99.9", "99", "p50", "median", "max"
// (= 100). Writes percent in (0, 100]; false for anything else.
bool ParsePercentile(std::string_view text, double* percent);
// The label for a percent: 50 -> "p50", 99.9 -> "p99.9", 100 -> "max".
std::string PercentileLabel(double percent);

// ---------------------------------------------------------------------------- planned steps
// What one planned step of a Session computes, for tables.
struct StepLabel {
  int first_layer = 0;  // the model layers the step covers, [first_layer, last_layer]
  int last_layer = 0;
  std::string name;       // layer names joined with '+': "conv3", "up_1+conv_up1" (fused)
  std::string op;         // op type, for aggregation: "conv 3x3/s2", "upsample x2 + conv 3x3/s1
                          // (fused)", "crop", "upsample x2"
  std::string kernel;     // PlannedStep::kernel, e.g. "conv2d_f32__avx512_8x32"
  std::string precision;  // "fp32" or "int8" (PlannedStep::precision)
};
// One label per session.steps() entry, in run order.
std::vector<StepLabel> LabelSteps(const Session& session);

// Step durations of many runs: a runs x steps matrix of milliseconds, allocated once for
// `capacity` runs. Add() converts Session::Run's step_end_ns (steps + 1 timestamps) into
// durations; beyond the capacity it grows the matrix (allocating), so size it for the runs
// expected.
class StepRecorder {
 public:
  StepRecorder(size_t steps, size_t capacity);
  // False (nothing recorded) when step_end_ns does not hold steps() + 1 values.
  bool Add(std::span<const int64_t> step_end_ns);
  size_t steps() const { return steps_; }
  size_t runs() const { return runs_; }
  // Row-major runs() x steps() durations: run r, step s at [r * steps() + s].
  std::span<const double> durations_ms() const { return {ms_.data(), runs_ * steps_}; }
  // Sum of run r's step durations (its first to last timestamp).
  double total_ms(size_t run) const;

 private:
  size_t steps_ = 0;
  size_t runs_ = 0;
  std::vector<double> ms_;
};

// One row of the per-step table.
struct StepRow {
  size_t step = 0;  // index in run order
  StepLabel label;
  Summary ms;        // this step's duration over the runs
  double share = 0;  // ms.mean / the sum of every step's ms.mean (0..1): shares sum to 1
};
// Rows in run order. durations_ms: runs x steps as StepRecorder::durations_ms(), with
// steps == labels.size(). Empty when the sizes do not fit.
std::vector<StepRow> StepTable(std::span<const StepLabel> labels,
                               std::span<const double> durations_ms);
// The n rows with the largest median (ties: earlier step first), slowest first.
std::vector<StepRow> TopSteps(std::span<const StepRow> rows, size_t n);

// Steps aggregated by StepLabel::op.
struct OpRow {
  std::string op;
  size_t steps = 0;      // how many steps have this op
  double median_ms = 0;  // sum of those steps' medians
  double mean_ms = 0;    // sum of those steps' means
  double share = 0;      // mean_ms / the sum over all steps (0..1)
};
// Slowest (by mean) first.
std::vector<OpRow> ByOp(std::span<const StepRow> rows);

// Fixed-width text tables (one line per row, a header line first, '\n'-terminated).
// StepRow table: step, layers, op, kernel, median/p99/max ms, share.
std::string FormatStepTable(std::span<const StepRow> rows);
std::string FormatOpTable(std::span<const OpRow> rows);
// Several configurations' steps side by side (configs[0] the first, "[1]"): a row per step of
// the first, in its run order, then per step only a later configuration has, matched by
// StepLabel::name; per configuration its median ("-" where it has no such step) and, after the
// first, that median / the first's ("-" where either lacks the step).
std::string FormatStepComparison(std::span<const std::vector<StepRow>> configs);

}  // namespace sfrt::profiling
