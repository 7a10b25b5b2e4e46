// Peak memory read bandwidth of this machine per thread count, beside the compute peaks
// (peak_fma.h, peak_dot.h): the roof of the steps that move more bytes than they compute on
// (a few-output convolution over a full-size tensor, the input's first layer). Each thread sums
// its own slice of a buffer far larger than the last-level cache (first touched by that thread,
// so its pages are local), with four independent 64-byte accumulators, the fastest of 20 windows
// over about `seconds`: a streaming read, as the runtime's convolutions read activations.
#pragma once

#include <cstddef>
#include <string>

#include "sfrt/status.h"

namespace sfrt::profiling {

struct PeakBandwidth {
  int threads = 1;
  double gbytes_per_second = 0;  // all threads together, 10^9 bytes read per second
  size_t buffer_bytes = 0;       // the buffer the threads read, split between them
  std::string kernel;  // what ran, e.g. "4 x 64-byte sums over 512 MiB, 1 pass(es) a window"
};

// The default buffer: 512 MiB (well beyond any server's last-level cache per socket share).
inline constexpr size_t kBandwidthBufferBytes = size_t{512} << 20;

// Measures for about `seconds` (at least 20 windows of one pass each). Fails when threads < 1 or
// the buffer cannot be allocated.
Result<PeakBandwidth> MeasureReadBandwidth(int threads, double seconds,
                                           size_t buffer_bytes = kBandwidthBufferBytes);

}  // namespace sfrt::profiling
