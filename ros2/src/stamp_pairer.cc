#include "stamp_pairer.h"

#include <cstdlib>

namespace sfrt::ros2 {

void StampPairer::Add(int side, const pipeline::ImageMessage& image, const std::string& frame_id) {
  if (queue_[side].size() == queue_size_) Drop(side);
  Slot slot;
  if (!free_.empty()) {
    slot = std::move(free_.back());
    free_.pop_back();
  }
  slot.bytes.assign(image.data, image.data + image.size);
  slot.image = image;
  slot.image.data = slot.bytes.data();
  slot.frame_id = frame_id;
  queue_[side].push_back(std::move(slot));
  Match();
}

void StampPairer::Drop(int side) {
  ++unpaired_[side];
  free_.push_back(std::move(queue_[side].front()));
  queue_[side].pop_front();
}

// With the next frame of a side at least interval_ns_ after its last, whether a frame still to
// come on either side would pair closer than this pair does.
bool StampPairer::NoBetterPartnerCanCome(int64_t left_ns, int64_t right_ns) const {
  if (interval_ns_ <= 0) return false;
  const int64_t gap = std::llabs(left_ns - right_ns);
  const int64_t next_right = queue_[1].back().image.stamp_ns + interval_ns_;
  const int64_t next_left = queue_[0].back().image.stamp_ns + interval_ns_;
  return std::llabs(next_right - left_ns) >= gap && std::llabs(next_left - right_ns) >= gap;
}

void StampPairer::Match() {
  while (!queue_[0].empty() && !queue_[1].empty()) {
    const int64_t l = queue_[0].front().image.stamp_ns;
    const int64_t r = queue_[1].front().image.stamp_ns;
    if (r < l - slop_ns_) {  // no left image, now or later, is within the slop of it
      Drop(1);
      continue;
    }
    if (l < r - slop_ns_) {
      Drop(0);
      continue;
    }
    // A later image of one side closer to the other's candidate replaces its candidate.
    if (queue_[1].size() > 1 && std::llabs(queue_[1][1].image.stamp_ns - l) < std::llabs(r - l)) {
      Drop(1);
      continue;
    }
    if (queue_[0].size() > 1 && std::llabs(queue_[0][1].image.stamp_ns - r) < std::llabs(r - l)) {
      Drop(0);
      continue;
    }
    const bool decided =
        (queue_[0].size() > 1 && queue_[1].size() > 1) || NoBetterPartnerCanCome(l, r);
    if (!decided) return;
    ++pairs_;
    on_pair_(queue_[0].front().image, queue_[1].front().image, queue_[0].front().frame_id);
    for (int side = 0; side < 2; ++side) {
      free_.push_back(std::move(queue_[side].front()));
      queue_[side].pop_front();
    }
  }
}

}  // namespace sfrt::ros2
