// An image as robots record and send it: ROS's sensor_msgs Image (raw pixels with an encoding
// name) or CompressedImage (a JPEG or PNG file), from ROS 1 or ROS 2, a bag or a topic. The bag
// and topic adapters (ros/, ros2/) decode their messages into this view and the pipeline turns
// it into the BGR8 frames its sources hand on.
//
// Plain C++17 on purpose: ROS 1's generated message headers do not compile as C++20, so the ros/
// files that include them are C++17 and include this header too.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>

namespace sfrt::pipeline {

// One image message as it arrived or was stored. A view: `data` belongs to the message.
struct ImageMessage {
  int64_t stamp_ns = 0;  // header.stamp, ns since the epoch (or of ROS time under use_sim_time)
  bool compressed = false;
  std::string encoding;  // Image.encoding ("bgr8", ...) or CompressedImage.format ("jpeg", ...)
  uint32_t height = 0;   // raw only
  uint32_t width = 0;
  uint32_t step = 0;
  const uint8_t* data = nullptr;
  size_t size = 0;
};

// A raw image in bgr8, rgb8, bgra8, rgba8 or mono8, or a compressed one (JPEG, PNG: anything
// OpenCV decodes), as BGR8 into *out (its memory reused when the size matches). Returns "" when
// done, else why not, naming the encoding ("encoding 'yuv422' is not one ...").
std::string ImageMessageToBgr(const ImageMessage& image, cv::Mat* out);

}  // namespace sfrt::pipeline
