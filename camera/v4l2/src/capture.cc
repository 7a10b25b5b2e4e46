#include "sfrt/camera/v4l2/capture.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <utility>

namespace sfrt::v4l2 {

using camera::ErrorKind;
using camera::Status;

namespace {

constexpr int64_t kNsPerMs = 1'000'000;

// "ENOSPC (No space left on device)".
std::string ErrnoText(int err) {
  const char* name = strerrorname_np(err);
  const char* desc = strerrordesc_np(err);
  return std::string(name ? name : "errno " + std::to_string(err)) + " (" +
         (desc ? desc : "unknown error") + ")";
}

std::string FixedString(const uint8_t* chars, size_t n) {
  const char* s = reinterpret_cast<const char*>(chars);
  return std::string(s, strnlen(s, n));
}

std::string FpsText(double fps) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", fps);
  return buf;
}

bool IsGone(int err) { return err == ENODEV || err == ENXIO; }

}  // namespace

CaptureDevice::CaptureDevice(CaptureConfig config, V4l2Syscalls& sys)
    : config_(std::move(config)), sys_(sys) {}

CaptureDevice::~CaptureDevice() { Close(); }

Status CaptureDevice::Fail(Status s) {
  stats_.last_error = s.message();
  return s;
}

int CaptureDevice::Xioctl(unsigned long request, void* arg) {
  int r;
  do {
    r = sys_.Ioctl(fd_, request, arg);
  } while (r < 0 && errno == EINTR);
  return r;
}

Status CaptureDevice::Open() {
  const std::string& dev = config_.device;
  if (fd_ >= 0) return Fail(Status::Error(ErrorKind::kInvalidArgument, dev + ": already open"));
  if (config_.width <= 0 || config_.height <= 0 || config_.buffer_count < 2 ||
      config_.watchdog_ms <= 0 || config_.fps < 0) {
    return Fail(Status::Error(
        ErrorKind::kInvalidArgument,
        dev + ": invalid capture config: size " + std::to_string(config_.width) + "x" +
            std::to_string(config_.height) + ", buffer_count " +
            std::to_string(config_.buffer_count) + " (>= 2), watchdog_ms " +
            std::to_string(config_.watchdog_ms) + " (> 0), fps " + FpsText(config_.fps)));
  }
  const int fd = sys_.Open(dev.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    const std::string what = dev + ": open: " + ErrnoText(err);
    if (err == EBUSY) {
      return Fail(Status::Error(
          ErrorKind::kBusy,
          what + ": the device is in use by another process (see fuser " + dev + ")", err));
    }
    if (err == ENOENT || IsGone(err)) {
      return Fail(Status::Error(ErrorKind::kDisconnected, what + ": no such device", err));
    }
    if (err == EACCES) {
      return Fail(
          Status::Error(ErrorKind::kSystem, what + ": add the user to the 'video' group", err));
    }
    return Fail(Status::Error(ErrorKind::kSystem, what, err));
  }
  fd_ = fd;
  Status s = Setup();
  if (!s.ok()) {
    Close();
    return Fail(std::move(s));
  }
  return Status::Ok();
}

Status CaptureDevice::SysError(const char* call, int err) const {
  const ErrorKind kind = IsGone(err) ? ErrorKind::kDisconnected : ErrorKind::kSystem;
  return Status::Error(kind, config_.device + ": " + call + ": " + ErrnoText(err), err);
}

namespace {

// One more adjustment the driver made, for NegotiatedFormat::adjustments.
void AddNote(std::string* notes, const std::string& note) {
  *notes += (notes->empty() ? "" : "; ") + note;
}

}  // namespace

Status CaptureDevice::QueryCapabilities() {
  const std::string& dev = config_.device;
  // QUERYCAP: a video capture device with streaming I/O.
  v4l2_capability cap{};
  if (Xioctl(VIDIOC_QUERYCAP, &cap) < 0) {
    const int err = errno;
    if (err == EINVAL || err == ENOTTY) {
      return Status::Error(ErrorKind::kNotV4l2,
                           dev + ": VIDIOC_QUERYCAP: " + ErrnoText(err) + ": not a V4L2 device",
                           err);
    }
    return SysError("VIDIOC_QUERYCAP", err);
  }
  const uint32_t caps =
      (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
    char hex[16];
    std::snprintf(hex, sizeof hex, "0x%08x", caps);
    return Status::Error(ErrorKind::kNotV4l2,
                         dev + ": VIDIOC_QUERYCAP: device_caps " + hex +
                             " lack V4L2_CAP_VIDEO_CAPTURE (multi-planar-only and output "
                             "devices are not supported)");
  }
  if (!(caps & V4L2_CAP_STREAMING)) {
    return Status::Error(ErrorKind::kNotV4l2, dev +
                                                  ": VIDIOC_QUERYCAP: device lacks "
                                                  "V4L2_CAP_STREAMING (read() I/O is not "
                                                  "supported)");
  }
  format_.driver = FixedString(cap.driver, sizeof cap.driver);
  format_.card = FixedString(cap.card, sizeof cap.card);
  format_.bus_info = FixedString(cap.bus_info, sizeof cap.bus_info);

  return Status::Ok();
}

