// LD_PRELOAD shim: serves /dev/video* paths from the fake V4L2 device to an unmodified binary.
//
//   SFRT_FAKE_V4L2='/dev/video0:side=0;/dev/video1:side=1,phase_ms=2,drop_every=10'
//   LD_PRELOAD=libsfrt_fake_v4l2_preload.so some-capture-program   (both in the environment)
//
// Each ';'-separated entry is a path and optional comma-separated knobs: side (pattern 0/1),
// sbs (1 = side-by-side pattern), fps, phase_ms, jitter_ms, drop_every, stalled (1 = never
// delivers a frame), width, height (the defaults), formats (e.g. YUYV+MJPG+GREY, in ENUM_FMT
// order), unplug_after_frames=N (the device unplugs itself right after its Nth dequeued frame:
// ioctls on its fds fail with ENODEV, poll says POLLERR|POLLHUP, open() fails with ENOENT; once
// per process) and replug_after_ms=M (with unplug_after_frames: the device node comes back M ms
// after that unplug, so a reopen succeeds with a new stream; without it the device stays away).
// Frames come in real time, on a grid shared by all devices (align_to_epoch), like two cameras
// on one clock.
//
// Interposed: open, open64, openat, openat64, __open_2, __open64_2, close, ioctl, mmap, mmap64,
// munmap, poll. Calls on other paths/fds go straight to the kernel with syscall(2) (no dlsym, so
// no recursion through allocators that mmap). Not interposed: dup, select, epoll, read.
#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cstdarg>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>

#include "camera/v4l2/fake_v4l2.h"

namespace {

using sfrt::v4l2::testing::FakeDevice;
using sfrt::v4l2::testing::FakeDeviceConfig;
using sfrt::v4l2::testing::FakeV4l2System;

std::atomic<FakeV4l2System*> g_sys{nullptr};

uint32_t ParseFourcc(const std::string& s) {
  if (s.size() != 4) return 0;
  return v4l2_fourcc(s[0], s[1], s[2], s[3]);
}

FakeV4l2System* Create() {
  auto* sys = new FakeV4l2System(FakeV4l2System::ClockMode::kReal);  // lives for the process
  const char* env = std::getenv("SFRT_FAKE_V4L2");
  std::string spec = env ? env : "/dev/video0";
  size_t pos = 0;
  while (pos <= spec.size()) {
    size_t end = spec.find(';', pos);
    if (end == std::string::npos) end = spec.size();
    const std::string entry = spec.substr(pos, end - pos);
    pos = end + 1;
    if (entry.empty()) continue;
    FakeDeviceConfig c;
    c.align_to_epoch = true;
    const size_t colon = entry.find(':');
    c.path = entry.substr(0, colon);
    std::string knobs = colon == std::string::npos ? "" : entry.substr(colon + 1);
    int drop_every = 0;
    bool stalled = false;
    int unplug_after = 0;
    int64_t replug_after_ns = -1;
    size_t k = 0;
    while (k < knobs.size()) {
      size_t comma = knobs.find(',', k);
      if (comma == std::string::npos) comma = knobs.size();
      const std::string kv = knobs.substr(k, comma - k);
      k = comma + 1;
      const size_t eq = kv.find('=');
      if (eq == std::string::npos) continue;
      const std::string key = kv.substr(0, eq);
      const std::string val = kv.substr(eq + 1);
      const double num = std::atof(val.c_str());
      if (key == "side") c.side = static_cast<int>(num);
      if (key == "sbs") c.side_by_side = num != 0;
      if (key == "fps") c.default_fps = num;
      if (key == "phase_ms") c.phase_ns = static_cast<int64_t>(num * 1e6);
      if (key == "jitter_ms") c.jitter_ns = static_cast<int64_t>(num * 1e6);
      if (key == "drop_every") drop_every = static_cast<int>(num);
      if (key == "stalled") stalled = num != 0;
      if (key == "unplug_after_frames") unplug_after = static_cast<int>(num);
      if (key == "replug_after_ms") replug_after_ns = static_cast<int64_t>(num * 1e6);
      if (key == "width") c.default_width = static_cast<int>(num);
      if (key == "height") c.default_height = static_cast<int>(num);
      if (key == "formats") {
        c.formats.clear();
        for (size_t f = 0; f + 4 <= val.size(); f += 5)
          c.formats.push_back(ParseFourcc(val.substr(f, 4)));
      }
    }
    FakeDevice& device = sys->AddDevice(c);
    device.faults().drop_every = drop_every;
    device.faults().stalled = stalled;
    device.faults().unplug_after_dqbufs = unplug_after;
    device.faults().replug_after_ns = replug_after_ns;
  }
  return sys;
}

FakeV4l2System* Sys() {
  static std::once_flag once;
  std::call_once(once, [] { g_sys.store(Create()); });
  return g_sys.load();
}

bool Served(const char* path) {
  if (path == nullptr || std::strncmp(path, "/dev/video", 10) != 0) return false;
  return Sys()->Find(path) != nullptr;
}

bool IsFake(int fd) {
  FakeV4l2System* sys = g_sys.load();
  return fd >= 0 && sys != nullptr && sys->IsFakeFd(fd);
}

mode_t ModeArg(int flags, va_list ap) {
  return (flags & (O_CREAT | O_TMPFILE)) ? static_cast<mode_t>(va_arg(ap, int)) : 0;
}

int RealOpenat(int dirfd, const char* path, int flags, mode_t mode) {
  return static_cast<int>(syscall(SYS_openat, dirfd, path, flags, mode));
}

}  // namespace

