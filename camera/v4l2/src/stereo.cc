#include "sfrt/camera/v4l2/stereo.h"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <utility>

namespace sfrt::v4l2 {

using camera::ErrorKind;
using camera::Status;

namespace {
constexpr int64_t kNsPerMs = 1'000'000;
}  // namespace

StereoCapture::StereoCapture(StereoConfig config, V4l2Syscalls& sys)
    : config_(std::move(config)), sys_(sys) {
  devices_[0] = std::make_unique<CaptureDevice>(config_.left, sys_);
  if (config_.mode == StereoConfig::Mode::kTwoDevices) {
    devices_[1] = std::make_unique<CaptureDevice>(config_.right, sys_);
  }
}

Status StereoCapture::Open() {
  if (config_.timeout_ms <= 0 || config_.pair_tolerance_ns < 0) {
    return Status::Error(ErrorKind::kInvalidArgument,
                         "stereo config: timeout_ms " + std::to_string(config_.timeout_ms) +
                             " must be > 0 and pair_tolerance_ns " +
                             std::to_string(config_.pair_tolerance_ns) + " >= 0");
  }
  Status s = devices_[0]->Open();
  if (!s.ok() || !devices_[1]) return s;
  s = devices_[1]->Open();
  if (!s.ok()) devices_[0]->Close();
  return s;
}

void StereoCapture::Close() {
  for (auto& d : devices_) {
    if (d) d->Close();
  }
  has_pending_ = {false, false};
}

Status StereoCapture::NextSideBySide(StereoPair* out) {
  Status s = devices_[0]->Read(&sbs_frame_);
  if (!s.ok()) return s;
  s = SplitSideBySide(sbs_frame_, config_.sbs_left_first, &out->left, &out->right);
  if (!s.ok()) return s;
  out->skew_ns = 0;
  out->paired_ns = sbs_frame_.dequeue_ns;
  out->converted_ns = sys_.MonotonicNowNs();
  ++stats_.pairs;
  return Status::Ok();
}

void StereoCapture::set_cancel_flag(const std::atomic<bool>* flag) {
  for (auto& device : devices_) {
    if (device) device->set_cancel_flag(flag);
  }
}

Status StereoCapture::Next(StereoPair* out) {
  if (config_.mode == StereoConfig::Mode::kSideBySide) return NextSideBySide(out);

  for (int i = 0; i < 2; ++i) {
    if (devices_[i]->disconnected()) {
      has_pending_ = {false, false};
      Status s = devices_[i]->Reconnect();
      if (!s.ok()) return s;
    }
  }
  const int64_t deadline = sys_.MonotonicNowNs() + int64_t{config_.timeout_ms} * kNsPerMs;
  std::array<bool, 2> heard{false, false};
  int64_t last_skew = 0;
  bool tried_pair = false;
  for (;;) {
    const int64_t remaining = deadline - sys_.MonotonicNowNs();
    if (remaining <= 0) break;
    std::array<pollfd, 2> fds{};
    for (int i = 0; i < 2; ++i) fds[i] = pollfd{devices_[i]->fd(), POLLIN, 0};
    const int r = sys_.Poll(fds.data(), 2, static_cast<int>((remaining + kNsPerMs - 1) / kNsPerMs));
    if (r < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      return Status::Error(ErrorKind::kSystem, std::string("stereo poll: ") + std::strerror(err),
                           err);
    }
    if (r == 0) continue;
    for (int i = 0; i < 2; ++i) {
      if (fds[i].revents & POLLIN) {
        bool got = false;
        const bool had = has_pending_[i];
        Status s = devices_[i]->DrainNewest(&pending_[i], &got);
        if (!s.ok()) {
          has_pending_ = {false, false};
          return s;
        }
        if (got) {
          if (had) ++(i == 0 ? stats_.unpaired_left : stats_.unpaired_right);
          has_pending_[i] = true;
          heard[i] = true;
        }
      }
      if (fds[i].revents & (POLLERR | POLLHUP | POLLNVAL)) {
        has_pending_ = {false, false};
        return devices_[i]->OnPollError(fds[i].revents);
      }
    }
    while (has_pending_[0] && has_pending_[1]) {
      const int64_t skew = pending_[0].timestamp_ns - pending_[1].timestamp_ns;
      last_skew = skew;
      tried_pair = true;
      if (std::llabs(skew) <= config_.pair_tolerance_ns) {
        has_pending_ = {false, false};
        out->paired_ns = sys_.MonotonicNowNs();
        Status s = devices_[0]->Convert(pending_[0], &out->left);
        if (s.ok()) s = devices_[1]->Convert(pending_[1], &out->right);
        if (!s.ok()) return s;
        out->converted_ns = sys_.MonotonicNowNs();
        ++devices_[0]->stats_.frames_delivered;
        ++devices_[1]->stats_.frames_delivered;
        out->skew_ns = skew;
        ++stats_.pairs;
        return Status::Ok();
      }
      // Too far apart: the older frame can never find a partner; drop it.
      const int older = skew < 0 ? 0 : 1;
      has_pending_[older] = false;
      ++(older == 0 ? stats_.unpaired_left : stats_.unpaired_right);
    }
  }

  // Watchdog: charge the camera(s) that sent nothing.
  std::string msg;
  Status last;
  for (int i = 0; i < 2; ++i) {
    if (heard[i]) continue;
    last = devices_[i]->OnWatchdog(config_.timeout_ms);
    msg += (msg.empty() ? "" : "; ") + last.message();
  }
  if (msg.empty()) {
    msg = "stereo: no pair within " + std::to_string(config_.pair_tolerance_ns / 1000) + " us in " +
          std::to_string(config_.timeout_ms) + " ms";
    if (tried_pair) msg += " (last skew " + std::to_string(last_skew / 1000) + " us)";
  }
  return Status::Error(ErrorKind::kTimeout, msg);
}

}  // namespace sfrt::v4l2