Status CaptureDevice::ChooseFourcc(uint32_t* fourcc) {
  const std::string& dev = config_.device;
  // ENUM_FMT: what the device offers, in its order of preference.
  std::vector<uint32_t> offered;
  for (uint32_t i = 0; i < 256; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (Xioctl(VIDIOC_ENUM_FMT, &desc) < 0) {
      if (errno == EINVAL) break;
      return SysError("VIDIOC_ENUM_FMT", errno);
    }
    offered.push_back(desc.pixelformat);
  }
  std::string offered_text;
  for (uint32_t f : offered) offered_text += (offered_text.empty() ? "" : ", ") + FourccToString(f);
  uint32_t want = config_.pixel_format;
  if (want == 0) {
    auto it = std::find_if(offered.begin(), offered.end(), IsSupportedFourcc);
    if (it == offered.end()) {
      return Status::Error(ErrorKind::kUnsupported,
                           dev + ": VIDIOC_ENUM_FMT: none of the offered formats [" + offered_text +
                               "] is supported (YUYV, MJPG, GREY, NV12, BGR3, RGB3)");
    }
    *fourcc = *it;
    return Status::Ok();
  } else if (!IsSupportedFourcc(want)) {
    return Status::Error(ErrorKind::kUnsupported, dev + ": pixel_format " + FourccToString(want) +
                                                      " is not one this module converts");
  } else if (std::find(offered.begin(), offered.end(), want) == offered.end()) {
    return Status::Error(ErrorKind::kUnsupported,
                         dev + ": VIDIOC_ENUM_FMT: pixel_format " + FourccToString(want) +
                             " is not offered; the device offers [" + offered_text + "]");
  }
  *fourcc = want;
  return Status::Ok();
}

Status CaptureDevice::SetFormat(uint32_t want, std::string* notes) {
  const std::string& dev = config_.device;
  // S_FMT: the driver may adjust anything; read back what it chose.
  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<uint32_t>(config_.width);
  fmt.fmt.pix.height = static_cast<uint32_t>(config_.height);
  fmt.fmt.pix.pixelformat = want;
  fmt.fmt.pix.field = V4L2_FIELD_ANY;
  if (Xioctl(VIDIOC_S_FMT, &fmt) < 0) {
    const int err = errno;
    if (err == EBUSY) {
      return Status::Error(ErrorKind::kBusy,
                           dev + ": VIDIOC_S_FMT: " + ErrnoText(err) +
                               ": the device is streaming for another process",
                           err);
    }
    return SysError("VIDIOC_S_FMT", err);
  }
  const v4l2_pix_format& pix = fmt.fmt.pix;
  if (pix.pixelformat != want) {
    if (!IsSupportedFourcc(pix.pixelformat)) {
      return Status::Error(ErrorKind::kUnsupported, dev + ": VIDIOC_S_FMT: the driver replaced " +
                                                        FourccToString(want) + " with " +
                                                        FourccToString(pix.pixelformat) +
                                                        ", which is not supported");
    }
    AddNote(notes, "format " + FourccToString(want) + " -> " + FourccToString(pix.pixelformat));
  }
  if (static_cast<int>(pix.width) != config_.width ||
      static_cast<int>(pix.height) != config_.height) {
    AddNote(notes, "size " + std::to_string(config_.width) + "x" + std::to_string(config_.height) +
                       " -> " + std::to_string(pix.width) + "x" + std::to_string(pix.height));
  }
  format_.fourcc = pix.pixelformat;
  format_.width = static_cast<int>(pix.width);
  format_.height = static_cast<int>(pix.height);
  if (format_.width <= 0 || format_.height <= 0) {
    return Status::Error(ErrorKind::kUnsupported, dev + ": VIDIOC_S_FMT: the driver set size " +
                                                      std::to_string(pix.width) + "x" +
                                                      std::to_string(pix.height));
  }
  // Buggy-driver paranoia (capture.c): a stride below the row size or an image size below
  // stride*height would make the converters read past the buffer.
  format_.bytesperline =
      std::max(static_cast<int>(pix.bytesperline), MinBytesPerLine(format_.fourcc, format_.width));
  format_.sizeimage =
      std::max<int>(static_cast<int>(pix.sizeimage),
                    static_cast<int>(RequiredBytes(format_.fourcc, format_.width, format_.height,
                                                   format_.bytesperline)));

  return Status::Ok();
}

