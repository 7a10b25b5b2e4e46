#include "sfrt/pipeline/stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>

#include "sfrt/layer_kinds.h"
#include "sfrt/model.h"
#include "sfrt/session.h"

namespace sfrt::profiling {

double PercentileOfSorted(std::span<const double> sorted, double q) {
  if (sorted.empty()) return std::numeric_limits<double>::quiet_NaN();
  q = std::clamp(q, 0.0, 1.0);
  const double pos = q * static_cast<double>(sorted.size() - 1);
  const size_t lo = static_cast<size_t>(pos);
  const size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - static_cast<double>(lo));
}

double Percentile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  return PercentileOfSorted(values, q);
}

double Summary::At(double percent) const {
  if (percent == 0) return min;
  if (percent == 50) return p50;
  if (percent == 90) return p90;
  if (percent == 99) return p99;
  if (percent == 99.9) return p999;
  if (percent == 100) return max;
  return std::numeric_limits<double>::quiet_NaN();
}

Summary Summarize(std::span<const double> values) {
  Summary s;
  if (values.empty()) return s;
  std::vector<double> sorted(values.begin(), values.end());
  std::sort(sorted.begin(), sorted.end());
  RunningStats running;
  for (double v : sorted) running.Add(v);
  s.count = sorted.size();
  s.min = sorted.front();
  s.max = sorted.back();
  s.mean = running.mean();
  s.stddev = running.stddev();
  s.p50 = PercentileOfSorted(sorted, 0.5);
  s.p90 = PercentileOfSorted(sorted, 0.9);
  s.p99 = PercentileOfSorted(sorted, 0.99);
  s.p999 = PercentileOfSorted(sorted, 0.999);
  return s;
}

void RunningStats::Add(double value) {
  ++count_;
  min_ = std::min(min_, value);
  max_ = std::max(max_, value);
  const double delta = value - mean_;
  mean_ += delta / static_cast<double>(count_);
  m2_ += delta * (value - mean_);
}

double RunningStats::variance() const {
  return count_ < 2 ? 0.0 : std::max(m2_ / static_cast<double>(count_), 0.0);
}

double RunningStats::stddev() const { return std::sqrt(variance()); }

std::string FormatFixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

std::string FormatCell(double v, int digits) {
  return std::isfinite(v) ? FormatFixed(v, digits) : "-";
}

bool ParsePercentile(std::string_view text, double* percent) {
  if (text == "max") {
    *percent = 100;
    return true;
  }
  if (text == "median") {
    *percent = 50;
    return true;
  }
  if (!text.empty() && (text.front() == 'p' || text.front() == 'P')) text.remove_prefix(1);
  if (text.empty() || text.size() > 32) return false;
  const std::string s(text);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size() || !(v > 0) || v > 100) return false;
  *percent = v;
  return true;
}

std::string PercentileLabel(double percent) {
  if (percent == 100) return "max";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "p%g", percent);
  return buf;
}

// ---------------------------------------------------------------------------- planned steps

namespace {

std::string Pad(std::string s, size_t width) {
  if (s.size() < width) s.append(width - s.size(), ' ');
  return s;
}

std::string PadLeft(const std::string& s, size_t width) {
  return s.size() < width ? std::string(width - s.size(), ' ') + s : s;
}

}  // namespace

std::vector<StepLabel> LabelSteps(const Session& session) {
  const auto layers = session.model().layers();
  std::vector<StepLabel> labels;
  for (const PlannedStep& step : session.steps()) {
    StepLabel label;
    label.first_layer = step.first_layer;
    label.last_layer = step.last_layer;
    label.kernel = step.kernel;
    label.precision = PrecisionName(step.precision);
    if (step.quantize) {
      // Computes no layer: it converts the float32 tensor the next (int8 or bf16) layer reads.
      const size_t next = static_cast<size_t>(step.first_layer);
      label.name = "quantize>" + (next < layers.size() ? layers[next].name : std::string("?"));
      label.op = step.precision == Precision::kBFloat16 ? "round to bf16" : "quantize uint8";
      labels.push_back(std::move(label));
      continue;
    }
    for (int i = step.first_layer; i <= step.last_layer; ++i) {
      if (i < 0 || static_cast<size_t>(i) >= layers.size()) continue;
      if (!label.name.empty()) {
        label.name += "+";
        label.op += " + ";
      }
      label.name += layers[static_cast<size_t>(i)].name;
      label.op += DescribeLayer(layers[static_cast<size_t>(i)], LayerText::kBrief);
    }
    if (step.last_layer > step.first_layer) label.op += " (fused)";
    if (step.precision != Precision::kFloat32) label.op = label.precision + " " + label.op;
    labels.push_back(std::move(label));
  }
  return labels;
}

StepRecorder::StepRecorder(size_t steps, size_t capacity) : steps_(steps) {
  ms_.resize(steps * std::max<size_t>(capacity, 1));
}

bool StepRecorder::Add(std::span<const int64_t> step_end_ns) {
  if (step_end_ns.size() != steps_ + 1) return false;
  if ((runs_ + 1) * steps_ > ms_.size()) ms_.resize(std::max(ms_.size() * 2, steps_));
  double* row = ms_.data() + runs_ * steps_;
  for (size_t s = 0; s < steps_; ++s) {
    row[s] = static_cast<double>(step_end_ns[s + 1] - step_end_ns[s]) * 1e-6;
  }
  ++runs_;
  return true;
}

double StepRecorder::total_ms(size_t run) const {
  double total = 0;
  for (size_t s = 0; s < steps_; ++s) total += ms_[run * steps_ + s];
  return total;
}

