// A fake V4L2 capture device that honours the kernel's contract, behind the V4l2Syscalls seam.
//
// What it does as the kernel does (Documentation/userspace-api/media/v4l/):
// - open() gives a real fd (an eventfd) that poll()/select()/epoll see: it is readable exactly
//   when a finished buffer waits to be dequeued.
// - QUERYCAP (VIDEO_CAPTURE | STREAMING | DEVICE_CAPS), ENUM_FMT (the configured list, MJPEG
//   flagged compressed), G/S/TRY_FMT (unknown fourcc -> the default one, size clamped to the
//   supported range and made even, bytesperline rounded up to bytesperline_align, sizeimage
//   computed), G/S_PARM (frame rate clamped and rounded to an integer), REQBUFS (count clamped to
//   [min_buffers, max_buffers]; 0 frees; EBUSY while streaming, while mapped, or when another fd
//   owns the queue), QUERYBUF (page-aligned offsets; QUEUED/DONE/MAPPED flags), mmap (a real
//   mmap of a memfd, so the pixels are shared memory as with a driver), QBUF, DQBUF (EAGAIN on a
//   non-blocking fd when nothing is ready; EINVAL when not streaming), STREAMON/STREAMOFF.
// - Frames come at the configured rate from STREAMON (optionally phase-shifted and jittered),
//   each stamped with CLOCK_MONOTONIC time (V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) and a sequence
//   number that also counts frames dropped for lack of a queued buffer. Pixel data is the test
//   pattern (test_pattern.h) encoded in the current format, row padding filled with 0xAB.
// - Time is virtual by default: the clock only moves when the code under test polls or sleeps
//   (poll() with a timeout jumps to the next frame or the deadline), so tests are exact and
//   instant. ClockMode::kReal uses CLOCK_MONOTONIC and really sleeps (for the LD_PRELOAD shim).
//
// Fault knobs (FakeFaults), mirroring vivid's error injection: unplug (ENODEV on ioctls,
// POLLERR|POLLHUP on poll, ENOENT on open until Replug(); also by itself after N frames, with an
// optional timed replug), V4L2_BUF_FLAG_ERROR, dropped frames
// (sequence gaps), EIO on DQBUF (the buffer is lost as the kernel may do), EBUSY at open or
// S_FMT, ENOSPC at STREAMON, stalls (no frames at all), short and corrupt frames (raw and MJPEG),
// and EINTR on every ioctl (a signal arriving while the driver sleeps; off by default).
//
// Thread-safety: all V4l2Syscalls methods lock one mutex (poll() sleeps without it). Fault knobs
// and Unplug/Replug are meant to be changed between calls from the test thread.
// The fake's own system calls (mmap, munmap, close, poll) go straight to the kernel (syscall(2))
// so that the LD_PRELOAD shim, which interposes the libc names, can host it.
#pragma once

#include <linux/videodev2.h>

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "sfrt/camera/v4l2/syscalls.h"

namespace sfrt::v4l2::testing {

struct FakeDeviceConfig {
  std::string path = "/dev/video0";
  std::vector<uint32_t> formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_GREY,
                                   V4L2_PIX_FMT_NV12, V4L2_PIX_FMT_BGR24, V4L2_PIX_FMT_RGB24};
  int default_width = 640;
  int default_height = 480;
  int min_width = 32, max_width = 1920;
  int min_height = 16, max_height = 1080;
  int bytesperline_align = 64;
  uint32_t min_buffers = 2, max_buffers = 8;
  double default_fps = 30.0;
  double min_fps = 1.0, max_fps = 60.0;
  int64_t phase_ns = 0;   // frame k is due at STREAMON + phase + (k+1) * period (+ jitter)
  int64_t jitter_ns = 0;  // deterministic per-frame offset in [-jitter_ns, +jitter_ns]
  // Frame times on a grid shared by every device (multiples of the period since clock zero, plus
  // phase), as for cameras on one sensor clock, instead of counting from each STREAMON.
  bool align_to_epoch = false;
  int side = 0;               // pattern side (0 left, 1 right)
  bool side_by_side = false;  // render side 0 in the left half and side 1 in the right half
  uint32_t first_sequence = 0;
  bool monotonic_timestamps = true;  // false: V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN
  int jpeg_quality = 95;
  std::string card = "sfrt fake camera";
};

