// The pipeline's clock: CLOCK_MONOTONIC (std::chrono::steady_clock on Linux), in which every
// FrameMeta time is given. Not installed.
#pragma once

#include <chrono>
#include <cstdint>

namespace sfrt::pipeline::detail {

inline int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace sfrt::pipeline::detail