Status CaptureDevice::SetFrameInterval(std::string* notes) {
  // S_PARM / G_PARM: the frame interval, when the driver lets us choose it.
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (Xioctl(VIDIOC_G_PARM, &parm) == 0) {
    if (config_.fps > 0 && (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME)) {
      v4l2_streamparm set{};
      set.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      set.parm.capture.timeperframe.numerator = 1000;
      set.parm.capture.timeperframe.denominator =
          static_cast<uint32_t>(std::lround(config_.fps * 1000.0));
      if (Xioctl(VIDIOC_S_PARM, &set) < 0) return SysError("VIDIOC_S_PARM", errno);
      parm = v4l2_streamparm{};
      parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      if (Xioctl(VIDIOC_G_PARM, &parm) < 0) return SysError("VIDIOC_G_PARM", errno);
    } else if (config_.fps > 0) {
      AddNote(notes, "fps " + FpsText(config_.fps) + " not settable (no V4L2_CAP_TIMEPERFRAME)");
    }
    const v4l2_fract tpf = parm.parm.capture.timeperframe;
    if (tpf.numerator != 0) format_.fps = static_cast<double>(tpf.denominator) / tpf.numerator;
    if (config_.fps > 0 && format_.fps > 0 && std::abs(format_.fps - config_.fps) > 0.01) {
      AddNote(notes, "fps " + FpsText(config_.fps) + " -> " + FpsText(format_.fps));
    }
  } else if (IsGone(errno)) {
    return SysError("VIDIOC_G_PARM", errno);
  }

  return Status::Ok();
}

Status CaptureDevice::MapBuffers(std::string* notes) {
  const std::string& dev = config_.device;
  // REQBUFS: the driver grants what it can.
  v4l2_requestbuffers req{};
  req.count = static_cast<uint32_t>(config_.buffer_count);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (Xioctl(VIDIOC_REQBUFS, &req) < 0) {
    const int err = errno;
    if (err == EINVAL) {
      return Status::Error(ErrorKind::kUnsupported,
                           dev + ": VIDIOC_REQBUFS: " + ErrnoText(err) +
                               ": memory-mapped streaming is not supported",
                           err);
    }
    if (err == EBUSY) {
      return Status::Error(
          ErrorKind::kBusy,
          dev + ": VIDIOC_REQBUFS: " + ErrnoText(err) + ": buffers are owned by another process",
          err);
    }
    return SysError("VIDIOC_REQBUFS", err);
  }
  buffers_.resize(req.count);  // from here on Close() releases them with REQBUFS(0)
  if (req.count < 2) {
    return Status::Error(ErrorKind::kUnsupported, dev + ": VIDIOC_REQBUFS: the driver granted " +
                                                      std::to_string(req.count) +
                                                      " buffers; streaming needs at least 2");
  }
  format_.buffer_count = static_cast<int>(req.count);
  if (format_.buffer_count != config_.buffer_count) {
    AddNote(notes, "buffers " + std::to_string(config_.buffer_count) + " -> " +
                       std::to_string(format_.buffer_count));
  }
  for (uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = i;
    if (Xioctl(VIDIOC_QUERYBUF, &b) < 0) return SysError("VIDIOC_QUERYBUF", errno);
    void* p = sys_.Mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_,
                        static_cast<off_t>(b.m.offset));
    if (p == MAP_FAILED) {
      const int err = errno;
      return Status::Error(ErrorKind::kSystem,
                           dev + ": mmap of buffer " + std::to_string(i) + " (" +
                               std::to_string(b.length) + " bytes at offset " +
                               std::to_string(b.m.offset) + "): " + ErrnoText(err),
                           err);
    }
    buffers_[i] = Buffer{p, b.length};
  }

  return Status::Ok();
}

