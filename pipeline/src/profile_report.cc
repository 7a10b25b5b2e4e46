#include "sfrt/pipeline/profile_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "sfrt/pipeline/io/atomic_write.h"

namespace sfrt::pipeline {
namespace {

using nlohmann::json;

constexpr const char* kFormat = "sfrt-profile";
constexpr int kFormatVersion = 1;

using profiling::FormatFixed;

std::string Pad(std::string s, size_t width, bool right = false) {
  if (s.size() >= width) return s;
  return right ? std::string(width - s.size(), ' ') + s : s + std::string(width - s.size(), ' ');
}

double Ms(int64_t ns) { return static_cast<double>(ns) / 1e6; }

using profiling::Summary;

json StatsJson(const Summary& s) {
  return json{{"p50", s.p50},    {"p90", s.p90},       {"p99", s.p99},
              {"p99.9", s.p999}, {"max", s.max},       {"min", s.min},
              {"mean", s.mean},  {"stddev", s.stddev}, {"count", s.count}};
}

Status WriteText(const std::string& path, const std::string& text) {
  return io::WriteFileAtomically(
      path, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
}

Status WritePng(const std::string& path, const cv::Mat& image) {
  std::vector<uint8_t> png;
  if (!cv::imencode(".png", image, png)) {
    return Status::Error("cannot encode the plot '" + path + "' as PNG");
  }
  return io::WriteFileAtomically(path, png);
}

// Per-frame durations pulled out of the ring once.
struct Series {
  std::vector<double> stage[kProfileStages];
  std::vector<double> e2e;
  std::vector<double> step_ms;  // frames with steps x steps, row-major (profiling::StepTable)
  int64_t misses = 0;
  int64_t at_other_size = 0;  // frames that ran at a size other than the planned one
};

Series Collect(const FrameProfiler& prof) {
  Series s;
  for (size_t i = 0; i < prof.size(); ++i) {
    const ProfiledFrame& f = prof.frame(i);
    for (int st = 0; st < kProfileStages; ++st) {
      s.stage[st].push_back(Ms(f.stage_ns[st][1] - f.stage_ns[st][0]));
    }
    s.e2e.push_back(Ms(f.end_ns(config::Stage::kOutput) - f.capture_ns));
    if (f.miss) ++s.misses;
    if (f.input_height > 0 && (f.input_height != prof.height() || f.input_width != prof.width())) {
      ++s.at_other_size;
    }
    if (f.has_steps) {
      std::span<const int64_t> t = prof.step_end_ns(i);
      for (size_t k = 0; k + 1 < t.size(); ++k) s.step_ms.push_back(Ms(t[k + 1] - t[k]));
    }
  }
  return s;
}

// ---- plots (OpenCV drawing)

constexpr int kPlotW = 900, kPlotH = 500;
constexpr int kLeft = 80, kRight = 30, kTop = 70, kBottom = 60;
constexpr double kLabelScale = 0.5;
constexpr int kLabelGap = 6;  // between a line and its label

// "Nice" tick step for a range: 1, 2 or 5 times a power of ten, about `count` ticks.
double TickStep(double range, int count) {
  if (!(range > 0)) return 1;
  const double raw = range / count;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double norm = raw / mag;
  return (norm < 1.5 ? 1 : norm < 3.5 ? 2 : norm < 7.5 ? 5 : 10) * mag;
}

std::string TickLabel(double v, double step) {
  const int digits = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step)));
  return FormatFixed(v, std::min(digits, 4));
}

void Text(cv::Mat* img, const std::string& s, cv::Point at, double scale = 0.5,
          cv::Scalar color = cv::Scalar(40, 40, 40)) {
  cv::putText(*img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, color, 1, cv::LINE_AA);
}

// Axes with ticks over [x0, x1] x [y0, y1]; returns the pixel mapping.
struct Axes {
  double x0, x1, y0, y1;
  bool integer_x = false;  // counts (frames): no fractional ticks
  bool integer_y = false;
  int X(double x) const {
    return kLeft + static_cast<int>(std::lround((x - x0) / (x1 - x0) * (kPlotW - kLeft - kRight)));
  }
  int Y(double y) const {
    return kPlotH - kBottom -
           static_cast<int>(std::lround((y - y0) / (y1 - y0) * (kPlotH - kTop - kBottom)));
  }
};

