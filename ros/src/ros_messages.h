// C++17 only (it includes ROS 1 message headers; see message_io.h): the one place ros/ fills the
// messages it writes, for the bag (bag_reader.cc) and the node (node_io.cc). Not installed.
#pragma once

#include <ros/time.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/Header.h>

#include <cstdint>
#include <string>

namespace sfrt::ros::detail {

inline ::ros::Time ToRosTime(int64_t ns) {
  ::ros::Time t;
  t.fromNSec(static_cast<uint64_t>(ns < 0 ? 0 : ns));
  return t;
}

inline void FillHeader(std_msgs::Header* h, int64_t stamp_ns, uint32_t seq,
                       const std::string& frame_id) {
  h->stamp = ToRosTime(stamp_ns);
  h->seq = seq;
  h->frame_id = frame_id;
}

// `height` rows of `step` bytes copied into im->data (its capacity reused).
inline void FillImage(sensor_msgs::Image* im, int64_t stamp_ns, uint32_t seq,
                      const std::string& frame_id, const std::string& encoding, uint32_t height,
                      uint32_t width, uint32_t step, const uint8_t* data) {
  FillHeader(&im->header, stamp_ns, seq, frame_id);
  im->height = height;
  im->width = width;
  im->encoding = encoding;
  im->is_bigendian = 0;  // as written by a little-endian machine (x86-64, aarch64)
  im->step = step;
  im->data.assign(data, data + static_cast<size_t>(step) * height);
}

}  // namespace sfrt::ros::detail
