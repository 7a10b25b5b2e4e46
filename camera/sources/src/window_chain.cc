#include "sfrt/camera/window_chain.h"

#include <algorithm>

namespace sfrt::camera {

const char* ChainLinkName(ChainLink link) {
  switch (link) {
    case ChainLink::kWindow:
      return "window";
    case ChainLink::kFirst:
      return "first";
    case ChainLink::kLost:
      return "lost frame";
    case ChainLink::kGap:
      return "gap";
    case ChainLink::kBackwards:
      return "backwards";
  }
  return "?";
}

void WindowChain::Restart() {
  have_last_ = false;
  lost_ = false;
  seen_ = 0;
  next_ = 0;
}

void WindowChain::Remember(int64_t interval) {
  intervals_[static_cast<size_t>(next_)] = interval;
  next_ = (next_ + 1) % kIntervals;
  seen_ = std::min(seen_ + 1, kIntervals);
}

int64_t WindowChain::interval() const {
  if (nominal_ > 0) return nominal_;
  if (seen_ == 0) return 0;
  std::array<int64_t, kIntervals> sorted = intervals_;  // on the stack: no allocation
  const auto end = sorted.begin() + seen_;
  const auto middle = sorted.begin() + seen_ / 2;
  std::nth_element(sorted.begin(), middle, end);
  if (seen_ % 2 == 1) return *middle;
  // An even count: the mean of the two middle values (the lower one is the largest below).
  const int64_t lower = *std::max_element(sorted.begin(), middle);
  return lower + (*middle - lower) / 2;
}

ChainLink WindowChain::Offer(int64_t stamp) {
  const bool had_last = have_last_;
  const int64_t last = last_;
  const bool lost = lost_;
  have_last_ = true;
  lost_ = false;
  last_ = stamp;
  if (!had_last) return ChainLink::kFirst;
  if (stamp <= last) {
    ++counts_.stream_restarts;
    seen_ = 0;  // another stream: its rate is learnt anew
    next_ = 0;
    return ChainLink::kBackwards;
  }
  const int64_t step = stamp - last;
  if (lost) {  // the step spans the lost frame: not an interval of the stream
    ++counts_.broken_by_loss;
    return ChainLink::kLost;
  }
  const int64_t expected = interval();
  Remember(step);
  // In double: a first step from a zero stamp to one since the epoch would overflow 2 x step.
  if (expected > 0 && static_cast<double>(step) > 1.5 * static_cast<double>(expected)) {
    ++counts_.skipped_for_gap;
    return ChainLink::kGap;
  }
  ++counts_.windows;
  return ChainLink::kWindow;
}

}  // namespace sfrt::camera
