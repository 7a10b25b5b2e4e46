#include "sfrt/pipeline/topic_sink.h"

#include <cmath>
#include <cstdio>
#include <ctime>
#include <nlohmann/json.hpp>
#include <span>

#include "clock.h"
#include "sfrt/pipeline/topic_source.h"

namespace sfrt::pipeline {
namespace {

// The series: the stages (config::Stage's order), then end to end and stamp to publish.
constexpr int kEndToEnd = config::kStageCount;
constexpr int kStampToPublish = kEndToEnd + 1;
const char* SeriesName(int s) {
  return s < config::kStageCount ? config::kStageNames[static_cast<size_t>(s)]
         : s == kEndToEnd        ? "end_to_end"
                                 : "stamp_to_publish";
}

std::string Ms(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

}  // namespace

FlowTopicSink::FlowTopicSink(TopicSinkOptions options, MessageWriter* writer,
                             const TopicSource* source, Clock ros_now, Publish publish_diagnostics)
    : options_(std::move(options)),
      writer_(writer),
      source_(source),
      ros_now_(std::move(ros_now)),
      publish_(std::move(publish_diagnostics)) {}

Status FlowTopicSink::Start() {
  recent_.assign(kSeries, profiling::LatestValues(options_.window_values));
  all_.assign(kSeries, profiling::LatestValues());
  last_publish_ns_ = detail::NowNs();
  return Status::Ok();
}

Status FlowTopicSink::Write(const FlowFrame& frame) {
  const FrameMeta& m = *frame.meta;
  const std::string& frame_id = options_.frame_id.empty() ? source_->frame_id() : options_.frame_id;
  const std::string e = WriteFlowMessages(frame, m.stamp_ns[0], m.stamp_ns[1], frame_id,
                                          options_.topics, nullptr, writer_);
  if (!e.empty()) return Status::Error(e);
  // From the header stamp of the newest image the flow needs to its publication, on ROS time;
  // counted when it is a plausible latency (a bag's old stamps are not).
  const double ms = static_cast<double>(ros_now_() - m.stamp_ns[1]) / 1e6;
  last_stamp_to_publish_ms_ = ms >= 0 && ms < 2000 ? ms : -1;
  return Status::Ok();
}

Status VisTopicSink::Write(const FlowFrame& frame) {
  const std::string& frame_id = frame_id_.empty() ? source_->frame_id() : frame_id_;
  const std::string e =
      WriteVisMessage(frame, frame.meta->stamp_ns[0], frame_id, topic_, &renderer_, writer_);
  return e.empty() ? Status::Ok() : Status::Error(e);
}

Status FlowTopicSink::Completed(const WindowRecord& record) {
  const FrameMeta& m = *record.meta;
  double v[kSeries];
  for (int s = 0; s < config::kStageCount; ++s) {
    v[s] = static_cast<double>(m.stage_ns[s][1] - m.stage_ns[s][0]) / 1e6;
  }
  v[kEndToEnd] = record.end_to_end_ms;
  v[kStampToPublish] = last_stamp_to_publish_ms_;
  for (int s = 0; s < kSeries; ++s) {
    if (v[s] < 0) continue;
    recent_[static_cast<size_t>(s)].Add(v[s]);
    all_[static_cast<size_t>(s)].Add(v[s]);
  }
  if (last_window_ >= 0 && m.window > last_window_ + 1) gaps_ += m.window - last_window_ - 1;
  last_window_ = m.window;
  if (record.miss) ++misses_;
  ++windows_;
  const int64_t now = detail::NowNs();
  last_done_ns_ = now;
  if (static_cast<double>(now - last_publish_ns_) >= options_.diagnostics_period_s * 1e9) {
    PublishDiagnostics(now);
  }
  return Status::Ok();
}

Status FlowTopicSink::Stop() {
  if (windows_.load() > windows_at_publish_) PublishDiagnostics(detail::NowNs());
  return Status::Ok();
}

std::vector<std::pair<std::string, std::string>> FlowTopicSink::Counters() const {
  std::vector<std::pair<std::string, std::string>> v;
  v.emplace_back("windows published", std::to_string(windows_.load()));
  v.emplace_back("stereo pairs", std::to_string(source_->pairs()));
  if (options_.received) {
    v.emplace_back("images received (left, right)", std::to_string(options_.received(0)) + ", " +
                                                        std::to_string(options_.received(1)));
  }
  v.emplace_back("pairs skipped (bad image)", std::to_string(source_->bad_pairs()));
  v.emplace_back("pairs dropped at the source (newest wins)", std::to_string(source_->drops()));
  v.emplace_back("windows dropped in the pipeline (newest wins)", std::to_string(gaps_.load()));
  v.emplace_back("deadline misses", std::to_string(misses_.load()));
  v.emplace_back("budget ms", options_.budget_ms > 0 ? Ms(options_.budget_ms) : "none");
  for (const auto& fact : options_.facts) v.push_back(fact);
  return v;
}

void FlowTopicSink::PublishDiagnostics(int64_t now) {
  const double seconds = static_cast<double>(now - last_publish_ns_) / 1e9;
  const int64_t windows = windows_.load(), misses = misses_.load();
  const double fps = seconds > 0 ? static_cast<double>(windows - windows_at_publish_) / seconds : 0;
  const int64_t new_misses = misses - misses_at_publish_;
  last_publish_ns_ = now;
  windows_at_publish_ = windows;
  misses_at_publish_ = misses;

  DiagnosticReport r;
  r.name = options_.diagnostics_name;
  r.hardware_id = options_.hardware_id;
  r.values = Counters();
  r.values.emplace_back("fps", Ms(fps));
  profiling::Summary e2e;
  for (int s = 0; s < kSeries; ++s) {
    const std::vector<double> values = recent_[static_cast<size_t>(s)].Values();
    const profiling::Summary sum = profiling::Summarize(values);
    if (s == kEndToEnd) e2e = sum;
    if (sum.count == 0) continue;
    r.values.emplace_back(std::string(SeriesName(s)) + " p50 ms", Ms(sum.p50));
    r.values.emplace_back(std::string(SeriesName(s)) + " p99 ms", Ms(sum.p99));
  }
  r.level = new_misses > 0 ? DiagnosticReport::kWarn : DiagnosticReport::kOk;
  r.message = Ms(fps) + " fps, end to end p50 " + Ms(e2e.p50) + " ms, p99 " + Ms(e2e.p99) +
              " ms, " + std::to_string(new_misses) + " deadline misses since the last status";
  publish_({r});
}

void FlowTopicSink::PublishIfIdle(int64_t now) {
  const int64_t last = last_done_ns_.load();
  const auto idle = static_cast<int64_t>(2 * options_.diagnostics_period_s * 1e9);
  // The output thread publishes while windows complete; this one only after a silence.
  if (now - (last != 0 ? last : now - idle) < idle) return;
  if (now - last_idle_publish_ns_ < static_cast<int64_t>(options_.diagnostics_period_s * 1e9)) {
    return;
  }
  last_idle_publish_ns_ = now;
  DiagnosticReport r;
  r.name = options_.diagnostics_name;
  r.hardware_id = options_.hardware_id;
  r.level = DiagnosticReport::kWarn;
  r.message = last == 0
                  ? "waiting for stereo pairs"
                  : "no window in the last " + Ms(static_cast<double>(now - last) / 1e9) + " s";
  r.values = Counters();
  publish_({r});
}

void FlowTopicSink::ToJson(nlohmann::json* out) const {
  for (int s = 0; s < kSeries; ++s) {
    const profiling::Summary sum = profiling::Summarize(all_[static_cast<size_t>(s)].Values());
    (*out)[std::string(SeriesName(s)) + "_ms"] = {
        {"count", sum.count}, {"p50", sum.p50}, {"p99", sum.p99}, {"max", sum.max}};
  }
  (*out)["windows"] = windows_.load();
  (*out)["windows_dropped"] = gaps_.load();
  (*out)["misses"] = misses_.load();
}

}  // namespace sfrt::pipeline