void DrawAxes(cv::Mat* img, const Axes& a, const std::string& title, const std::string& subtitle,
              const std::string& xlabel, const std::string& ylabel) {
  const cv::Scalar grid(225, 225, 225), axis(60, 60, 60);
  double xs = TickStep(a.x1 - a.x0, 8), ys = TickStep(a.y1 - a.y0, 6);
  if (a.integer_x) xs = std::max(xs, 1.0);
  if (a.integer_y) ys = std::max(ys, 1.0);
  for (double x = std::ceil(a.x0 / xs) * xs; x <= a.x1 + 1e-9 * xs; x += xs) {
    cv::line(*img, {a.X(x), kTop}, {a.X(x), kPlotH - kBottom}, grid);
    Text(img, TickLabel(x, xs), {a.X(x) - 12, kPlotH - kBottom + 20}, 0.42);
  }
  for (double y = std::ceil(a.y0 / ys) * ys; y <= a.y1 + 1e-9 * ys; y += ys) {
    cv::line(*img, {kLeft, a.Y(y)}, {kPlotW - kRight, a.Y(y)}, grid);
    Text(img, TickLabel(y, ys), {8, a.Y(y) + 5}, 0.42);
  }
  cv::rectangle(*img, {kLeft, kTop}, {kPlotW - kRight, kPlotH - kBottom}, axis, 1);
  Text(img, title, {kLeft, 24}, 0.6);
  Text(img, subtitle, {kLeft, 48}, 0.45);
  Text(img, xlabel, {kPlotW / 2 - 80, kPlotH - 15});
  Text(img, ylabel, {8, kTop - 12});
}

cv::Rect PlotArea() { return {kLeft, kTop, kPlotW - kRight - kLeft, kPlotH - kBottom - kTop}; }

// Draws `text` in `box` (as LabelBeside* computed it).
void DrawLabel(cv::Mat* img, const std::string& text, const cv::Rect& box, cv::Scalar color) {
  int descent = 0;
  const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, kLabelScale, 1, &descent);
  Text(img, text, {box.x, box.y + size.height}, kLabelScale, color);
}

cv::Mat HistogramPlot(const std::vector<double>& e2e, double budget_ms,
                      const std::string& subtitle) {
  cv::Mat img(kPlotH, kPlotW, CV_8UC3, cv::Scalar(255, 255, 255));
  const profiling::Summary p = profiling::Summarize(e2e);
  double lo = *std::min_element(e2e.begin(), e2e.end());
  double hi = p.max;
  if (budget_ms > 0 && budget_ms <= 2 * hi) hi = std::max(hi, budget_ms);
  if (hi - lo < 1e-3) {
    lo -= 0.5;
    hi += 0.5;
  }
  const double pad = 0.04 * (hi - lo);
  lo = std::max(0.0, lo - pad);
  hi += pad;
  constexpr int kBins = 40;
  std::vector<int> count(kBins, 0);
  for (double v : e2e) {
    int b = static_cast<int>((v - lo) / (hi - lo) * kBins);
    count[std::clamp(b, 0, kBins - 1)]++;
  }
  const int top = *std::max_element(count.begin(), count.end());
  const Axes a{lo, hi, 0, top * 1.1 + 1, false, true};
  DrawAxes(&img, a,
           "end-to-end latency, " + std::to_string(e2e.size()) + " frames: p50 " +
               FormatFixed(p.p50, 2) + " ms, p99 " + FormatFixed(p.p99, 2) + " ms, max " +
               FormatFixed(p.max, 2) + " ms",
           subtitle, "end-to-end latency (ms)", "frames");
  for (int b = 0; b < kBins; ++b) {
    if (count[b] == 0) continue;
    const double b0 = lo + (hi - lo) * b / kBins, b1 = lo + (hi - lo) * (b + 1) / kBins;
    cv::rectangle(img, {a.X(b0) + 1, a.Y(count[b])}, {a.X(b1) - 1, a.Y(0)},
                  cv::Scalar(200, 120, 40), cv::FILLED);
  }
  if (budget_ms > 0) {
    if (budget_ms <= hi) {
      cv::line(img, {a.X(budget_ms), kTop}, {a.X(budget_ms), kPlotH - kBottom},
               cv::Scalar(30, 30, 220), 2);
      const std::string label = "budget " + FormatFixed(budget_ms, 1) + " ms";
      DrawLabel(&img, label, LabelBesideVerticalLine(label, a.X(budget_ms), 2, PlotArea()),
                cv::Scalar(30, 30, 220));
    } else {
      Text(&img, "budget " + FormatFixed(budget_ms, 1) + " ms (beyond the axis)",
           {kPlotW - kRight - 300, kTop + 18}, 0.5, cv::Scalar(30, 30, 220));
    }
  }
  return img;
}

