#include "sfrt/pipeline/profiler.h"

#include <algorithm>
#include <chrono>

namespace sfrt::pipeline {
namespace {

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// Median over 7 batches of the mean cost of one steady_clock read.
double MeasureClockRead() {
  constexpr int kBatch = 2000;
  double batches[7];
  for (double& b : batches) {
    const int64_t t0 = NowNs();
    int64_t sink = 0;
    for (int i = 0; i < kBatch; ++i) sink ^= NowNs();
    const int64_t t1 = NowNs();
    b = static_cast<double>(t1 - t0) / kBatch;
    if (sink == 1) b += 0;  // keeps the loop's reads observable
  }
  std::sort(std::begin(batches), std::end(batches));
  return batches[3];
}

}  // namespace

FrameProfiler::FrameProfiler(size_t capacity)
    : capacity_(std::max<size_t>(capacity, 1)), frames_(capacity_) {}

void FrameProfiler::Prepare(const Session& session, int height, int width) {
  steps_ = profiling::LabelSteps(session);
  height_ = height;
  width_ = width;
  isa_ = IsaName(session.isa());
  threads_ = session.threads();
  step_ns_.assign(capacity_ * (steps_.size() + 1), 0);
  clock_read_ns_ = MeasureClockRead();
  prepared_ = true;
}

void FrameProfiler::Record(const FrameMeta& meta, std::span<const int64_t> step_end_ns, bool miss) {
  const int64_t t0 = NowNs();
  const size_t slot = static_cast<size_t>(recorded_ % capacity_);
  ProfiledFrame& f = frames_[slot];
  f.window = meta.window;
  f.frame0 = meta.frame0;
  f.frame1 = meta.frame1;
  f.capture_ns = meta.capture_ns[1];
  for (int s = 0; s < kProfileStages; ++s) {
    f.stage_ns[s][0] = meta.stage_ns[s][0];
    f.stage_ns[s][1] = meta.stage_ns[s][1];
  }
  f.miss = miss;
  f.input_height = meta.input_height;
  f.input_width = meta.input_width;
  const size_t n = steps_.size() + 1;
  f.has_steps = prepared_ && step_end_ns.size() == n;
  if (f.has_steps) std::copy(step_end_ns.begin(), step_end_ns.end(), step_ns_.begin() + slot * n);
  ++recorded_;
  const int64_t took = NowNs() - t0;
  record_ns_total_ += took;
  record_ns_max_ = std::max(record_ns_max_, took);
}

size_t FrameProfiler::size() const {
  return static_cast<size_t>(std::min<uint64_t>(recorded_, capacity_));
}

size_t FrameProfiler::Slot(size_t i) const {
  const uint64_t first = recorded_ - size();  // oldest retained record
  return static_cast<size_t>((first + i) % capacity_);
}

const ProfiledFrame& FrameProfiler::frame(size_t i) const { return frames_[Slot(i)]; }

std::span<const int64_t> FrameProfiler::step_end_ns(size_t i) const {
  const size_t n = steps_.size() + 1;
  return std::span<const int64_t>(step_ns_).subspan(Slot(i) * n, n);
}

double FrameProfiler::record_ns_mean() const {
  return recorded_ == 0 ? 0.0
                        : static_cast<double>(record_ns_total_) / static_cast<double>(recorded_);
}

double FrameProfiler::overhead_ns_per_frame() const {
  return static_cast<double>(steps_.size() + 1) * clock_read_ns_ + record_ns_mean();
}

}  // namespace sfrt::pipeline
