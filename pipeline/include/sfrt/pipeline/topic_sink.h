// A node's outputs: each window's flow published as messages (flow_messages.h:
// `flow` 32FC3 stamped with pair t, `flow_t1` with pair t+1; `flow_vis` by VisTopicSink), and
// /diagnostics (diagnostic_msgs/DiagnosticArray) every `diagnostics_period_s`: latency p50/p99
// per stage over the latest windows, drops, deadline misses, the ISA and precision in use.
// Over a MessageWriter and a diagnostics callback (message_io.h), so the ROS 1 and ROS 2 nodes
// share it.
//
// Threads: Write() and Completed() come from the output stage (sink.h), which also publishes the
// diagnostics; PublishIfIdle() is for the node's main thread and reads only atomics, so nothing
// here takes a lock.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "sfrt/pipeline/flow_messages.h"
#include "sfrt/pipeline/message_io.h"
#include "sfrt/pipeline/output_sinks.h"
#include "sfrt/pipeline/sink.h"
#include "sfrt/pipeline/stats.h"

namespace sfrt::pipeline {

class TopicSource;

struct TopicSinkOptions {
  FlowTopics topics;     // resolved names; topics.vis is VisTopicSink's
  std::string frame_id;  // "" = the left images' frame_id (TopicSource::frame_id())
  double diagnostics_period_s = 1;
  std::string diagnostics_name = "sfrt_ros: scene flow";
  std::string hardware_id;  // the model's name
  // Facts that do not change during a run, shown in every status: isa, precision, threads, ...
  std::vector<std::pair<std::string, std::string>> facts;
  double budget_ms = 0;
  // Messages received on the left (0) and right (1) image topics (NodeIo::received); null: not
  // reported.
  std::function<uint64_t(int side)> received;
  size_t window_values = 300;  // the diagnostics' percentiles cover this many latest windows
};

class FlowTopicSink final : public FlowSink {
 public:
  using Clock = std::function<int64_t()>;  // ROS time, ns
  using Publish = std::function<void(const std::vector<DiagnosticReport>&)>;
  FlowTopicSink(TopicSinkOptions options, MessageWriter* writer, const TopicSource* source,
                Clock ros_now, Publish publish_diagnostics);

  std::string name() const override { return "ros"; }
  Status Start() override;
  Status Write(const FlowFrame& frame) override;
  Status Completed(const WindowRecord& record) override;
  Status Stop() override;
  void ToJson(nlohmann::json* out) const override;

  // From another thread: when no window was completed for twice the diagnostics period, a
  // status saying so (WARN, "no stereo pairs ...") with the counters.
  void PublishIfIdle(int64_t now_monotonic_ns);

  int64_t windows() const { return windows_.load(); }

 private:
  void PublishDiagnostics(int64_t now_monotonic_ns);
  std::vector<std::pair<std::string, std::string>> Counters() const;

  TopicSinkOptions options_;
  MessageWriter* writer_;
  const TopicSource* source_;
  Clock ros_now_;
  Publish publish_;
  // The output stage's thread only.
  static constexpr int kSeries =
      config::kStageCount + 2;                   // the stages, end to end, stamp to publish
  std::vector<profiling::LatestValues> recent_;  // the latest windows
  std::vector<profiling::LatestValues> all_;     // the run (for summary.json)
  int64_t last_window_ = -1;
  int64_t last_publish_ns_ = 0;
  int64_t windows_at_publish_ = 0;
  int64_t misses_at_publish_ = 0;
  double last_stamp_to_publish_ms_ = -1;  // of the window being written
  int64_t last_idle_publish_ns_ = 0;      // PublishIfIdle()'s thread only
  // Read by PublishIfIdle().
  std::atomic<int64_t> windows_{0}, misses_{0}, gaps_{0}, last_done_ns_{0};
};

// `flow_vis`: the picture `sfrt run` writes as PNG, as a bgr8 image stamped with pair t. Apart
// from FlowTopicSink so that the node puts it behind a QueuedSink that drops (and
// counts) the pictures it cannot keep up with: drawing never delays a flow message.
class VisTopicSink final : public FlowSink {
 public:
  VisTopicSink(std::string topic, VisualizerOptions vis_options, std::string frame_id,
               MessageWriter* writer, const TopicSource* source)
      : topic_(std::move(topic)),
        renderer_(std::move(vis_options)),
        frame_id_(std::move(frame_id)),
        writer_(writer),
        source_(source) {}
  std::string name() const override { return "ros flow_vis"; }
  Status Write(const FlowFrame& frame) override;

 private:
  std::string topic_;
  FlowRenderer renderer_;
  std::string frame_id_;  // "" = the left images' (TopicSource::frame_id())
  MessageWriter* writer_;
  const TopicSource* source_;
};

}  // namespace sfrt::pipeline