cv::Mat SeriesPlot(const std::vector<double>& e2e, const std::vector<double>& infer,
                   double budget_ms, const std::string& subtitle) {
  cv::Mat img(kPlotH, kPlotW, CV_8UC3, cv::Scalar(255, 255, 255));
  double hi = *std::max_element(e2e.begin(), e2e.end());
  if (budget_ms > 0 && budget_ms <= 2 * hi) hi = std::max(hi, budget_ms);
  hi = hi > 0 ? hi * 1.1 : 1;
  const double n = static_cast<double>(std::max<size_t>(e2e.size(), 2) - 1);
  const Axes a{0, n, 0, hi, true, false};
  DrawAxes(&img, a, "latency per frame (blue: end to end, orange: infer, red: budget)", subtitle,
           "frame", "ms");
  auto draw = [&](const std::vector<double>& v, cv::Scalar color) {
    std::vector<cv::Point> pts;
    for (size_t i = 0; i < v.size(); ++i) pts.emplace_back(a.X(static_cast<double>(i)), a.Y(v[i]));
    if (pts.size() == 1) pts.push_back(pts[0]);
    cv::polylines(img, pts, false, color, 1, cv::LINE_AA);
    if (v.size() <= 200) {
      for (const cv::Point& q : pts) cv::circle(img, q, 2, color, cv::FILLED, cv::LINE_AA);
    }
  };
  draw(infer, cv::Scalar(0, 140, 255));
  draw(e2e, cv::Scalar(200, 90, 20));
  if (budget_ms > 0) {
    if (budget_ms <= hi) {
      cv::line(img, {kLeft, a.Y(budget_ms)}, {kPlotW - kRight, a.Y(budget_ms)},
               cv::Scalar(30, 30, 220), 2);
      const std::string label = "budget " + FormatFixed(budget_ms, 1) + " ms";
      DrawLabel(&img, label, LabelBesideHorizontalLine(label, a.Y(budget_ms), 2, PlotArea()),
                cv::Scalar(30, 30, 220));
    } else {
      Text(&img, "budget " + FormatFixed(budget_ms, 1) + " ms (above the axis)",
           {kPlotW - kRight - 300, kTop + 18}, 0.5, cv::Scalar(30, 30, 220));
    }
  }
  return img;
}

// ---- trace

// The trace's track (thread id) of a stage: 1 for the source, then in stage order.
int TrackOf(config::Stage stage) { return config::StageIndex(stage) + 1; }

json TraceEvent(const char* ph, const std::string& name, int tid, double ts_us) {
  return json{{"ph", ph}, {"name", name}, {"pid", 1}, {"tid", tid}, {"ts", ts_us}};
}

