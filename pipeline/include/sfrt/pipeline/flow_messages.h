// One window's flow as the messages every bag and node of sfrt writes (ros/: ROS 1 bags and
// sfrt_ros; ros2/: rosbag2 bags), so they all agree on topics, encodings, stamps and units.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "sfrt/pipeline/message_io.h"
#include "sfrt/pipeline/output_sinks.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/sink.h"

namespace sfrt::pipeline {

struct FlowTopics {
  std::string flow = "/flow";     // sensor_msgs/Image, 32FC3
  std::string t1 = "/flow_t1";    // std_msgs/Header, the stamp of pair t+1
  std::string vis = "/flow_vis";  // sensor_msgs/Image, bgr8 (when a renderer is given)
};

// Writes `frame` as: `flow` (encoding "32FC<channels>": dX, dY, dZ per pixel of the left image at
// t, little-endian floats, row-major; header.stamp = stamp_t0, the stamp of pair t;
// header.seq = the window number), `t1` (the same seq and frame_id, stamped stamp_t1) and, when
// `renderer` is not null, `vis` (its canvas, bgr8, stamped stamp_t0). Returns "" or the first
// error; the messages before it stay written.
std::string WriteFlowMessages(const FlowFrame& frame, int64_t stamp_t0, int64_t stamp_t1,
                              const std::string& frame_id, const FlowTopics& topics,
                              FlowRenderer* renderer, MessageWriter* writer);

// The `vis` message alone: the renderer's canvas of `frame`, bgr8, stamped stamp_t0, seq = the
// window number (the node publishes it from a queue of its own, VisTopicSink).
std::string WriteVisMessage(const FlowFrame& frame, int64_t stamp_t0, const std::string& frame_id,
                            const std::string& topic, FlowRenderer* renderer,
                            MessageWriter* writer);

// What every bag recorder of the flow writes (ros/: ROS 1 bags; ros2/: rosbag2 MCAP): the path,
// the messages' frame_id, the topics, the optional picture and the optional input images.
struct FlowRecordingOptions {
  std::string path;
  std::string frame_id = "left_camera";
  std::string flow_topic = "/flow";
  std::string t1_topic = "/flow_t1";
  bool vis = false;
  std::string vis_topic = "/flow_vis";
  VisualizerOptions vis_options;
  // The stereo pairs the source read (MakeRecordingSource), as sensor_msgs/Image bgr8 at the
  // source's frame size, stamped as the flow is, header.seq the frame number: a bag that replays.
  std::string left_topic = "/left/image_rect";
  std::string right_topic = "/right/image_rect";
  std::string right_frame_id = "right_camera";  // the left images' is frame_id
};

// Where a recording source hands each stereo pair it read (MakeRecordingSource).
class InputRecorder {
 public:
  virtual ~InputRecorder() = default;
  // The pairs of `item` not recorded yet: pair t+1, and pair t unless the window continues the
  // one before (FrameMeta::continues). Called on the source's thread.
  virtual Status RecordInputs(const WindowItem& item) = 0;
};

// The part of a bag recorder that does not depend on the bag: each window's messages through
// WriteFlowMessages, and the input pairs, stamped with the source's header stamps when it has
// them, else the capture time moved from CLOCK_MONOTONIC to the wall clock by the offset between
// the two clocks at Start(). Write (the output stage's thread) and WriteInputs (the source's) may
// run at once: they take turns on the writer. After a failed write every later one fails too (a
// bag with a hole is not finished).
class FlowRecorder {
 public:
  explicit FlowRecorder(FlowRecordingOptions options) : options_(std::move(options)) {}
  void Start();  // the clock offset, the renderer
  Status Write(const FlowFrame& frame, MessageWriter* writer);
  Status WriteInputs(const WindowItem& item, MessageWriter* writer);
  bool failed() const;
  int64_t windows() const;
  int64_t input_pairs() const;
  const FlowRecordingOptions& options() const { return options_; }

 private:
  int64_t WallStamp(const FrameMeta& m, int pair) const;
  Status Fail(const std::string& error);  // with mu_ held

  FlowRecordingOptions options_;
  std::optional<FlowRenderer> renderer_;
  int64_t realtime_minus_monotonic_ns_ = 0;
  mutable std::mutex mu_;  // the writer and the counts below
  int64_t windows_ = 0;
  int64_t input_pairs_ = 0;
  bool failed_ = false;
};

// `source` whose every window is also handed to `recorder` (not owned; it must outlive the
// source) as it is read, before the pipeline sees it. A recorder's error ends the run as a source
// error does. Everything else is `source`'s own.
// Recorded files (a replay that is not live and has no stamps of its own) get stamps on a fixed
// clock (FrameMeta::stamp_ns, which the flow messages carry too): the time they were read depends
// on the machine's load, and a bag stamped with it would replay into other windows (a slow read
// looks like a lost frame). Pairs are kRecordedFramePeriodNs apart from the recording's start on
// the wall clock, with kRecordedBreakNs more where the replay's chain broke (another sequence, a
// lost frame), so the bag replays into the same windows.
inline constexpr int64_t kRecordedFramePeriodNs = 100'000'000;  // 10 frames a second
inline constexpr int64_t kRecordedBreakNs = 1'000'000'000;
std::unique_ptr<FrameSource> MakeRecordingSource(std::unique_ptr<FrameSource> source,
                                                 InputRecorder* recorder);

}  // namespace sfrt::pipeline
