// The pipeline's side of a robot's messages, whatever the middleware (ROS 1, ROS 2) or the bag:
//   in:  an image as robots record and send it, ROS's sensor_msgs Image (raw pixels with an
//        encoding name) or CompressedImage (a JPEG or PNG file), which the bag and topic
//        adapters (ros/, ros2/) decode into an ImageMessage and the pipeline turns into the BGR8
//        frames its sources hand on;
//   out: a MessageWriter, where the flow of a window goes as messages (flow_messages.h says
//        which): a bag, or a node's publishers.
//
// Plain C++17 on purpose: ROS 1's generated message headers do not compile as C++20, so the ros/
// files that include them are C++17 and include this header too.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

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

// Where the flow of a window goes as messages. Errors are returned as strings ("" = done).
class MessageWriter {
 public:
  virtual ~MessageWriter() = default;
  // A sensor_msgs/Image of `height` rows of `step` bytes: "32FC3" (3 floats a pixel) or "bgr8".
  // `seq` is ROS 1's header.seq (the window number); ROS 2's Header has none.
  virtual std::string WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                                 const std::string& frame_id, const std::string& encoding,
                                 uint32_t height, uint32_t width, uint32_t step,
                                 const uint8_t* data) = 0;
  // A std_msgs/Header.
  virtual std::string WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                                  const std::string& frame_id) = 0;
};

// One diagnostic_msgs/DiagnosticStatus, as a node publishes its health on /diagnostics.
struct DiagnosticReport {
  enum Level { kOk = 0, kWarn = 1, kError = 2, kStale = 3 };
  Level level = kOk;
  std::string name;
  std::string message;
  std::string hardware_id;
  std::vector<std::pair<std::string, std::string>> values;
};

}  // namespace sfrt::pipeline
