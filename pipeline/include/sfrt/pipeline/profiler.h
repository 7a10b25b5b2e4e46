// Per-frame, per-stage profiling of the `sfrt run` pipeline (`--profile`, issue #6).
//
// FrameProfiler is a ring of fixed capacity, allocated when it is constructed and when Prepare()
// learns the session's step count, before the pipeline's threads start. Per frame the pipeline
// only copies into it: the infer stage asks Session::Run for the end time of every planned step
// (into a buffer that travels with the frame), and the output stage calls Record() with the
// frame's stage timestamps and those step times. No allocation, no lock, no I/O per frame. When
// more frames are recorded than the ring holds, the oldest are overwritten (counted).
//
// Every timestamp is std::chrono::steady_clock (CLOCK_MONOTONIC on Linux) in nanoseconds, the
// clock the pipeline and V4L2 use, so stages and layers line up on one time axis.
//
// Overhead: Prepare() measures what one clock read costs on this machine; Record() measures its
// own duration. The estimated cost per frame is (steps + 1) clock reads inside Session::Run plus
// one Record(). profile_report.h writes it with the reports.
//
// Thread-safety: Prepare() before the stages start; Record() from one thread (the output
// stage); the accessors after the stages have been joined.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/stats.h"
#include "sfrt/session.h"

namespace sfrt::pipeline {

// Stage names in profiles and reports (sfrt/config/vocabulary.h): index 0 is the source stage
// (camera capture or file read).
inline constexpr int kProfileStages = config::kStageCount;
using config::kStageNames;

// One planned step of the session (Session::steps()): layers, op type and kernel.
using ProfileStep = profiling::StepLabel;

struct ProfiledFrame {
  int64_t window = -1;
  int64_t frame0 = -1;
  int64_t frame1 = -1;
  int64_t capture_ns = 0;                    // capture of pair t+1: start of the end-to-end time
  int64_t stage_ns[kProfileStages][2] = {};  // [stage][start, end], indexed by config::Stage
  int64_t& start_ns(config::Stage s) { return stage_ns[config::StageIndex(s)][0]; }
  int64_t& end_ns(config::Stage s) { return stage_ns[config::StageIndex(s)][1]; }
  int64_t start_ns(config::Stage s) const { return stage_ns[config::StageIndex(s)][0]; }
  int64_t end_ns(config::Stage s) const { return stage_ns[config::StageIndex(s)][1]; }
  bool has_steps = false;  // the step times are valid
  bool miss = false;       // end to end over the budget
  int input_height = 0;    // the size the frame ran at (smaller-input)
  int input_width = 0;
};

class FrameProfiler {
 public:
  // capacity: frames the ring holds (>= 1).
  explicit FrameProfiler(size_t capacity);

  // Learns the session's steps and allocates their timestamps; also measures the cost of one
  // clock read. Called by the pipeline once the session exists, before the stages start.
  void Prepare(const Session& session, int height, int width);

  // Copies one written frame. step_end_ns: steps().size() + 1 values as Session::Run filled
  // them, or empty when the frame has none. No allocation.
  void Record(const FrameMeta& meta, std::span<const int64_t> step_end_ns, bool miss);

  size_t capacity() const { return capacity_; }
  bool prepared() const { return prepared_; }
  const std::vector<ProfileStep>& steps() const { return steps_; }
  int height() const { return height_; }
  int width() const { return width_; }
  const std::string& isa() const { return isa_; }
  int threads() const { return threads_; }

  uint64_t recorded() const { return recorded_; }  // Record() calls
  size_t size() const;                             // frames retained (<= capacity)
  uint64_t overwritten() const { return recorded_ - size(); }
  // Retained frame i, oldest first, and its step end times (steps().size() + 1 values).
  const ProfiledFrame& frame(size_t i) const;
  std::span<const int64_t> step_end_ns(size_t i) const;

  double clock_read_ns() const { return clock_read_ns_; }  // median cost of one clock read
  double record_ns_mean() const;                           // mean duration of Record()
  int64_t record_ns_max() const { return record_ns_max_; }
  // Estimated profiling cost per frame, nanoseconds: (steps + 1) clock reads + one Record().
  double overhead_ns_per_frame() const;

 private:
  size_t Slot(size_t i) const;

  size_t capacity_;
  bool prepared_ = false;
  std::vector<ProfileStep> steps_;
  int height_ = 0;
  int width_ = 0;
  std::string isa_;
  int threads_ = 0;
  std::vector<ProfiledFrame> frames_;  // capacity_
  std::vector<int64_t> step_ns_;       // capacity_ x (steps + 1)
  uint64_t recorded_ = 0;
  double clock_read_ns_ = 0;
  int64_t record_ns_total_ = 0;
  int64_t record_ns_max_ = 0;
};

}  // namespace sfrt::pipeline
