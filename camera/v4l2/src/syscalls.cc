#include "sfrt/camera/v4l2/syscalls.h"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <ctime>

namespace sfrt::v4l2 {
namespace {

class LibcV4l2Syscalls final : public V4l2Syscalls {
 public:
  int Open(const char* path, int flags) override { return ::open(path, flags); }
  int Close(int fd) override { return ::close(fd); }
  int Ioctl(int fd, unsigned long request, void* arg) override { return ::ioctl(fd, request, arg); }
  void* Mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) override {
    return ::mmap(addr, length, prot, flags, fd, offset);
  }
  int Munmap(void* addr, size_t length) override { return ::munmap(addr, length); }
  int Poll(pollfd* fds, nfds_t nfds, int timeout_ms) override {
    return ::poll(fds, nfds, timeout_ms);
  }
  int64_t MonotonicNowNs() override {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
  }
  void SleepNs(int64_t ns) override {
    if (ns <= 0) return;
    timespec req{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
    timespec rem{};
    while (nanosleep(&req, &rem) != 0 && errno == EINTR) req = rem;
  }
};

}  // namespace

V4l2Syscalls& LibcSyscalls() {
  static LibcV4l2Syscalls* const sys = new LibcV4l2Syscalls();  // never destroyed
  return *sys;
}

}  // namespace sfrt::v4l2