struct FakeFaults {
  int drop_next = 0;               // the next N frames are dropped (their sequence numbers skipped)
  int drop_every = 0;              // every Nth frame slot is dropped
  int error_flag_next = 0;         // the next N frames carry V4L2_BUF_FLAG_ERROR
  int short_next = 0;              // the next N frames have half their bytes (bytesused halved)
  int corrupt_jpeg_next = 0;       // the next N MJPEG frames have garbage in the entropy data
  int eio_next_dqbuf = 0;          // the next N DQBUFs with a frame ready fail with EIO, losing it
  bool busy_on_open = false;       // open() fails with EBUSY
  bool busy_on_s_fmt = false;      // S_FMT fails with EBUSY
  bool nospc_on_streamon = false;  // STREAMON fails with ENOSPC
  bool stalled = false;            // no frames are produced (sequence does not advance)
  // The device unplugs itself (as FakeDevice::Unplug) right after the Nth successful DQBUF from
  // now: that frame's data is handed out, then its fds see ENODEV and POLLERR|POLLHUP. Counted
  // down; 0 = never.
  int unplug_after_dqbufs = 0;
  // With unplug_after_dqbufs: the device comes back this long after that unplug (an open() from
  // then on succeeds, as after Replug(); the dead fds stay dead); < 0 = it stays away.
  int64_t replug_after_ns = -1;
  // Every ioctl on the device's live fds is interrupted once, as by a signal during the call: it
  // fails with EINTR, changing nothing, and only the immediate retry (the same request on the
  // same fd as the next ioctl) is served; any other ioctl in between is interrupted in its turn.
  // Counted in FakeDeviceStats::ioctls_interrupted.
  bool eintr_every_ioctl = false;
};

struct FakeDeviceStats {
  uint64_t frames_produced = 0;           // filled buffers
  uint64_t frames_dequeued = 0;           // successful DQBUFs
  uint64_t frames_dropped_by_knob = 0;    // drop_next / drop_every
  uint64_t frames_dropped_no_buffer = 0;  // slot passed with no buffer queued
  uint64_t opens = 0;
  uint64_t streamons = 0;
  // eintr_every_ioctl: the EINTRs returned, by ioctl name as in call_log() ("QUERYCAP", ...).
  std::map<std::string, uint64_t> ioctls_interrupted;
};

class FakeV4l2System;

class FakeDevice {
 public:
  const FakeDeviceConfig& config() const { return config_; }
  FakeFaults& faults() { return faults_; }
  const FakeDeviceStats& stats() const { return stats_; }
  // Removes the device: ioctls on its open fds fail with ENODEV, poll reports POLLERR|POLLHUP,
  // open() fails with ENOENT. Mappings stay valid until munmap, as in the kernel.
  void Unplug();
  // Brings the device back (new opens work; old fds stay dead), default format restored.
  void Replug();
  bool streaming() const { return streaming_; }
  uint32_t buffers_queued() const { return static_cast<uint32_t>(queued_.size()); }
  uint32_t buffers_done() const { return static_cast<uint32_t>(done_.size()); }
  uint32_t buffer_count() const { return static_cast<uint32_t>(bufs_.size()); }
  const v4l2_pix_format& format() const { return fmt_; }
  double fps() const { return fps_; }

 private:
  friend class FakeV4l2System;
  struct Buf {
    uint32_t offset = 0;
    enum State { kDequeued, kQueued, kDone } state = kDequeued;
    int mappings = 0;
    v4l2_buffer meta{};
  };
  FakeDevice(FakeV4l2System* sys, FakeDeviceConfig config);
  void ResetFormat();
  void FreeBuffers();
  void UnplugLocked();
  int64_t FrameDue(uint64_t slot) const;
  void Render(uint8_t* dst, uint32_t seq, v4l2_buffer* meta);
  void PatternAt(int x, int y, uint32_t seq, uint8_t* bgr) const;
  uint32_t RenderNv12(uint8_t* dst, uint32_t seq);
  uint32_t RenderJpeg(uint8_t* dst, uint32_t seq);

