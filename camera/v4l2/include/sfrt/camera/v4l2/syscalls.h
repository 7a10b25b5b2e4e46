// The system-call seam under V4L2 capture. Everything the capture code does to a device goes
// through a V4l2Syscalls, so tests can put a fake device behind it (tests/camera/v4l2/) and the
// product uses the libc calls unchanged.
//
// Contract: each method behaves like the libc function of the same name: on failure it returns
// -1 (MAP_FAILED for Mmap) and sets errno. MonotonicNowNs is CLOCK_MONOTONIC, the clock V4L2
// stamps buffers with (V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC); SleepNs is used only for reconnect
// back-off, so a fake clock can make back-off instantaneous in tests.
//
// Thread-safety: LibcSyscalls() is stateless and may be used from any thread. Implementations
// used by several CaptureDevice objects on several threads must be thread-safe.
#pragma once

#include <poll.h>
#include <sys/types.h>

#include <cstddef>
#include <cstdint>

namespace sfrt::v4l2 {

class V4l2Syscalls {
 public:
  virtual ~V4l2Syscalls() = default;
  virtual int Open(const char* path, int flags) = 0;
  virtual int Close(int fd) = 0;
  virtual int Ioctl(int fd, unsigned long request, void* arg) = 0;
  virtual void* Mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) = 0;
  virtual int Munmap(void* addr, size_t length) = 0;
  virtual int Poll(pollfd* fds, nfds_t nfds, int timeout_ms) = 0;
  virtual int64_t MonotonicNowNs() = 0;
  virtual void SleepNs(int64_t ns) = 0;
};

// The production seam: ::open, ::close, ::ioctl, ::mmap, ::munmap, ::poll, clock_gettime and
// nanosleep. A process-wide object that lives forever.
V4l2Syscalls& LibcSyscalls();

}  // namespace sfrt::v4l2