std::vector<StepRow> StepTable(std::span<const StepLabel> labels,
                               std::span<const double> durations_ms) {
  const size_t steps = labels.size();
  if (steps == 0 || durations_ms.empty() || durations_ms.size() % steps != 0) return {};
  const size_t runs = durations_ms.size() / steps;
  std::vector<StepRow> rows(steps);
  std::vector<double> column(runs);
  double total_mean = 0;
  for (size_t s = 0; s < steps; ++s) {
    for (size_t r = 0; r < runs; ++r) column[r] = durations_ms[r * steps + s];
    rows[s].step = s;
    rows[s].label = labels[s];
    rows[s].ms = Summarize(column);
    total_mean += rows[s].ms.mean;
  }
  for (StepRow& row : rows) row.share = total_mean > 0 ? row.ms.mean / total_mean : 0.0;
  return rows;
}

std::vector<StepRow> TopSteps(std::span<const StepRow> rows, size_t n) {
  std::vector<StepRow> top(rows.begin(), rows.end());
  std::stable_sort(top.begin(), top.end(),
                   [](const StepRow& a, const StepRow& b) { return a.ms.p50 > b.ms.p50; });
  if (top.size() > n) top.resize(n);
  return top;
}

std::vector<OpRow> ByOp(std::span<const StepRow> rows) {
  std::vector<OpRow> ops;
  std::map<std::string, size_t> index;
  double total = 0;
  for (const StepRow& row : rows) {
    auto [it, added] = index.emplace(row.label.op, ops.size());
    if (added) ops.push_back(OpRow{row.label.op});
    OpRow& op = ops[it->second];
    ++op.steps;
    op.median_ms += row.ms.p50;
    op.mean_ms += row.ms.mean;
    total += row.ms.mean;
  }
  for (OpRow& op : ops) op.share = total > 0 ? op.mean_ms / total : 0.0;
  std::stable_sort(ops.begin(), ops.end(),
                   [](const OpRow& a, const OpRow& b) { return a.mean_ms > b.mean_ms; });
  return ops;
}

std::string FormatStepTable(std::span<const StepRow> rows) {
  size_t name_w = 6, op_w = 2, kernel_w = 6;
  for (const StepRow& r : rows) {
    name_w = std::max(name_w, r.label.name.size());
    op_w = std::max(op_w, r.label.op.size());
    kernel_w = std::max(kernel_w, r.label.kernel.size());
  }
  std::string out = PadLeft("step", 4) + "  " + Pad("layers", name_w) + "  " + Pad("op", op_w) +
                    "  " + Pad("kernel", kernel_w) + "  " + PadLeft("median ms", 10) +
                    PadLeft("p99 ms", 10) + PadLeft("max ms", 10) + PadLeft("share", 8) + "\n";
  for (const StepRow& r : rows) {
    out += PadLeft(std::to_string(r.step), 4) + "  " + Pad(r.label.name, name_w) + "  " +
           Pad(r.label.op, op_w) + "  " + Pad(r.label.kernel, kernel_w) + "  " +
           PadLeft(FormatFixed(r.ms.p50, 3), 10) + PadLeft(FormatFixed(r.ms.p99, 3), 10) +
           PadLeft(FormatFixed(r.ms.max, 3), 10) +
           PadLeft(FormatFixed(100.0 * r.share, 1) + "%", 8) + "\n";
  }
  return out;
}

std::string FormatOpTable(std::span<const OpRow> rows) {
  size_t op_w = 7;
  for (const OpRow& r : rows) op_w = std::max(op_w, r.op.size());
  std::string out = Pad("op type", op_w) + PadLeft("steps", 7) + PadLeft("median ms", 11) +
                    PadLeft("mean ms", 10) + PadLeft("share", 8) + "\n";
  for (const OpRow& r : rows) {
    out += Pad(r.op, op_w) + PadLeft(std::to_string(r.steps), 7) +
           PadLeft(FormatFixed(r.median_ms, 3), 11) + PadLeft(FormatFixed(r.mean_ms, 3), 10) +
           PadLeft(FormatFixed(100.0 * r.share, 1) + "%", 8) + "\n";
  }
  return out;
}

std::string FormatStepComparison(std::span<const std::vector<StepRow>> configs) {
  // The step names in order: the first configuration's, then any only a later one has.
  std::vector<std::string> names;
  for (const std::vector<StepRow>& rows : configs) {
    for (const StepRow& r : rows) {
      if (std::find(names.begin(), names.end(), r.label.name) == names.end()) {
        names.push_back(r.label.name);
      }
    }
  }
  auto median = [](const std::vector<StepRow>& rows, const std::string& name) {
    for (const StepRow& r : rows) {
      if (r.label.name == name) return r.ms.p50;
    }
    return std::nan("");
  };
  size_t name_w = 6;
  for (const std::string& n : names) name_w = std::max(name_w, n.size());
  std::string out = Pad("layers", name_w);
  for (size_t c = 0; c < configs.size(); ++c) {
    const std::string tag = "[" + std::to_string(c + 1) + "]";
    out += PadLeft(tag + " ms", 12);
    if (c > 0) out += PadLeft(tag + "/[1]", 10);
  }
  out += "\n";
  for (const std::string& n : names) {
    out += Pad(n, name_w);
    const double first = configs.empty() ? std::nan("") : median(configs[0], n);
    for (size_t c = 0; c < configs.size(); ++c) {
      const double ms = median(configs[c], n);
      out += PadLeft(FormatCell(ms, 3), 12);
      if (c > 0) out += PadLeft(FormatCell(ms / first, 3), 10);
    }
    out += "\n";
  }
  return out;
}

}  // namespace sfrt::profiling
