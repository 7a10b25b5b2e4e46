// The clocks ros/ reads: CLOCK_MONOTONIC (the pipeline's, FrameMeta's times) and CLOCK_REALTIME
// (ROS stamps). Not installed.
#pragma once

#include <cstdint>
#include <ctime>

namespace sfrt::ros::detail {

inline int64_t ClockNs(clockid_t clock) {
  timespec ts{};
  ::clock_gettime(clock, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

inline int64_t MonotonicNs() { return ClockNs(CLOCK_MONOTONIC); }

}  // namespace sfrt::ros::detail