std::string TraceJson(const FrameProfiler& prof, const ProfileReportInfo& info) {
  int64_t origin = INT64_MAX;
  for (size_t i = 0; i < prof.size(); ++i) {
    const ProfiledFrame& f = prof.frame(i);
    origin = std::min({origin, f.capture_ns, f.start_ns(config::Stage::kSource)});
  }
  auto us = [&](int64_t ns) { return std::round(static_cast<double>(ns - origin) / 10.0) / 100.0; };
  json events = json::array();
  events.push_back(
      json{{"ph", "M"}, {"name", "process_name"}, {"pid", 1}, {"args", {{"name", "sfrt run"}}}});
  for (int st = 0; st < kProfileStages; ++st) {
    events.push_back(json{{"ph", "M"},
                          {"name", "thread_name"},
                          {"pid", 1},
                          {"tid", TrackOf(static_cast<config::Stage>(st))},
                          {"args", {{"name", kStageNames[st]}}}});
    events.push_back(json{{"ph", "M"},
                          {"name", "thread_sort_index"},
                          {"pid", 1},
                          {"tid", TrackOf(static_cast<config::Stage>(st))},
                          {"args", {{"sort_index", st}}}});
  }
  for (size_t i = 0; i < prof.size(); ++i) {
    const ProfiledFrame& f = prof.frame(i);
    const std::string frame = "frame " + std::to_string(f.window);
    for (int st = 0; st < kProfileStages; ++st) {
      json e =
          TraceEvent("X", frame, TrackOf(static_cast<config::Stage>(st)), us(f.stage_ns[st][0]));
      e["cat"] = kStageNames[st];
      e["dur"] = us(f.stage_ns[st][1]) - us(f.stage_ns[st][0]);
      e["args"] = {{"window", f.window},
                   {"frame0", f.frame0},
                   {"frame1", f.frame1},
                   {"input_size", {f.input_height, f.input_width}}};
      if (st == config::StageIndex(config::Stage::kOutput))
        e["args"]["end_to_end_ms"] = Ms(f.end_ns(config::Stage::kOutput) - f.capture_ns);
      events.push_back(std::move(e));
    }
    if (f.has_steps) {
      std::span<const int64_t> t = prof.step_end_ns(i);
      for (size_t k = 0; k + 1 < t.size(); ++k) {
        const ProfileStep& s = prof.steps()[k];
        json e = TraceEvent("X", s.name, TrackOf(config::Stage::kInfer), us(t[k]));
        e["cat"] = "layer";
        e["dur"] = us(t[k + 1]) - us(t[k]);
        e["args"] = {
            {"kernel", s.kernel}, {"layers", {s.first_layer, s.last_layer}}, {"window", f.window}};
        events.push_back(std::move(e));
      }
    }
    if (f.miss) {
      json e = TraceEvent("i", "deadline miss", TrackOf(config::Stage::kOutput),
                          us(f.end_ns(config::Stage::kOutput)));
      e["s"] = "t";
      e["args"] = {{"window", f.window}, {"budget_ms", info.budget_ms}};
      events.push_back(std::move(e));
    }
  }
  json trace{{"traceEvents", events},
             {"displayTimeUnit", "ms"},
             {"otherData",
              {{"clock", "CLOCK_MONOTONIC"},
               {"origin_ns", origin},
               {"model", info.model_path},
               {"source", info.source}}}};
  return trace.dump() + "\n";
}

Result<json> ReadProfileJson(const std::string& path) {
  Result<std::string> text = io::ReadWholeFile(path);
  if (!text.ok()) return text.status();
  json j = json::parse(*text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return Status::Error("'" + path + "' is not valid JSON");
  if (!j.is_object() || !j.contains("format") || j["format"] != kFormat) {
    return Status::Error("'" + path +
                         "' is not a profile report (no \"format\": \"sfrt-profile\"; "
                         "`sfrt run --profile DIR` writes DIR/profile.json)");
  }
  if (!j.contains("version") || !j["version"].is_number_integer() ||
      j["version"].get<int>() != kFormatVersion) {
    return Status::Error("'" + path + "': profile report version " +
                         (j.contains("version") ? j["version"].dump() : std::string("(missing)")) +
                         " is not supported (this build reads " + std::to_string(kFormatVersion) +
                         ")");
  }
  auto bad_section = [&](const char* key) {
    return Status::Error("'" + path + "': profile report field '" + key +
                         "' is missing or malformed");
  };
  if (!j.contains("stages") || !j["stages"].is_object()) return bad_section("stages");
  for (auto& [name, s] : j["stages"].items()) {
    if (!s.is_object() || !s.contains("p50") || !s["p50"].is_number()) {
      return bad_section(("stages." + name + ".p50").c_str());
    }
  }
  if (!j.contains("steps") || !j["steps"].is_array()) return bad_section("steps");
  for (const json& s : j["steps"]) {
    if (!s.is_object() || !s.contains("name") || !s["name"].is_string() || !s.contains("p50") ||
        !s["p50"].is_number()) {
      return bad_section("steps[].name/p50");
    }
  }
  return j;
}

}  // namespace