Status CaptureDevice::StartStreaming() {
  const std::string& dev = config_.device;
  // Hand every buffer to the driver and start.
  for (uint32_t i = 0; i < static_cast<uint32_t>(buffers_.size()); ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = i;
    if (Xioctl(VIDIOC_QBUF, &b) < 0) return SysError("VIDIOC_QBUF", errno);
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (Xioctl(VIDIOC_STREAMON, &type) < 0) {
    const int err = errno;
    if (err == ENOSPC) {
      return Status::Error(
          ErrorKind::kNoBandwidth,
          dev + ": VIDIOC_STREAMON: " + ErrnoText(err) +
              ": the USB controller cannot reserve isochronous bandwidth for " +
              std::to_string(format_.width) + "x" + std::to_string(format_.height) + " " +
              FourccToString(format_.fourcc) + " at " + FpsText(format_.fps) +
              " fps; lower the resolution or frame rate, use MJPEG instead of raw YUYV, or "
              "put each camera on its own USB controller",
          err);
    }
    return SysError("VIDIOC_STREAMON", err);
  }
  return Status::Ok();
}

Status CaptureDevice::Setup() {
  format_ = NegotiatedFormat{};
  std::string notes;
  uint32_t fourcc = 0;
  if (Status s = QueryCapabilities(); !s.ok()) return s;
  if (Status s = ChooseFourcc(&fourcc); !s.ok()) return s;
  if (Status s = SetFormat(fourcc, &notes); !s.ok()) return s;
  if (Status s = SetFrameInterval(&notes); !s.ok()) return s;
  if (Status s = MapBuffers(&notes); !s.ok()) return s;
  if (Status s = StartStreaming(); !s.ok()) return s;
  streaming_ = true;
  have_sequence_ = false;
  consecutive_timeouts_ = 0;
  format_.adjustments = notes;
  return Status::Ok();
}

void CaptureDevice::ReleaseBuffers() {
  for (Buffer& b : buffers_) {
    if (b.start != nullptr) sys_.Munmap(b.start, b.length);
  }
  if (!buffers_.empty()) {
    v4l2_requestbuffers req{};
    req.count = 0;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    Xioctl(VIDIOC_REQBUFS, &req);  // fails with ENODEV after an unplug; nothing to do then
  }
  buffers_.clear();
}

void CaptureDevice::Close() {
  if (fd_ < 0) return;
  if (streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    Xioctl(VIDIOC_STREAMOFF, &type);  // returns every buffer to the dequeued state
    streaming_ = false;
  }
  ReleaseBuffers();
  sys_.Close(fd_);
  fd_ = -1;
}

Status CaptureDevice::Lost(const std::string& what, int err) {
  ++stats_.disconnects;
  Close();
  lost_ = true;
  backoff_ns_ = int64_t{config_.reopen_backoff_initial_ms} * kNsPerMs;
  return Fail(Status::Error(ErrorKind::kDisconnected,
                            config_.device + ": " + what + ": " + ErrnoText(err) +
                                ": the device was removed; reopening with back-off",
                            err));
}

Status CaptureDevice::Reconnect() {
  if (!lost_) return Status::Ok();
  constexpr int64_t kSliceNs = 20 * kNsPerMs;
  const auto cancelled = [this] { return cancel_ != nullptr && cancel_->load(); };
  for (int64_t left = backoff_ns_; left > 0 && !cancelled(); left -= kSliceNs) {
    sys_.SleepNs(std::min(left, kSliceNs));
  }
  if (cancelled()) {
    return Status::Error(ErrorKind::kCancelled,
                         config_.device + ": reopen back-off cancelled (stop requested)");
  }
  ++stats_.reopen_attempts;
  Status s = Open();
  if (s.ok()) {
    lost_ = false;
    ++stats_.reopens;
    return Status::Ok();
  }
  backoff_ns_ = std::min(backoff_ns_ * 2, int64_t{config_.reopen_backoff_max_ms} * kNsPerMs);
  return Fail(Status::Error(
      s.kind(),
      "reopen attempt " + std::to_string(stats_.reopen_attempts) + " failed: " + s.message(),
      s.sys_errno()));
}

Status CaptureDevice::Requeue(uint32_t index) {
  v4l2_buffer b{};
  b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b.memory = V4L2_MEMORY_MMAP;
  b.index = index;
  if (Xioctl(VIDIOC_QBUF, &b) < 0) {
    const int err = errno;
    if (IsGone(err)) return Lost("VIDIOC_QBUF", err);
    return Fail(Status::Error(
        ErrorKind::kIo,
        config_.device + ": VIDIOC_QBUF of buffer " + std::to_string(index) + ": " + ErrnoText(err),
        err));
  }
  return Status::Ok();
}

// After EIO the driver may have dequeued a buffer without telling us which (vidioc-qbuf.rst).
// Any buffer neither queued nor done (and not the one we hold) goes back to the driver.
Status CaptureDevice::RecoverAfterEio(int held_index) {
  for (uint32_t i = 0; i < buffers_.size(); ++i) {
    if (static_cast<int>(i) == held_index) continue;
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = i;
    if (Xioctl(VIDIOC_QUERYBUF, &b) < 0) {
      const int err = errno;
      if (IsGone(err)) return Lost("VIDIOC_QUERYBUF", err);
      continue;
    }
    if (!(b.flags & (V4L2_BUF_FLAG_QUEUED | V4L2_BUF_FLAG_DONE))) {
      Status s = Requeue(i);
      if (!s.ok()) return s;
      ++stats_.eio_requeued;
    }
  }
  return Status::Ok();
}

Status CaptureDevice::DrainNewest(RawFrame* out, bool* got) {
  *got = false;
  if (fd_ < 0) {
    return Fail(Status::Error(ErrorKind::kInvalidArgument, config_.device + ": not open"));
  }
  const size_t need =
      RequiredBytes(format_.fourcc, format_.width, format_.height, format_.bytesperline);
  bool holding = false;
  v4l2_buffer held{};
  int64_t held_dequeue_ns = 0;
  size_t eio_rounds = 0;
  for (;;) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    if (Xioctl(VIDIOC_DQBUF, &b) < 0) {
      const int err = errno;
      if (err == EAGAIN) {
        ++stats_.eagain;
        break;
      }
      if (IsGone(err)) return Lost("VIDIOC_DQBUF", err);
      if (err == EIO) {
        ++stats_.eio;
        stats_.last_error = config_.device + ": VIDIOC_DQBUF: " + ErrnoText(err);
        // The buffer we hold is dequeued by us, so the recovery must leave it alone.
        Status s = RecoverAfterEio(holding ? static_cast<int>(held.index) : -1);
        if (!s.ok()) return s;
        if (++eio_rounds > buffers_.size()) break;
        continue;
      }
      return Fail(
          Status::Error(ErrorKind::kIo, config_.device + ": VIDIOC_DQBUF: " + ErrnoText(err), err));
    }
    ++stats_.frames_dequeued;
    if (b.index >= buffers_.size()) {
      return Fail(Status::Error(
          ErrorKind::kIo, config_.device + ": VIDIOC_DQBUF returned buffer index " +
                              std::to_string(b.index) + " of " + std::to_string(buffers_.size())));
    }
    if (have_sequence_) {
      const uint32_t step = b.sequence - last_sequence_;  // wraps correctly at 2^32
      if (step > 1 && step < 0x80000000u) stats_.sequence_drops += step - 1;
    }
    have_sequence_ = true;
    last_sequence_ = b.sequence;

    bool usable = true;
    if (b.flags & V4L2_BUF_FLAG_ERROR) {
      ++stats_.error_flag_frames;
      usable = false;
    } else if (b.bytesused == 0 || b.bytesused > buffers_[b.index].length || b.bytesused < need) {
      ++stats_.short_frames;
      usable = false;
    }
    if (!usable) {
      Status s = Requeue(b.index);
      if (!s.ok()) return s;
      continue;
    }
    if (holding) {  // a newer frame supersedes the one we hold
      ++stats_.stale_dropped;
      Status s = Requeue(held.index);
      if (!s.ok()) return s;
    }
    held = b;
    holding = true;
    held_dequeue_ns = sys_.MonotonicNowNs();
  }
  if (!holding) return Status::Ok();

  // Copy out the newest frame, reading the metadata before the buffer goes back.
  const auto* start = static_cast<const uint8_t*>(buffers_[held.index].start);
  out->fourcc = format_.fourcc;
  out->width = format_.width;
  out->height = format_.height;
  out->bytesperline = MinBytesPerLine(format_.fourcc, format_.width) ? format_.bytesperline : 0;
  out->bytes.assign(start, start + held.bytesused);
  out->sequence = held.sequence;
  out->dequeue_ns = held_dequeue_ns;
  if ((held.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) {
    out->timestamp_ns =
        int64_t{held.timestamp.tv_sec} * 1'000'000'000 + int64_t{held.timestamp.tv_usec} * 1000;
  } else {
    out->timestamp_ns = sys_.MonotonicNowNs();
    ++stats_.timestamp_fallbacks;
  }
  *got = true;
  return Requeue(held.index);
}

Status CaptureDevice::OnPollError(short revents) {
  // POLLERR also means "not streaming" or "nothing queued" (func-poll.rst), so an unplug is
  // confirmed by an ioctl failing with ENODEV before the device is declared gone.
  v4l2_capability cap{};
  if (Xioctl(VIDIOC_QUERYCAP, &cap) < 0 && IsGone(errno)) {
    return Lost("poll returned POLLERR|POLLHUP, then VIDIOC_QUERYCAP", errno);
  }
  if (revents & POLLHUP) return Lost("poll returned POLLHUP", ENODEV);
  if (revents & POLLNVAL) {
    return Fail(Status::Error(ErrorKind::kSystem, config_.device + ": poll: POLLNVAL (fd " +
                                                      std::to_string(fd_) + " is not open)"));
  }
  return Fail(Status::Error(ErrorKind::kIo, config_.device +
                                                ": poll: POLLERR while streaming (no buffer "
                                                "queued or stream stopped by the driver)"));
}

Status CaptureDevice::OnWatchdog(int waited_ms) {
  ++stats_.watchdog_timeouts;
  ++consecutive_timeouts_;
  std::string msg = config_.device + ": no frame in " + std::to_string(waited_ms) +
                    " ms (watchdog, " + std::to_string(consecutive_timeouts_) + " in a row)";
  if (consecutive_timeouts_ >= config_.restart_after_timeouts) {
    ++stats_.stream_restarts;
    consecutive_timeouts_ = 0;
    Close();
    Status s = Open();
    if (s.ok()) {
      msg += "; stream restarted";
    } else {
      msg += "; stream restart failed: " + s.message();
      if (s.kind() == ErrorKind::kDisconnected) {
        ++stats_.disconnects;
        lost_ = true;
        backoff_ns_ = int64_t{config_.reopen_backoff_initial_ms} * kNsPerMs;
      }
    }
  }
  return Fail(Status::Error(ErrorKind::kTimeout, msg));
}

Status CaptureDevice::WaitNewest(RawFrame* out) {
  if (lost_) {
    Status s = Reconnect();
    if (!s.ok()) return s;
  }
  if (fd_ < 0) {
    return Fail(Status::Error(ErrorKind::kInvalidArgument, config_.device + ": not open"));
  }
  const int64_t deadline = sys_.MonotonicNowNs() + int64_t{config_.watchdog_ms} * kNsPerMs;
  for (;;) {
    const int64_t remaining = deadline - sys_.MonotonicNowNs();
    if (remaining <= 0) return OnWatchdog(config_.watchdog_ms);
    pollfd p{fd_, POLLIN, 0};
    const int r = sys_.Poll(&p, 1, static_cast<int>((remaining + kNsPerMs - 1) / kNsPerMs));
    if (r < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      return Fail(
          Status::Error(ErrorKind::kSystem, config_.device + ": poll: " + ErrnoText(err), err));
    }
    if (r == 0) continue;
    if (p.revents & POLLIN) {
      bool got = false;
      Status s = DrainNewest(out, &got);
      if (!s.ok()) return s;
      if (got) {
        consecutive_timeouts_ = 0;
        return Status::Ok();
      }
    }
    if (p.revents & (POLLERR | POLLHUP | POLLNVAL)) return OnPollError(p.revents);
  }
}

Status CaptureDevice::ReadRaw(RawFrame* out) {
  Status s = WaitNewest(out);
  if (s.ok()) ++stats_.frames_delivered;
  return s;
}

Status CaptureDevice::Convert(const RawFrame& raw, Frame* out) {
  Status s = converter_.ToBgr(raw, out);
  if (!s.ok()) {
    if (s.kind() == ErrorKind::kFrameError) ++stats_.decode_errors;
    return Fail(Status::Error(s.kind(), config_.device + ": " + s.message(), s.sys_errno()));
  }
  return s;
}

Status CaptureDevice::Read(Frame* out) {
  Status s = WaitNewest(&scratch_);
  if (!s.ok()) return s;
  s = Convert(scratch_, out);
  if (s.ok()) ++stats_.frames_delivered;
  return s;
}

}  // namespace sfrt::v4l2
