// Stereo capture: two V4L2 devices paired by timestamp, or one side-by-side device split in two.
//
// Two devices: each camera has its own clock and exposure, so frames are paired by their
// CLOCK_MONOTONIC buffer timestamps. Next() polls both fds, drains each to its newest frame
// (CaptureDevice::DrainNewest), and pairs the newest left with the newest right when their
// timestamps differ by at most pair_tolerance_ns (keep it under half a frame period). Otherwise
// the older frame is dropped (counted in unpaired_left/unpaired_right) and the newer waits for a
// partner. Frames dropped by each driver are counted per camera from sequence gaps
// (left()/right() stats().sequence_drops). The result is always the newest pair available.
//
// Side-by-side: one device whose image holds both eyes (e.g. ZED: YUYV 2560x720 for two
// 1280x720 eyes); each frame is split at width/2, left half = left eye unless sbs_left_first is
// false. Both eyes carry the same timestamp (the sensors are hardware-synchronised).
//
// Errors are those of CaptureDevice (see capture.h). A disconnect of either camera returns
// kDisconnected; the next Next() reconnects it with back-off. No frame from a camera within
// timeout_ms counts a watchdog expiry on that camera and returns kTimeout.
// Ownership and thread-safety: as CaptureDevice; one thread drives a StereoCapture.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>

#include "sfrt/camera/v4l2/capture.h"

namespace sfrt::v4l2 {

struct StereoConfig {
  enum class Mode { kTwoDevices, kSideBySide };
  Mode mode = Mode::kTwoDevices;
  CaptureConfig left;   // kSideBySide: the one device, width = both eyes
  CaptureConfig right;  // kTwoDevices only
  int64_t pair_tolerance_ns = 8'000'000;
  bool sbs_left_first = true;
  int timeout_ms = 1000;  // per Next(): the watchdog for the pair
};

struct StereoPair {
  Frame left;
  Frame right;
  int64_t skew_ns = 0;  // left.timestamp_ns - right.timestamp_ns
  // CLOCK_MONOTONIC: when the pair formed (the later of the two frames was dequeued and matched)
  // and when both were converted to BGR (the latency attribution of pipeline/).
  int64_t paired_ns = 0;
  int64_t converted_ns = 0;
};

struct StereoStats {
  uint64_t pairs = 0;
  uint64_t unpaired_left = 0;   // left frames dropped for want of a right frame close in time
  uint64_t unpaired_right = 0;  // and the other way round
};

class StereoCapture {
 public:
  explicit StereoCapture(StereoConfig config, V4l2Syscalls& sys = LibcSyscalls());

  camera::Status Open();  // opens both devices (or the one side-by-side device)
  void Close();
  // Waits for and returns the newest pair (see the header comment).
  camera::Status Next(StereoPair* out);

  // CaptureDevice::set_cancel_flag for every device of the pair.
  void set_cancel_flag(const std::atomic<bool>* flag);

  const StereoConfig& config() const { return config_; }
  const StereoStats& stats() const { return stats_; }
  // kSideBySide: left() is the one device and right() must not be called.
  const CaptureDevice& left() const { return *devices_[0]; }
  const CaptureDevice& right() const { return *devices_[1]; }

 private:
  camera::Status NextSideBySide(StereoPair* out);

  StereoConfig config_;
  V4l2Syscalls& sys_;
  std::array<std::unique_ptr<CaptureDevice>, 2> devices_;
  std::array<RawFrame, 2> pending_;
  std::array<bool, 2> has_pending_{false, false};
  Frame sbs_frame_;
  StereoStats stats_;
};

}  // namespace sfrt::v4l2
