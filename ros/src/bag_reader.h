// The one part of ros/ that sees ROS 1 message types: their generated headers need C++17 (they
// use std::allocator<void>::rebind, gone in C++20), so bag_reader.cc is compiled as C++17 and
// this interface uses nothing the two standards disagree on. Not installed.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sfrt/pipeline/message_io.h"

namespace sfrt::ros::detail {

// One image message as stored: raw pixels (sensor_msgs/Image) or an encoded file
// (sensor_msgs/CompressedImage).
struct BagImage {
  int side = 0;          // 0: the left topic, 1: the right topic
  int64_t index = 0;     // the message's number on its topic (0, 1, ...)
  int64_t stamp_ns = 0;  // header.stamp
  bool compressed = false;
  std::string encoding;  // Image.encoding ("bgr8", ...) or CompressedImage.format ("jpeg", ...)
  uint32_t height = 0;   // raw only
  uint32_t width = 0;
  uint32_t step = 0;
  std::vector<uint8_t> data;

  pipeline::ImageMessage view() const {
    pipeline::ImageMessage v;
    v.stamp_ns = stamp_ns;
    v.compressed = compressed;
    v.encoding = encoding;
    v.height = height;
    v.width = width;
    v.step = step;
    v.data = data.data();
    v.size = data.size();
    return v;
  }
};

struct BagTopics {
  std::string left_type, right_type;  // "sensor_msgs/Image" or "sensor_msgs/CompressedImage"
  int64_t left_messages = 0, right_messages = 0;
};

class BagReader {
 public:
  BagReader();
  ~BagReader();
  // Opens the bag, checks both topics (absolute names) and starts at its first message. Returns
  // "" or the error (naming the file and the topic).
  std::string Open(const std::string& path, const std::string& left, const std::string& right,
                   BagTopics* topics);
  // The next message on either topic, in the bag's time order. False at the end or on an error
  // (then *error is set).
  bool Next(BagImage* out, std::string* error);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Writes the flow's messages into a bag; each message's record time is its header stamp.
class BagWriter final : public pipeline::MessageWriter {
 public:
  BagWriter();
  ~BagWriter() override;  // closes the bag if Close() was not called (errors are lost)
  std::string Open(const std::string& path);
  std::string WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                         const std::string& frame_id, const std::string& encoding, uint32_t height,
                         uint32_t width, uint32_t step, const uint8_t* data) override;
  std::string WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                          const std::string& frame_id) override;
  std::string Close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sfrt::ros::detail