std::string ProfilePlotSubtitle(const FrameProfiler& profiler, const ProfileReportInfo& info) {
  std::string model = std::filesystem::path(info.model_path).filename().string();
  std::string text =
      "model " + (model.empty() ? std::string("?") : model) + ", ISA " + profiler.isa();
  if (!info.precision.empty()) text += ", " + info.precision;
  return text + ", " + std::to_string(profiler.height()) + "x" + std::to_string(profiler.width()) +
         " (HxW), " + std::to_string(profiler.threads()) +
         (profiler.threads() == 1 ? " thread" : " threads");
}

cv::Rect LabelBesideVerticalLine(const std::string& text, int line_x, int line_width,
                                 const cv::Rect& plot) {
  int descent = 0;
  const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, kLabelScale, 1, &descent);
  const int w = size.width + 1, h = size.height + descent + 1;
  const int half = (line_width + 1) / 2;
  int x = line_x - half - kLabelGap - w;                                 // left of the line
  if (x < plot.x + 2) x = line_x + half + kLabelGap;                     // else right of it
  if (x + w > plot.x + plot.width - 2) x = plot.x + plot.width - 2 - w;  // (never: too narrow)
  return {x, plot.y + 8, w, h};
}

cv::Rect LabelBesideHorizontalLine(const std::string& text, int line_y, int line_width,
                                   const cv::Rect& plot) {
  int descent = 0;
  const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, kLabelScale, 1, &descent);
  const int w = size.width + 1, h = size.height + descent + 1;
  const int half = (line_width + 1) / 2;
  int y = line_y - half - kLabelGap - h;              // above the line
  if (y < plot.y + 2) y = line_y + half + kLabelGap;  // else below it
  return {plot.x + plot.width - 8 - w, y, w, h};
}

// The profiling overhead: the clock reads and recording per frame, estimated and, with an A/B
// comparison, measured.
json OverheadJson(const FrameProfiler& prof, const ProfileReportInfo& info, const Summary& e2e) {
  json overhead;
  overhead["clock_read_ns"] = prof.clock_read_ns();
  overhead["record_ns_mean"] = prof.record_ns_mean();
  overhead["record_ns_max"] = prof.record_ns_max();
  overhead["estimated_ns_per_frame"] = prof.overhead_ns_per_frame();
  overhead["estimated_percent_of_e2e_p50"] =
      e2e.p50 > 0 ? prof.overhead_ns_per_frame() / 1e6 / e2e.p50 * 100 : 0.0;
  if (info.ab) {
    const OverheadComparison& ab = *info.ab;
    auto pct = [](double with, double without) {
      return without > 0 ? (with - without) / without * 100 : 0.0;
    };
    overhead["ab"] = {
        {"frames_without", ab.frames_without},
        {"frames_with", ab.frames_with},
        {"e2e_p50_without_ms", ab.e2e_p50_without_ms},
        {"e2e_p50_with_ms", ab.e2e_p50_with_ms},
        {"e2e_p50_change_ms", ab.e2e_p50_with_ms - ab.e2e_p50_without_ms},
        {"e2e_p50_change_percent", pct(ab.e2e_p50_with_ms, ab.e2e_p50_without_ms)},
        {"infer_p50_without_ms", ab.infer_p50_without_ms},
        {"infer_p50_with_ms", ab.infer_p50_with_ms},
        {"infer_p50_change_ms", ab.infer_p50_with_ms - ab.infer_p50_without_ms},
        {"infer_p50_change_percent", pct(ab.infer_p50_with_ms, ab.infer_p50_without_ms)}};
  } else {
    overhead["ab"] = nullptr;
  }
  return overhead;
}

