// The pipeline's clocks: CLOCK_MONOTONIC (std::chrono::steady_clock on Linux), in which every
// FrameMeta time is given, and the wall clock. Not installed.
#pragma once

#include <chrono>
#include <cstdint>

namespace sfrt::pipeline::detail {

inline int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// CLOCK_REALTIME (the wall clock, ROS stamps' clock), ns since the epoch.
inline int64_t WallNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace sfrt::pipeline::detail