  FakeV4l2System* sys_;
  FakeDeviceConfig config_;
  FakeFaults faults_;
  FakeDeviceStats stats_;
  v4l2_pix_format fmt_{};
  double fps_ = 30.0;
  bool unplugged_ = false;
  int64_t replug_at_ = -1;  // unplug_after_dqbufs with replug_after_ns: when open() works again
  // eintr_every_ioctl: the ioctl just interrupted, which is served if it comes next (fd -1: none).
  int interrupted_fd_ = -1;
  unsigned long interrupted_request_ = 0;
  uint64_t generation_ = 0;
  int owner_fd_ = -1;
  int memfd_ = -1;
  uint8_t* mem_ = nullptr;
  size_t mem_size_ = 0;
  uint32_t buf_stride_ = 0;  // page-aligned distance between buffer offsets
  uint64_t bufset_ = 0;      // bumped whenever the buffers are freed
  std::vector<Buf> bufs_;
  std::deque<uint32_t> queued_, done_;
  bool streaming_ = false;
  int64_t stream_t0_ = 0;
  uint64_t slot_ = 0;
  uint32_t sequence_ = 0;
  std::vector<uint8_t> scratch_;  // BGR rendering for MJPEG
  void* jpeg_ = nullptr;          // tjhandle for compression
 public:
  ~FakeDevice();
};

class FakeV4l2System final : public V4l2Syscalls {
 public:
  enum class ClockMode { kVirtual, kReal };
  explicit FakeV4l2System(ClockMode mode = ClockMode::kVirtual);
  ~FakeV4l2System() override;

  FakeDevice& AddDevice(FakeDeviceConfig config);
  FakeDevice* Find(const std::string& path);
  bool IsFakeFd(int fd);
  bool IsFakeMapping(void* addr);
  // Virtual clock only: move time forward (frames due in between are produced lazily).
  void AdvanceClock(int64_t ns);
  int open_fds();
  int live_mappings();
  // Every call made, in order: "open", "close", "mmap", "munmap", "poll" and ioctl names
  // without the VIDIOC_ prefix ("QUERYCAP", "DQBUF", ...).
  std::vector<std::string> call_log();
  void clear_call_log();
  // Called after every SleepNs with the clock's time then, e.g. to raise a cancel flag at a
  // given moment of a back-off. Set before the code under test runs.
  void set_after_sleep(std::function<void(int64_t now_ns)> hook) { after_sleep_ = std::move(hook); }

  int Open(const char* path, int flags) override;
  int Close(int fd) override;
  int Ioctl(int fd, unsigned long request, void* arg) override;
  void* Mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) override;
  int Munmap(void* addr, size_t length) override;
  int Poll(pollfd* fds, nfds_t nfds, int timeout_ms) override;
  int64_t MonotonicNowNs() override;
  void SleepNs(int64_t ns) override;

 private:
  friend class FakeDevice;
  std::function<void(int64_t)> after_sleep_;
  struct File {
    FakeDevice* dev = nullptr;
    uint64_t generation = 0;
    bool nonblocking = false;
  };
  struct Mapping {
    FakeDevice* dev = nullptr;
    uint64_t bufset = 0;
    uint32_t index = 0;
    size_t length = 0;
  };
  // One ioctl on a fake device, as its handler sees it (Ioctl finds the handler in one table).
  struct IoctlCall {
    int fd;
    unsigned long request;
    void* arg;
    File& file;
    FakeDevice* dev;
    std::unique_lock<std::mutex>& lock;  // DQBUF on a blocking fd waits without it
  };
  int QueryCap(IoctlCall& c);
  int EnumFormat(IoctlCall& c);
  int GetFormat(IoctlCall& c);
  int SetFormat(IoctlCall& c);   // and TRY_FMT
  int StreamParm(IoctlCall& c);  // G_PARM and S_PARM
  int RequestBuffers(IoctlCall& c);
  int QueryBuffer(IoctlCall& c);
  int QueueBuffer(IoctlCall& c);
  int DequeueBuffer(IoctlCall& c);
  int Stream(IoctlCall& c);  // STREAMON and STREAMOFF
  int64_t NowLocked();
  void CatchUp(FakeDevice* dev);
  void ProduceSlot(FakeDevice* dev, int64_t due);
  void UpdateReadable(FakeDevice* dev);
  void Log(const char* what) { log_.emplace_back(what); }

  std::mutex mu_;
  ClockMode mode_;
  int64_t virtual_now_ = 1'000'000'000'000;  // 1000 s, so timestamps are clearly non-zero
  std::vector<std::unique_ptr<FakeDevice>> devices_;
  std::map<int, File> files_;
  std::map<void*, Mapping> mappings_;
  std::vector<std::string> log_;
};

}  // namespace sfrt::v4l2::testing