// profile.json: the run, its frames, each stage's and step's statistics, the overhead.
json ProfileJson(const FrameProfiler& prof, const ProfileReportInfo& info, const Series& s,
                 const Summary (&stage_stats)[kProfileStages], const Summary& e2e,
                 const std::vector<profiling::StepRow>& step_rows) {
  json j;
  j["format"] = kFormat;
  j["version"] = kFormatVersion;
  j["clock"] = "CLOCK_MONOTONIC";
  j["model"] = info.model_path;
  j["source"] = info.source;
  j["stopped_by"] = info.stopped_by;
  j["input_size"] = {prof.height(), prof.width()};
  j["isa"] = prof.isa();
  j["threads"] = prof.threads();
  j["frames"] = {{"recorded", prof.recorded()},
                 {"retained", prof.size()},
                 {"overwritten", prof.overwritten()},
                 {"capacity", prof.capacity()}};
  j["deadline"] = {{"budget_ms", info.budget_ms > 0 ? json(info.budget_ms) : json(nullptr)},
                   {"misses", s.misses},
                   {"frames_at_fallback_size", s.at_other_size}};
  json stages;
  for (int st = 0; st < kProfileStages; ++st) {
    stages[kStageNames[st]] = StatsJson(stage_stats[st]);
  }
  stages["end_to_end"] = StatsJson(e2e);
  j["stages"] = stages;
  json steps = json::array();
  for (const profiling::StepRow& r : step_rows) {
    json e = StatsJson(r.ms);
    e["index"] = r.step;
    e["name"] = r.label.name;
    e["op"] = r.label.op;
    e["kernel"] = r.label.kernel;
    e["layers"] = {r.label.first_layer, r.label.last_layer};
    e["share"] = r.share;
    steps.push_back(std::move(e));
  }
  j["steps"] = steps;
  json by_op = json::array();
  for (const profiling::OpRow& r : profiling::ByOp(step_rows)) {
    by_op.push_back(json{{"op", r.op},
                         {"steps", r.steps},
                         {"median_ms", r.median_ms},
                         {"mean_ms", r.mean_ms},
                         {"share", r.share}});
  }
  j["by_op"] = by_op;
  j["overhead"] = OverheadJson(prof, info, e2e);
  j["files"] = {{"csv", "frames.csv"},
                {"trace", "trace.json"},
                {"histogram", "latency_hist.png"},
                {"series", "latency_series.png"}};
  return j;
}

// frames.csv: one row per retained frame with its stage stamps and times and its step times.
std::string FramesCsv(const FrameProfiler& prof) {
  std::string csv = "window,frame0,frame1,capture_ns";
  for (const char* name : kStageNames) {
    csv += std::string(",") + name + "_start_ns," + name + "_end_ns";
  }
  for (const char* name : kStageNames) csv += std::string(",") + name + "_ms";
  csv += ",end_to_end_ms,miss,input_height,input_width";
  for (const ProfileStep& p : prof.steps()) csv += ",step_" + p.name + "_ms";
  csv += "\n";
  for (size_t i = 0; i < prof.size(); ++i) {
    const ProfiledFrame& f = prof.frame(i);
    csv += std::to_string(f.window) + "," + std::to_string(f.frame0) + "," +
           std::to_string(f.frame1) + "," + std::to_string(f.capture_ns);
    for (int st = 0; st < kProfileStages; ++st) {
      csv += "," + std::to_string(f.stage_ns[st][0]) + "," + std::to_string(f.stage_ns[st][1]);
    }
    for (int st = 0; st < kProfileStages; ++st) {
      csv += "," + FormatFixed(Ms(f.stage_ns[st][1] - f.stage_ns[st][0]), 4);
    }
    csv += "," + FormatFixed(Ms(f.end_ns(config::Stage::kOutput) - f.capture_ns), 4) +
           (f.miss ? ",1" : ",0");
    csv += "," + std::to_string(f.input_height) + "," + std::to_string(f.input_width);
    std::span<const int64_t> t = prof.step_end_ns(i);
    for (size_t k = 0; k < prof.steps().size(); ++k) {
      csv += f.has_steps ? "," + FormatFixed(Ms(t[k + 1] - t[k]), 4) : std::string(",");
    }
    csv += "\n";
  }
  return csv;
}

