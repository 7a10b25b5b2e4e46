// The plain vocabulary between ros/'s C++20 adapters and its C++17 files, the only ones that
// include ROS 1 headers (their generated message headers use std::allocator<void>::rebind, gone
// in C++20): image messages as views, and a writer of the messages the flow is published as, which
// a bag (BagWriter) and the node's publishers (NodeIo) both are. Nothing here is ROS-specific
// C++, so it compiles at either standard. Not installed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace sfrt::ros::detail {

// One image message as it arrived or was stored: raw pixels (sensor_msgs/Image) or an encoded
// file (sensor_msgs/CompressedImage). A view: `data` belongs to the message.
struct ImageView {
  int64_t stamp_ns = 0;  // header.stamp, ns since the epoch (or of ROS time under use_sim_time)
  bool compressed = false;
  std::string encoding;  // Image.encoding ("bgr8", ...) or CompressedImage.format ("jpeg", ...)
  uint32_t height = 0;   // raw only
  uint32_t width = 0;
  uint32_t step = 0;
  const uint8_t* data = nullptr;
  size_t size = 0;
};

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