extern "C" {

__attribute__((visibility("default"))) int open(const char* path, int flags, ...) {
  va_list ap;
  va_start(ap, flags);
  const mode_t mode = ModeArg(flags, ap);
  va_end(ap);
  if (Served(path)) return Sys()->Open(path, flags);
  return RealOpenat(AT_FDCWD, path, flags, mode);
}

__attribute__((visibility("default"))) int open64(const char* path, int flags, ...) {
  va_list ap;
  va_start(ap, flags);
  const mode_t mode = ModeArg(flags, ap);
  va_end(ap);
  if (Served(path)) return Sys()->Open(path, flags);
  return RealOpenat(AT_FDCWD, path, flags | O_LARGEFILE, mode);
}

__attribute__((visibility("default"))) int __open_2(const char* path, int flags) {
  if (Served(path)) return Sys()->Open(path, flags);
  return RealOpenat(AT_FDCWD, path, flags, 0);
}

__attribute__((visibility("default"))) int __open64_2(const char* path, int flags) {
  if (Served(path)) return Sys()->Open(path, flags);
  return RealOpenat(AT_FDCWD, path, flags | O_LARGEFILE, 0);
}

__attribute__((visibility("default"))) int openat(int dirfd, const char* path, int flags, ...) {
  va_list ap;
  va_start(ap, flags);
  const mode_t mode = ModeArg(flags, ap);
  va_end(ap);
  if (Served(path)) return Sys()->Open(path, flags);
  return RealOpenat(dirfd, path, flags, mode);
}

__attribute__((visibility("default"))) int openat64(int dirfd, const char* path, int flags, ...) {
  va_list ap;
  va_start(ap, flags);
  const mode_t mode = ModeArg(flags, ap);
  va_end(ap);
  if (Served(path)) return Sys()->Open(path, flags);
  return RealOpenat(dirfd, path, flags | O_LARGEFILE, mode);
}

__attribute__((visibility("default"))) int close(int fd) {
  if (IsFake(fd)) return g_sys.load()->Close(fd);
  return static_cast<int>(syscall(SYS_close, fd));
}

__attribute__((visibility("default"))) int ioctl(int fd, unsigned long request, ...) {
  va_list ap;
  va_start(ap, request);
  void* arg = va_arg(ap, void*);
  va_end(ap);
  if (IsFake(fd)) return g_sys.load()->Ioctl(fd, request, arg);
  return static_cast<int>(syscall(SYS_ioctl, fd, request, arg));
}

__attribute__((visibility("default"))) void* mmap(void* addr, size_t length, int prot, int flags,
                                                  int fd, off_t offset) {
  if (IsFake(fd)) return g_sys.load()->Mmap(addr, length, prot, flags, fd, offset);
  return reinterpret_cast<void*>(syscall(SYS_mmap, addr, length, prot, flags, fd, offset));
}

__attribute__((visibility("default"))) void* mmap64(void* addr, size_t length, int prot, int flags,
                                                    int fd, off_t offset) {
  return mmap(addr, length, prot, flags, fd, offset);
}

__attribute__((visibility("default"))) int munmap(void* addr, size_t length) {
  FakeV4l2System* sys = g_sys.load();
  if (sys != nullptr && sys->IsFakeMapping(addr)) return sys->Munmap(addr, length);
  return static_cast<int>(syscall(SYS_munmap, addr, length));
}

__attribute__((visibility("default"))) int poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  bool any_fake = false;
  for (nfds_t i = 0; i < nfds; ++i) any_fake = any_fake || IsFake(fds[i].fd);
  if (any_fake) return g_sys.load()->Poll(fds, nfds, timeout_ms);
  if (timeout_ms < 0) return static_cast<int>(syscall(SYS_ppoll, fds, nfds, nullptr, nullptr, 0));
  timespec ts{timeout_ms / 1000, static_cast<long>(timeout_ms % 1000) * 1'000'000};
  return static_cast<int>(syscall(SYS_ppoll, fds, nfds, &ts, nullptr, 0));
}

}  // extern "C"
