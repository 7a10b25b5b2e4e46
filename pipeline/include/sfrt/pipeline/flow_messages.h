// One window's flow as the messages every bag and node of sfrt writes (ros/: ROS 1 bags and
// sfrt_ros; ros2/: rosbag2 bags), so they all agree on topics, encodings, stamps and units.
#pragma once

#include <cstdint>
#include <string>

#include "sfrt/pipeline/message_io.h"
#include "sfrt/pipeline/output_sinks.h"
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

}  // namespace sfrt::pipeline
