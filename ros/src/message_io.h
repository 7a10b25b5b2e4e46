// The plain vocabulary between ros/'s C++20 adapters and its C++17 files, the only ones that
// include ROS 1 headers (their generated message headers use std::allocator<void>::rebind, gone
// in C++20): image messages as views (the pipeline's ImageMessage), and a writer of the messages
// the flow is published as, which a bag (BagWriter) and the node's publishers (NodeIo) both are.
// Nothing here is ROS-specific C++, so it compiles at either standard. Not installed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "sfrt/pipeline/image_message.h"

namespace sfrt::ros::detail {

// One image message as it arrived or was stored (pipeline/image_message.h).
using ImageView = pipeline::ImageMessage;

// Where the flow of a window goes as ROS messages. Errors are returned as strings ("" = done).
class MessageWriter {
 public:
  virtual ~MessageWriter() = default;
  // A sensor_msgs/Image of `height` rows of `step` bytes: "32FC3" (3 floats a pixel) or "bgr8".
  virtual std::string WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                                 const std::string& frame_id, const std::string& encoding,
                                 uint32_t height, uint32_t width, uint32_t step,
                                 const uint8_t* data) = 0;
  // A std_msgs/Header.
  virtual std::string WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                                  const std::string& frame_id) = 0;
};

}  // namespace sfrt::ros::detail
