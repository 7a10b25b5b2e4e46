// V4L2 capture: one device streaming through memory-mapped buffers (V4L2_MEMORY_MMAP).
//
// Open() runs the canonical sequence (kernel Documentation/userspace-api/media/v4l/capture.c):
//   open(O_RDWR|O_NONBLOCK) -> QUERYCAP (VIDEO_CAPTURE + STREAMING, device_caps when present)
//   -> ENUM_FMT -> S_FMT (the driver's adjustment read back and reported) -> S_PARM/G_PARM
//   (frame rate granted read back) -> REQBUFS (what the driver grants, at least 2) -> QUERYBUF +
//   mmap per buffer -> QBUF all -> STREAMON.
// Close() undoes it: STREAMOFF, munmap, REQBUFS(0), close. Every ioctl is retried on EINTR.
//
// Newest-frame policy: Read()/ReadRaw() wait (poll) for a frame, then dequeue everything the
// driver has finished, keep only the newest, requeue the rest at once (counted in
// stats().stale_dropped) and requeue the newest after copying it out. No buffer is held between
// calls, so the driver always has every buffer but the one being copied, and a slow consumer
// gets the latest frame, never a queue of old ones.
//
// Errors are sfrt::camera::Status (sfrt/camera/status.h): a one-line message naming the device,
// the call and the value, an ErrorKind (below) and the errno of the failing call.
//
// Error policy (what each kernel error does):
//   EAGAIN from DQBUF        nothing (more) ready; poll again. Counted (eagain).
//   V4L2_BUF_FLAG_ERROR      the frame is skipped and requeued. Counted (error_flag_frames).
//   short bytesused (raw)    the frame is skipped and requeued. Counted (short_frames).
//   corrupt/short MJPEG      Read() returns kFrameError for that frame (the buffer is already
//                            requeued); the next Read() goes on. Counted (decode_errors).
//   sequence gaps            frames the driver dropped: seq - last - 1. Counted (sequence_drops).
//   EIO from DQBUF           counted (eio); buffers the driver neither holds nor has finished are
//                            found with QUERYBUF and requeued (eio_requeued), then polling goes on.
//   ENODEV/ENXIO, or POLLERR|POLLHUP confirmed by a failing ioctl: the device was unplugged.
//                            Resources are released, kDisconnected is returned once (counted:
//                            disconnects); each later Read() first sleeps the back-off (doubling
//                            from reopen_backoff_initial_ms to reopen_backoff_max_ms) and tries
//                            Open() again (reopen_attempts / reopens), returning its error if it
//                            fails.
//   poll timeout             the watchdog: kTimeout (watchdog_timeouts). After
//                            restart_after_timeouts consecutive expiries the stream is closed and
//                            reopened (stream_restarts).
//   ENOSPC at STREAMON       kNoBandwidth, with the USB bandwidth explanation.
//   EBUSY at open/S_FMT/REQBUFS  kBusy: another process has the device.
//
// Ownership: a CaptureDevice owns its fd and mappings; the V4l2Syscalls must outlive it.
// Frames handed out are copies owned by the caller. The destructor calls Close().
// Thread-safety: none inside; use one CaptureDevice from one thread at a time. Different
// CaptureDevice objects may run on different threads if their V4l2Syscalls is thread-safe.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "sfrt/camera/status.h"
#include "sfrt/camera/v4l2/pixel_format.h"
#include "sfrt/camera/v4l2/syscalls.h"

namespace sfrt::v4l2 {

struct CaptureConfig {
  std::string device = "/dev/video0";
  // V4L2 fourcc to request (e.g. V4L2_PIX_FMT_MJPEG); 0 = the first format the device lists
  // (ENUM_FMT order) that this module converts.
  uint32_t pixel_format = 0;
  int width = 640;
  int height = 480;
  double fps = 30.0;       // 0 = keep the driver's frame rate
  int buffer_count = 4;    // requested; the driver grants what it can (at least 2 are needed)
  int watchdog_ms = 1000;  // a Read() that sees no frame for this long returns kTimeout
  int restart_after_timeouts = 3;  // consecutive watchdog expiries before a stream restart
  int reopen_backoff_initial_ms = 100;
  int reopen_backoff_max_ms = 2000;
};

// What the driver actually granted.
struct NegotiatedFormat {
  uint32_t fourcc = 0;
  int width = 0;
  int height = 0;
  int bytesperline = 0;
  int sizeimage = 0;
  double fps = 0.0;  // 0 when the driver does not report a frame interval
  int buffer_count = 0;
  std::string driver, card, bus_info;
  // Human-readable differences from the request, "" when the driver granted everything, e.g.
  // "size 1000x700 -> 992x700; fps 45 -> 30".
  std::string adjustments;
};

// Counters since construction (they survive reopen).
struct CaptureStats {
  uint64_t frames_dequeued = 0;    // every successful DQBUF
  uint64_t frames_delivered = 0;   // frames returned by Read()/ReadRaw() or in a StereoCapture pair
  uint64_t stale_dropped = 0;      // older frames skipped to deliver the newest
  uint64_t sequence_drops = 0;     // frames the driver dropped (gaps in the sequence numbers)
  uint64_t error_flag_frames = 0;  // buffers dequeued with V4L2_BUF_FLAG_ERROR
  uint64_t short_frames = 0;       // raw buffers with bytesused below a full frame, or 0 bytes
  uint64_t decode_errors = 0;      // frames that failed conversion (corrupt or short MJPEG)
  uint64_t eagain = 0;             // DQBUF said "nothing ready"
  uint64_t eio = 0;                // DQBUF failed with EIO
  uint64_t eio_requeued = 0;       // buffers found lost after EIO and requeued
  uint64_t watchdog_timeouts = 0;  // polls that expired without a frame
  uint64_t stream_restarts = 0;    // close + open after repeated watchdog expiry
  uint64_t disconnects = 0;        // unplugs detected (ENODEV/ENXIO or POLLERR|POLLHUP)
  uint64_t reopen_attempts = 0;
  uint64_t reopens = 0;              // successful reopen after a disconnect
  uint64_t timestamp_fallbacks = 0;  // buffers without a monotonic timestamp (stamped at DQBUF)
  std::string last_error;            // the most recent error message, "" if none
};

class CaptureDevice {
 public:
  explicit CaptureDevice(CaptureConfig config, V4l2Syscalls& sys = LibcSyscalls());
  ~CaptureDevice();
  CaptureDevice(const CaptureDevice&) = delete;
  CaptureDevice& operator=(const CaptureDevice&) = delete;