// The console table: stage percentiles, misses, the slowest steps, the overhead.
std::string ConsoleTable(const FrameProfiler& prof, const ProfileReportInfo& info, const Series& s,
                         const Summary (&stage_stats)[kProfileStages], const Summary& e2e,
                         const std::vector<profiling::StepRow>& step_rows) {
  const json oh = OverheadJson(prof, info, e2e);
  std::string t;
  t += "profile     " + std::to_string(prof.size()) + " frames";
  if (prof.overwritten() > 0) {
    t += " (the last " + std::to_string(prof.size()) + " of " + std::to_string(prof.recorded()) +
         "; raise --profile-frames to keep all)";
  }
  t += ", " + std::to_string(prof.steps().size()) + " steps, clock CLOCK_MONOTONIC\n";
  t += "  " + Pad("stage", 14) + Pad("p50 ms", 10, true) + Pad("p90 ms", 10, true) +
       Pad("p99 ms", 10, true) + Pad("max ms", 10, true) + "\n";
  auto row = [&](const std::string& name, const Summary& st) {
    t += "  " + Pad(name, 14) + Pad(FormatFixed(st.p50, 3), 10, true) +
         Pad(FormatFixed(st.p90, 3), 10, true) + Pad(FormatFixed(st.p99, 3), 10, true) +
         Pad(FormatFixed(st.max, 3), 10, true) + "\n";
  };
  for (int st = 0; st < kProfileStages; ++st) row(kStageNames[st], stage_stats[st]);
  row("end to end", e2e);
  if (info.budget_ms > 0) {
    t += "  budget " + FormatFixed(info.budget_ms, 2) + " ms: " + std::to_string(s.misses) +
         " of " + std::to_string(prof.size()) + " frames over\n";
  }
  const std::vector<profiling::StepRow> top = profiling::TopSteps(step_rows, 5);
  if (!top.empty()) {
    t += "  slowest steps (p50 ms): ";
    for (size_t r = 0; r < top.size(); ++r) {
      t += (r ? ", " : "") + top[r].label.name + " " + FormatFixed(top[r].ms.p50, 3);
    }
    t += "\n";
  }
  t += "  overhead    estimated " + FormatFixed(prof.overhead_ns_per_frame() / 1000, 2) +
       " us per frame (" + std::to_string(prof.steps().size() + 1) + " clock reads of " +
       FormatFixed(prof.clock_read_ns(), 1) + " ns + record " +
       FormatFixed(prof.record_ns_mean(), 0) +
       " ns) = " + FormatFixed(oh["estimated_percent_of_e2e_p50"].get<double>(), 3) +
       "% of the end-to-end p50\n";
  if (info.ab) {
    t += "  overhead    A/B in this process: end-to-end p50 " +
         FormatFixed(info.ab->e2e_p50_without_ms, 3) + " ms without, " +
         FormatFixed(info.ab->e2e_p50_with_ms, 3) + " ms with (" +
         FormatFixed(oh["ab"]["e2e_p50_change_percent"].get<double>(), 2) + "%); infer p50 " +
         FormatFixed(info.ab->infer_p50_without_ms, 3) + " / " +
         FormatFixed(info.ab->infer_p50_with_ms, 3) + " ms (" +
         FormatFixed(oh["ab"]["infer_p50_change_percent"].get<double>(), 2) + "%)\n";
  }
  return t;
}

Result<ProfileReportFiles> WriteProfileReports(const FrameProfiler& prof,
                                               const ProfileReportInfo& info, std::string* table) {
  if (prof.size() == 0) {
    return Status::Error("no frame was recorded, so there is no profile to write to '" + info.dir +
                         "'");
  }
  const std::filesystem::path dir(info.dir);
  ProfileReportFiles files;
  files.json = (dir / "profile.json").string();
  files.csv = (dir / "frames.csv").string();
  files.trace = (dir / "trace.json").string();
  files.histogram_png = (dir / "latency_hist.png").string();
  files.series_png = (dir / "latency_series.png").string();
  const Series s = Collect(prof);
  Summary stage_stats[kProfileStages];
  for (int st = 0; st < kProfileStages; ++st) stage_stats[st] = profiling::Summarize(s.stage[st]);
  const Summary e2e = profiling::Summarize(s.e2e);
  const std::vector<profiling::StepRow> step_rows =
      profiling::StepTable(prof.steps(), s.step_ms);  // empty when no frame has step times

  const json j = ProfileJson(prof, info, s, stage_stats, e2e, step_rows);
  if (Status st = WriteText(files.json, j.dump(2) + "\n"); !st.ok()) return st;

  // ---- CSV
  const std::string csv = FramesCsv(prof);
  if (Status st = WriteText(files.csv, csv); !st.ok()) return st;

  // ---- trace and plots
  if (Status st = WriteText(files.trace, TraceJson(prof, info)); !st.ok()) return st;
  const std::string subtitle = ProfilePlotSubtitle(prof, info);
  if (Status st = WritePng(files.histogram_png, HistogramPlot(s.e2e, info.budget_ms, subtitle));
      !st.ok()) {
    return st;
  }
  if (Status st = WritePng(files.series_png,
                           SeriesPlot(s.e2e, s.stage[config::StageIndex(config::Stage::kInfer)],
                                      info.budget_ms, subtitle));
      !st.ok()) {
    return st;
  }

  if (table) *table = ConsoleTable(prof, info, s, stage_stats, e2e, step_rows);
  return files;
}

