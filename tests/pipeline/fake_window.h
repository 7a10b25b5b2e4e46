// What the tests' fake frame sources write into every window they hand out: the frame numbers
// of pair t and t+1, and the clock a real source reads (capture times and the source stage's
// start at "now"), so the pipeline's latency bookkeeping sees a window as from a file source.
#pragma once

#include <chrono>
#include <cstdint>

#include "sfrt/pipeline/pipeline.h"

namespace sfrt::pipeline {

inline void StampFakeWindow(FrameMeta* meta, int64_t frame0) {
  meta->frame0 = frame0;
  meta->frame1 = frame0 + 1;
  const int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                          std::chrono::steady_clock::now().time_since_epoch())
                          .count();
  meta->capture_ns[0] = meta->capture_ns[1] = now;
  meta->stage_ns[0][0] = now;
}

}  // namespace sfrt::pipeline