  // Runs the canonical sequence up to STREAMON. On failure everything acquired is released.
  camera::Status Open();
  // STREAMOFF, munmap, REQBUFS(0), close. Safe to call twice and after an unplug.
  void Close();

  // Waits up to config().watchdog_ms for a frame and returns the newest one, converted to BGR.
  camera::Status Read(Frame* out);
  // As Read() without conversion (the copied bytes of the newest buffer).
  camera::Status ReadRaw(RawFrame* out);
  // Converts a frame this device produced (MJPEG decoding state lives here).
  camera::Status Convert(const RawFrame& raw, Frame* out);

  bool is_open() const { return fd_ >= 0; }
  // True after an unplug was detected and before a successful reopen.
  bool disconnected() const { return lost_; }
  const CaptureConfig& config() const { return config_; }
  const NegotiatedFormat& format() const { return format_; }
  const CaptureStats& stats() const { return stats_; }

  // Building blocks for multi-device loops (StereoCapture); Read() is made of these.
  int fd() const { return fd_; }
  // Dequeues every finished buffer without blocking; *got is true if *out now holds a newer
  // frame than before. Skipped buffers are requeued. Returns kDisconnected on unplug.
  camera::Status DrainNewest(RawFrame* out, bool* got);
  // Handles POLLERR/POLLHUP/POLLNVAL from poll(): confirms an unplug with an ioctl.
  camera::Status OnPollError(short revents);
  // Counts a watchdog expiry and restarts the stream after too many in a row.
  camera::Status OnWatchdog(int waited_ms);
  // Sleeps the current back-off and tries Open() once. Only valid when disconnected().
  camera::Status Reconnect();
  // While *flag is true, the reopen back-off ends early (it is slept in slices of at most
  // 20 ms) and Reconnect() returns kCancelled without an attempt, so a stop request is not held
  // up by up to reopen_backoff_max_ms. nullptr (the default): the back-off is always slept.
  void set_cancel_flag(const std::atomic<bool>* flag) { cancel_ = flag; }

 private:
  friend class StereoCapture;  // counts the frames it delivers in pairs (frames_delivered)
  camera::Status Setup();      // the canonical sequence after open(), up to STREAMON
  // Setup's steps in V4L2's order, each failing with the ioctl named and an ErrorKind.
  camera::Status QueryCapabilities();             // QUERYCAP: capture with streaming I/O
  camera::Status ChooseFourcc(uint32_t* fourcc);  // ENUM_FMT: the configured or first usable
  camera::Status SetFormat(uint32_t fourcc, std::string* notes);  // S_FMT, read back
  camera::Status SetFrameInterval(std::string* notes);            // S_PARM / G_PARM
  camera::Status MapBuffers(std::string* notes);                  // REQBUFS, QUERYBUF, mmap
  camera::Status StartStreaming();                                // QBUF each, STREAMON
  // A failed system call as an error of kind kDisconnected (the device is gone) or kSystem.
  camera::Status SysError(const char* call, int err) const;
  camera::Status WaitNewest(RawFrame* out);
  camera::Status Fail(camera::Status s);  // records s.message() in stats_.last_error and returns s
  camera::Status Lost(const std::string& what, int err);
  int Xioctl(unsigned long request, void* arg);
  camera::Status Requeue(uint32_t index);
  camera::Status RecoverAfterEio(int held_index);
  void ReleaseBuffers();

  struct Buffer {
    void* start = nullptr;
    size_t length = 0;
  };

  CaptureConfig config_;
  V4l2Syscalls& sys_;
  int fd_ = -1;
  bool streaming_ = false;
  bool lost_ = false;
  int64_t backoff_ns_ = 0;
  const std::atomic<bool>* cancel_ = nullptr;
  int consecutive_timeouts_ = 0;
  bool have_sequence_ = false;
  uint32_t last_sequence_ = 0;
  std::vector<Buffer> buffers_;
  NegotiatedFormat format_;
  CaptureStats stats_;
  PixelConverter converter_;
  RawFrame scratch_;  // Read()'s raw copy, reused so steady-state capture does not allocate
};

}  // namespace sfrt::v4l2
