// Pairs a stereo camera's left and right images by header stamp, for sfrt_ros2 (ROS 1's node
// uses message_filters' ApproximateTime; ROS 2 without rclcpp has no message_filters). The rule
// is ApproximateTime's for two topics, with its inter-message lower bound:
//   - each side keeps its newest `queue_size` images (older ones are dropped, counted);
//   - the oldest image of each side is a candidate pair when their stamps differ by at most
//     `slop_ns`; a side's image that no image of the other side can be within the slop of is
//     dropped, counted as unpaired;
//   - a candidate pair is given out once no image still to come could pair better: when the
//     next image of each side is already here, or when `frame_interval_ns` (the least time
//     between two frames of one camera; 0 = unknown) proves a later one would be further away.
// A pair goes to the callback, in stamp order, with the images' bytes valid during the call.
// Not thread-safe (the node's DDS callbacks are serialised by the caller). After the queues have
// filled once, no allocation per image: buffers are reused. Not installed.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "sfrt/pipeline/message_io.h"

namespace sfrt::ros2 {

class StampPairer {
 public:
  using PairCallback =
      std::function<void(const pipeline::ImageMessage& left, const pipeline::ImageMessage& right,
                         const std::string& left_frame_id)>;

  StampPairer(int64_t slop_ns, int64_t frame_interval_ns, size_t queue_size, PairCallback on_pair)
      : slop_ns_(slop_ns),
        interval_ns_(frame_interval_ns),
        queue_size_(queue_size < 1 ? 1 : queue_size),
        on_pair_(std::move(on_pair)) {}

  // One image of side 0 (left) or 1 (right); copies it, then gives out every pair now decided.
  void Add(int side, const pipeline::ImageMessage& image, const std::string& frame_id);

  uint64_t unpaired(int side) const { return unpaired_[side]; }
  uint64_t pairs() const { return pairs_; }

 private:
  struct Slot {
    pipeline::ImageMessage image;  // data points into bytes
    std::vector<uint8_t> bytes;
    std::string frame_id;
  };
  void Drop(int side);  // the oldest of a side, counted as unpaired
  void Match();
  bool NoBetterPartnerCanCome(int64_t left_ns, int64_t right_ns) const;

  int64_t slop_ns_;
  int64_t interval_ns_;
  size_t queue_size_;
  PairCallback on_pair_;
  std::deque<Slot> queue_[2];
  std::vector<Slot> free_;  // slots given back, their buffers kept
  uint64_t unpaired_[2] = {0, 0};
  uint64_t pairs_ = 0;
};

}  // namespace sfrt::ros2