Result<std::string> CompareProfileFiles(const std::string& a_path, const std::string& b_path) {
  Result<json> a = ReadProfileJson(a_path);
  if (!a.ok()) return a.status();
  Result<json> b = ReadProfileJson(b_path);
  if (!b.ok()) return b.status();
  struct Row {
    std::string kind, name;
    std::optional<double> a, b;
  };
  std::vector<Row> rows;
  std::map<std::string, size_t> index;
  auto add = [&](const std::string& kind, const std::string& name, double v, bool is_a) {
    const std::string key = kind + "\n" + name;
    auto it = index.find(key);
    if (it == index.end()) {
      it = index.emplace(key, rows.size()).first;
      rows.push_back(Row{kind, name, std::nullopt, std::nullopt});
    }
    (is_a ? rows[it->second].a : rows[it->second].b) = v;
  };
  for (int side = 0; side < 2; ++side) {
    const json& j = side == 0 ? *a : *b;
    for (auto& [name, s] : j["stages"].items()) add("stage", name, s["p50"].get<double>(), !side);
    std::map<std::string, int> seen;  // repeated step names get "#2", "#3"
    for (const json& s : j["steps"]) {
      std::string name = s["name"].get<std::string>();
      if (int n = ++seen[name]; n > 1) name += "#" + std::to_string(n);
      add("layer", name, s["p50"].get<double>(), !side);
    }
  }
  std::stable_sort(rows.begin(), rows.end(), [](const Row& x, const Row& y) {
    const bool xb = x.a && x.b, yb = y.a && y.b;
    if (xb != yb) return xb;
    if (!xb) return false;
    return std::fabs(*x.b - *x.a) > std::fabs(*y.b - *y.a);
  });
  auto describe = [](const json& j) {
    return j.value("isa", "") + ", " + std::to_string(j.value("threads", 0)) + " thread(s), " +
           std::to_string(j["frames"].value("retained", 0)) + " frames";
  };
  std::string out =
      "A  " + a_path + " (" + describe(*a) + ")\n" + "B  " + b_path + " (" + describe(*b) + ")\n";
  // Runs that differ in what they ran on: their change is not the code's alone.
  for (const char* key : {"threads", "isa"}) {
    if ((*a).contains(key) && (*b).contains(key) && (*a)[key] != (*b)[key]) {
      out += "note: A and B differ in " + std::string(key) + " (" + (*a)[key].dump() + " and " +
             (*b)[key].dump() + "): the changes below are not the code's alone\n";
    }
  }
  size_t name_w = 10;
  for (const Row& r : rows) name_w = std::max(name_w, r.name.size() + 2);
  out += Pad("kind", 7) + Pad("name", name_w) + Pad("A p50 ms", 11, true) +
         Pad("B p50 ms", 11, true) + Pad("change ms", 11, true) + Pad("change %", 10, true) + "\n";
  for (const Row& r : rows) {
    out += Pad(r.kind, 7) + Pad(r.name, name_w);
    out += Pad(r.a ? FormatFixed(*r.a, 3) : "-", 11, true) +
           Pad(r.b ? FormatFixed(*r.b, 3) : "-", 11, true);
    if (r.a && r.b) {
      const double d = *r.b - *r.a;
      out += Pad((d >= 0 ? "+" : "") + FormatFixed(d, 3), 11, true);
      out +=
          Pad(*r.a > 0 ? (d >= 0 ? "+" : "") + FormatFixed(d / *r.a * 100, 1) : std::string("n/a"),
              10, true);
    } else {
      out += Pad(r.a ? "only in A" : "only in B", 21, true);
    }
    out += "\n";
  }
  return out;
}

}  // namespace sfrt::pipeline
