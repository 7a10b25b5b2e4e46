#include "fake_v4l2.h"

#include <fcntl.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <sys/syscall.h>
#include <turbojpeg.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>

#include "camera/v4l2/test_pattern.h"

namespace sfrt::v4l2::testing {
namespace {

constexpr int64_t kNsPerSec = 1'000'000'000;

// The fake's own system calls bypass libc so an LD_PRELOAD shim hosting it does not recurse.
void* RawMmap(void* addr, size_t len, int prot, int flags, int fd, off_t off) {
  return reinterpret_cast<void*>(syscall(SYS_mmap, addr, len, prot, flags, fd, off));
}
int RawMunmap(void* addr, size_t len) { return static_cast<int>(syscall(SYS_munmap, addr, len)); }
int RawClose(int fd) { return static_cast<int>(syscall(SYS_close, fd)); }
int RawPoll(pollfd* fds, nfds_t n, int64_t timeout_ns) {
  timespec ts{static_cast<time_t>(timeout_ns / kNsPerSec),
              static_cast<long>(timeout_ns % kNsPerSec)};
  return static_cast<int>(syscall(SYS_ppoll, fds, n, &ts, nullptr, 0));
}
int64_t RealNow() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t{ts.tv_sec} * kNsPerSec + ts.tv_nsec;
}

int Fail(int err) {
  errno = err;
  return -1;
}

uint32_t RoundUp(uint32_t v, uint32_t a) { return a ? (v + a - 1) / a * a : v; }

bool IsJpeg(uint32_t f) { return f == V4L2_PIX_FMT_MJPEG || f == V4L2_PIX_FMT_JPEG; }

uint32_t MinRow(uint32_t fourcc, uint32_t w) {
  switch (fourcc) {
    case V4L2_PIX_FMT_YUYV:
      return 2 * w;
    case V4L2_PIX_FMT_BGR24:
    case V4L2_PIX_FMT_RGB24:
      return 3 * w;
    case V4L2_PIX_FMT_GREY:
    case V4L2_PIX_FMT_NV12:
      return w;
    default:
      return 0;
  }
}

const char* IoctlName(unsigned long request) {
  switch (request) {
    case VIDIOC_QUERYCAP:
      return "QUERYCAP";
    case VIDIOC_ENUM_FMT:
      return "ENUM_FMT";
    case VIDIOC_G_FMT:
      return "G_FMT";
    case VIDIOC_S_FMT:
      return "S_FMT";
    case VIDIOC_TRY_FMT:
      return "TRY_FMT";
    case VIDIOC_G_PARM:
      return "G_PARM";
    case VIDIOC_S_PARM:
      return "S_PARM";
    case VIDIOC_REQBUFS:
      return "REQBUFS";
    case VIDIOC_QUERYBUF:
      return "QUERYBUF";
    case VIDIOC_QBUF:
      return "QBUF";
    case VIDIOC_DQBUF:
      return "DQBUF";
    case VIDIOC_STREAMON:
      return "STREAMON";
    case VIDIOC_STREAMOFF:
      return "STREAMOFF";
    default:
      return "ioctl?";
  }
}

// Deterministic per-frame jitter in [-range, +range] (splitmix64 of the slot).
int64_t Jitter(uint64_t slot, int64_t range) {
  if (range <= 0) return 0;
  uint64_t z = slot + 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  z ^= z >> 31;
  return static_cast<int64_t>(z % static_cast<uint64_t>(2 * range + 1)) - range;
}

}  // namespace

// ---------------------------------------------------------------------------------- device

FakeDevice::FakeDevice(FakeV4l2System* sys, FakeDeviceConfig config)
    : sys_(sys), config_(std::move(config)) {
  ResetFormat();
}

FakeDevice::~FakeDevice() {
  FreeBuffers();
  if (jpeg_ != nullptr) tjDestroy(static_cast<tjhandle>(jpeg_));
}

void FakeDevice::ResetFormat() {
  fmt_ = v4l2_pix_format{};
  fmt_.pixelformat = config_.formats.empty() ? V4L2_PIX_FMT_YUYV : config_.formats[0];
  fmt_.width = static_cast<uint32_t>(config_.default_width);
  fmt_.height = static_cast<uint32_t>(config_.default_height);
  fps_ = config_.default_fps;
  // Fill in bytesperline/sizeimage the way S_FMT does.
  v4l2_pix_format p = fmt_;
  const uint32_t row = MinRow(p.pixelformat, p.width);
  p.bytesperline = row ? RoundUp(row, static_cast<uint32_t>(config_.bytesperline_align)) : 0;
  p.sizeimage = row ? p.bytesperline * p.height : p.width * p.height * 3;
  fmt_ = p;
}

void FakeDevice::FreeBuffers() {
  if (mem_ != nullptr) RawMunmap(mem_, mem_size_);
  if (memfd_ >= 0) RawClose(memfd_);
  mem_ = nullptr;
  memfd_ = -1;
  mem_size_ = 0;
  bufs_.clear();
  queued_.clear();
  done_.clear();
  ++bufset_;
}

int64_t FakeDevice::FrameDue(uint64_t slot) const {
  const int64_t period = std::llround(1e9 / fps_);
  return stream_t0_ + config_.phase_ns + static_cast<int64_t>(slot + 1) * period +
         Jitter(slot, config_.jitter_ns);
}

// Rows of the pattern depend on y / 8 only (test_pattern.h), so a packed format renders the first
// row of each 8-row block and copies it: the same bytes at a fraction of the cost, which the
// capture thread pays while it polls (a real driver fills buffers by DMA).
namespace {

// The packed formats' rows: each 8-row block's first row written by write_row(y, row) over
// padding bytes of 0xAB, the other rows copies of it (the pattern is flat over 8-row blocks).
template <typename WriteRow>
void FillBlockRows(uint8_t* dst, size_t bpl, int h, WriteRow write_row) {
  for (int y = 0; y < h; ++y) {
    uint8_t* row = dst + y * bpl;
    if (y % 8 != 0) {
      std::memcpy(row, row - bpl, bpl);
      continue;
    }
    std::memset(row, 0xAB, bpl);
    write_row(y, row);
  }
}

uint8_t Grey(const uint8_t* c) {
  return static_cast<uint8_t>((29 * c[0] + 150 * c[1] + 77 * c[2] + 128) >> 8);
}

}  // namespace

// Pixel (x, y) of frame `seq` in BGR: one camera's pattern, or a side-by-side frame's halves.
void FakeDevice::PatternAt(int x, int y, uint32_t seq, uint8_t* bgr) const {
  if (!config_.side_by_side) {
    PatternBgr(x, y, seq, config_.side, bgr);
    return;
  }
  const int half = static_cast<int>(fmt_.width) / 2;
  if (x < half) {
    PatternBgr(x, y, seq, 0, bgr);
  } else {
    PatternBgr(x - half, y, seq, 1, bgr);
  }
}

void FakeDevice::Render(uint8_t* dst, uint32_t seq, v4l2_buffer* meta) {
  const int w = static_cast<int>(fmt_.width);
  const int h = static_cast<int>(fmt_.height);
  const size_t bpl = fmt_.bytesperline;
  uint8_t c[3], c2[3];
  switch (fmt_.pixelformat) {
    case V4L2_PIX_FMT_BGR24:
    case V4L2_PIX_FMT_RGB24: {
      const bool rgb = fmt_.pixelformat == V4L2_PIX_FMT_RGB24;
      FillBlockRows(dst, bpl, h, [&](int y, uint8_t* row) {
        for (int x = 0; x < w; ++x) {
          PatternAt(x, y, seq, c);
          row[3 * x] = rgb ? c[2] : c[0];
          row[3 * x + 1] = c[1];
          row[3 * x + 2] = rgb ? c[0] : c[2];
        }
      });
      meta->bytesused = static_cast<uint32_t>(bpl * h);
      return;
    }
    case V4L2_PIX_FMT_GREY:
      FillBlockRows(dst, bpl, h, [&](int y, uint8_t* row) {
        for (int x = 0; x < w; ++x) {
          PatternAt(x, y, seq, c);
          row[x] = Grey(c);
        }
      });
      meta->bytesused = static_cast<uint32_t>(bpl * h);
      return;
    case V4L2_PIX_FMT_YUYV:
      FillBlockRows(dst, bpl, h, [&](int y, uint8_t* row) {
        for (int x = 0; x + 1 < w; x += 2) {
          PatternAt(x, y, seq, c);
          PatternAt(x + 1, y, seq, c2);
          int y0, cb0, cr0, y1, cb1, cr1;
          BgrToYuv601(c, &y0, &cb0, &cr0);
          BgrToYuv601(c2, &y1, &cb1, &cr1);
          uint8_t* g = row + 2 * x;
          g[0] = static_cast<uint8_t>(y0);
          g[1] = static_cast<uint8_t>((cb0 + cb1 + 1) / 2);
          g[2] = static_cast<uint8_t>(y1);
          g[3] = static_cast<uint8_t>((cr0 + cr1 + 1) / 2);
        }
      });
      meta->bytesused = static_cast<uint32_t>(bpl * h);
      return;
    case V4L2_PIX_FMT_NV12:
      meta->bytesused = RenderNv12(dst, seq);
      return;
    case V4L2_PIX_FMT_MJPEG:
    case V4L2_PIX_FMT_JPEG:
      meta->bytesused = RenderJpeg(dst, seq);
      return;
    default:
      meta->bytesused = 0;
  }
}

// NV12: the Y plane, then the interleaved Cb, Cr plane at half resolution (each the rounded
// mean of its 2x2 pixels'). Returns the bytes used.
uint32_t FakeDevice::RenderNv12(uint8_t* dst, uint32_t seq) {
  const int w = static_cast<int>(fmt_.width);
  const int h = static_cast<int>(fmt_.height);
  const size_t bpl = fmt_.bytesperline;
  uint8_t c[3];
  uint8_t* uv_plane = dst + bpl * h;
  for (int y = 0; y < h; ++y) {
    uint8_t* row = dst + y * bpl;
    std::memset(row, 0xAB, bpl);
    for (int x = 0; x < w; ++x) {
      PatternAt(x, y, seq, c);
      int yy, cb, cr;
      BgrToYuv601(c, &yy, &cb, &cr);
      row[x] = static_cast<uint8_t>(yy);
    }
  }
  for (int y = 0; y < h / 2; ++y) {
    uint8_t* row = uv_plane + y * bpl;
    std::memset(row, 0xAB, bpl);
    for (int x = 0; x + 1 < w; x += 2) {
      int sum_cb = 0, sum_cr = 0;
      for (int k = 0; k < 4; ++k) {
        PatternAt(x + k % 2, 2 * y + k / 2, seq, c);
        int yy, cb, cr;
        BgrToYuv601(c, &yy, &cb, &cr);
        sum_cb += cb;
        sum_cr += cr;
      }
      row[x] = static_cast<uint8_t>((sum_cb + 2) / 4);
      row[x + 1] = static_cast<uint8_t>((sum_cr + 2) / 4);
    }
  }
  return static_cast<uint32_t>(bpl * h * 3 / 2);
}

// MJPEG / JPEG: the frame compressed by TurboJPEG (4:4:4) into the buffer. Returns the bytes
// used (0 where it does not fit).
uint32_t FakeDevice::RenderJpeg(uint8_t* dst, uint32_t seq) {
  const int w = static_cast<int>(fmt_.width);
  const int h = static_cast<int>(fmt_.height);
  scratch_.resize(static_cast<size_t>(w) * h * 3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x)
      PatternAt(x, y, seq, &scratch_[(static_cast<size_t>(y) * w + x) * 3]);
  }
  if (jpeg_ == nullptr) jpeg_ = tjInitCompress();
  unsigned char* out = dst;
  unsigned long size = fmt_.sizeimage;
  if (tjCompress2(static_cast<tjhandle>(jpeg_), scratch_.data(), w, 0, h, TJPF_BGR, &out, &size,
                  TJSAMP_444, config_.jpeg_quality, TJFLAG_NOREALLOC) != 0) {
    size = 0;
  }
  return static_cast<uint32_t>(size);
}

void FakeDevice::Unplug() {
  std::lock_guard<std::mutex> lock(sys_->mu_);
  UnplugLocked();
}

void FakeDevice::UnplugLocked() {
  unplugged_ = true;
  ++generation_;
  streaming_ = false;
  owner_fd_ = -1;
  FreeBuffers();
  // Wake anyone sleeping in select()/epoll on the dead fds.
  for (auto& [fd, file] : sys_->files_) {
    if (file.dev == this) eventfd_write(fd, 1);
  }
}

void FakeDevice::Replug() {
  std::lock_guard<std::mutex> lock(sys_->mu_);
  unplugged_ = false;
  replug_at_ = -1;
  ResetFormat();
}

// ---------------------------------------------------------------------------------- system

FakeV4l2System::FakeV4l2System(ClockMode mode) : mode_(mode) {}

FakeV4l2System::~FakeV4l2System() {
  for (auto& [fd, file] : files_) RawClose(fd);
  for (auto& [addr, m] : mappings_) RawMunmap(addr, m.length);
}

FakeDevice& FakeV4l2System::AddDevice(FakeDeviceConfig config) {
  std::lock_guard<std::mutex> lock(mu_);
  devices_.push_back(std::unique_ptr<FakeDevice>(new FakeDevice(this, std::move(config))));
  return *devices_.back();
}

FakeDevice* FakeV4l2System::Find(const std::string& path) {
  for (auto& d : devices_) {
    if (d->config_.path == path) return d.get();
  }
  return nullptr;
}

bool FakeV4l2System::IsFakeFd(int fd) {
  std::lock_guard<std::mutex> lock(mu_);
  return files_.count(fd) != 0;
}

bool FakeV4l2System::IsFakeMapping(void* addr) {
  std::lock_guard<std::mutex> lock(mu_);
  return mappings_.count(addr) != 0;
}

void FakeV4l2System::AdvanceClock(int64_t ns) {
  std::lock_guard<std::mutex> lock(mu_);
  if (mode_ == ClockMode::kVirtual) virtual_now_ += ns;
}

int FakeV4l2System::open_fds() {
  std::lock_guard<std::mutex> lock(mu_);
  return static_cast<int>(files_.size());
}

int FakeV4l2System::live_mappings() {
  std::lock_guard<std::mutex> lock(mu_);
  return static_cast<int>(mappings_.size());
}

std::vector<std::string> FakeV4l2System::call_log() {
  std::lock_guard<std::mutex> lock(mu_);
  return log_;
}

void FakeV4l2System::clear_call_log() {
  std::lock_guard<std::mutex> lock(mu_);
  log_.clear();
}

int64_t FakeV4l2System::NowLocked() {
  return mode_ == ClockMode::kVirtual ? virtual_now_ : RealNow();
}

int64_t FakeV4l2System::MonotonicNowNs() {
  std::lock_guard<std::mutex> lock(mu_);
  return NowLocked();
}

void FakeV4l2System::SleepNs(int64_t ns) {
  if (ns <= 0) return;
  bool slept = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (mode_ == ClockMode::kVirtual) {
      virtual_now_ += ns;
      slept = true;
    }
  }
  if (!slept) RawPoll(nullptr, 0, ns);
  if (after_sleep_) after_sleep_(MonotonicNowNs());
}

void FakeV4l2System::UpdateReadable(FakeDevice* dev) {
  for (auto& [fd, file] : files_) {
    if (file.dev != dev || file.generation != dev->generation_) continue;
    eventfd_t value;
    eventfd_read(fd, &value);  // non-blocking: empties the counter if set
    if (!dev->done_.empty()) eventfd_write(fd, 1);
  }
}

void FakeV4l2System::ProduceSlot(FakeDevice* dev, int64_t due) {
  FakeFaults& f = dev->faults_;
  const uint64_t slot = dev->slot_;
  if (f.stalled) return;  // the sensor sends nothing: no frame, no sequence number
  const uint32_t seq = dev->sequence_++;
  if (f.drop_next > 0) {
    --f.drop_next;
    ++dev->stats_.frames_dropped_by_knob;
    return;
  }
  if (f.drop_every > 0 && (slot + 1) % static_cast<uint64_t>(f.drop_every) == 0) {
    ++dev->stats_.frames_dropped_by_knob;
    return;
  }
  if (dev->queued_.empty()) {
    ++dev->stats_.frames_dropped_no_buffer;
    return;
  }
  const uint32_t index = dev->queued_.front();
  dev->queued_.pop_front();
  FakeDevice::Buf& b = dev->bufs_[index];
  v4l2_buffer& m = b.meta;
  m = v4l2_buffer{};
  m.index = index;
  m.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  m.memory = V4L2_MEMORY_MMAP;
  m.field = V4L2_FIELD_NONE;
  m.length = dev->fmt_.sizeimage;
  m.m.offset = b.offset;
  m.sequence = seq;
  m.timestamp.tv_sec = due / kNsPerSec;
  m.timestamp.tv_usec = (due % kNsPerSec) / 1000;
  m.flags = (dev->config_.monotonic_timestamps ? V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC
                                               : V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN) |
            V4L2_BUF_FLAG_TSTAMP_SRC_EOF;
  uint8_t* data = dev->mem_ + b.offset;
  dev->Render(data, seq, &m);
  if (f.error_flag_next > 0) {
    --f.error_flag_next;
    m.flags |= V4L2_BUF_FLAG_ERROR;
  }
  if (f.short_next > 0) {
    --f.short_next;
    m.bytesused /= 2;
  }
  if (f.corrupt_jpeg_next > 0 && IsJpeg(dev->fmt_.pixelformat) && m.bytesused > 64) {
    --f.corrupt_jpeg_next;
    // Garbage in the middle of the entropy-coded data: a marker (0xFF 0xD9, end of image) and
    // a run of impossible codes.
    const uint32_t mid = m.bytesused / 2;
    for (uint32_t i = 0; i < 32; ++i) data[mid + i] = static_cast<uint8_t>(i % 2 ? 0xD9 : 0xFF);
  }
  b.state = FakeDevice::Buf::kDone;
  dev->done_.push_back(index);
  ++dev->stats_.frames_produced;
}

void FakeV4l2System::CatchUp(FakeDevice* dev) {
  if (!dev->streaming_ || dev->unplugged_) return;
  const int64_t now = NowLocked();
  const size_t done_before = dev->done_.size();
  while (dev->FrameDue(dev->slot_) <= now) {
    ProduceSlot(dev, dev->FrameDue(dev->slot_));
    ++dev->slot_;
  }
  if (dev->done_.size() != done_before) UpdateReadable(dev);
}

int FakeV4l2System::Open(const char* path, int flags) {
  std::lock_guard<std::mutex> lock(mu_);
  Log("open");
  FakeDevice* dev = Find(path);
  if (dev != nullptr && dev->unplugged_ && dev->replug_at_ >= 0 && NowLocked() >= dev->replug_at_) {
    dev->unplugged_ = false;  // the timed replug of unplug_after_dqbufs
    dev->replug_at_ = -1;
    dev->ResetFormat();
  }
  if (dev == nullptr || dev->unplugged_) return Fail(ENOENT);
  if (dev->faults_.busy_on_open) return Fail(EBUSY);
  const int fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (fd < 0) return -1;
  files_[fd] = File{dev, dev->generation_, (flags & O_NONBLOCK) != 0};
  ++dev->stats_.opens;
  return fd;
}

int FakeV4l2System::Close(int fd) {
  std::lock_guard<std::mutex> lock(mu_);
  Log("close");
  auto it = files_.find(fd);
  if (it == files_.end()) return Fail(EBADF);
  FakeDevice* dev = it->second.dev;
  if (it->second.generation == dev->generation_ && dev->owner_fd_ == fd) {
    // Closing the owner stops streaming and frees the queue; mappings stay until munmap.
    dev->streaming_ = false;
    dev->owner_fd_ = -1;
    dev->FreeBuffers();
  }
  files_.erase(it);
  return RawClose(fd);
}

void* FakeV4l2System::Mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) {
  std::lock_guard<std::mutex> lock(mu_);
  Log("mmap");
  auto it = files_.find(fd);
  if (it == files_.end()) {
    errno = EBADF;
    return MAP_FAILED;
  }
  FakeDevice* dev = it->second.dev;
  if (it->second.generation != dev->generation_) {
    errno = ENODEV;
    return MAP_FAILED;
  }
  for (uint32_t i = 0; i < dev->bufs_.size(); ++i) {
    FakeDevice::Buf& b = dev->bufs_[i];
    if (static_cast<off_t>(b.offset) != offset) continue;
    if (length == 0 || length > dev->buf_stride_ || !(flags & MAP_SHARED)) break;
    void* p = RawMmap(addr, length, prot, flags, dev->memfd_, offset);
    if (p == MAP_FAILED) return p;
    ++b.mappings;
    mappings_[p] = Mapping{dev, dev->bufset_, i, length};
    return p;
  }
  errno = EINVAL;
  return MAP_FAILED;
}

int FakeV4l2System::Munmap(void* addr, size_t length) {
  std::lock_guard<std::mutex> lock(mu_);
  Log("munmap");
  auto it = mappings_.find(addr);
  if (it == mappings_.end()) return Fail(EINVAL);
  const Mapping m = it->second;
  mappings_.erase(it);
  if (m.bufset == m.dev->bufset_ && m.index < m.dev->bufs_.size()) --m.dev->bufs_[m.index].mappings;
  return RawMunmap(addr, length);
}

int FakeV4l2System::Poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  std::unique_lock<std::mutex> lock(mu_);
  Log("poll");
  const int64_t start = NowLocked();
  const int64_t deadline =
      start + (timeout_ms < 0 ? int64_t{3600} * kNsPerSec : int64_t{timeout_ms} * 1'000'000);
  for (;;) {
    int ready = 0;
    int64_t next_due = INT64_MAX;
    for (nfds_t i = 0; i < nfds; ++i) {
      pollfd& p = fds[i];
      p.revents = 0;
      auto it = files_.find(p.fd);
      if (it == files_.end()) {
        if (p.fd >= 0) {  // not ours: ask the kernel without waiting
          pollfd q = p;
          if (RawPoll(&q, 1, 0) > 0) p.revents = q.revents;
        }
      } else {
        FakeDevice* dev = it->second.dev;
        if (it->second.generation != dev->generation_) {
          p.revents = POLLERR | POLLHUP;
        } else if (!dev->streaming_ || dev->owner_fd_ != p.fd) {
          p.revents = POLLERR;  // func-poll.rst: not streaming, or another fd owns the queue
        } else {
          CatchUp(dev);
          if (!dev->done_.empty()) p.revents = p.events & (POLLIN | POLLRDNORM);
          if (!dev->faults_.stalled) next_due = std::min(next_due, dev->FrameDue(dev->slot_));
        }
      }
      if (p.revents != 0) ++ready;
    }
    const int64_t now = NowLocked();
    if (ready > 0 || now >= deadline) return ready;
    const int64_t target = std::min(next_due, deadline);
    if (mode_ == ClockMode::kVirtual) {
      virtual_now_ = std::max(virtual_now_, target);
    } else {
      lock.unlock();
      std::vector<pollfd> copy(fds, fds + nfds);
      RawPoll(copy.data(), nfds, std::max<int64_t>(target - now, 0));
      lock.lock();
    }
  }
}

int FakeV4l2System::Ioctl(int fd, unsigned long request, void* arg) {
  std::unique_lock<std::mutex> lock(mu_);
  log_.emplace_back(IoctlName(request));
  auto it = files_.find(fd);
  if (it == files_.end()) return Fail(EBADF);
  File& file = it->second;
  if (file.generation != file.dev->generation_) return Fail(ENODEV);
  if (arg == nullptr) return Fail(EFAULT);
  FakeDevice* dev = file.dev;
  if (dev->faults_.eintr_every_ioctl) {
    const bool retry = dev->interrupted_fd_ == fd && dev->interrupted_request_ == request;
    dev->interrupted_fd_ = retry ? -1 : fd;
    dev->interrupted_request_ = retry ? 0 : request;
    if (!retry) {
      ++dev->stats_.ioctls_interrupted[IoctlName(request)];
      return Fail(EINTR);
    }
  }

  // One handler per request.
  static constexpr std::pair<unsigned long, int (FakeV4l2System::*)(IoctlCall&)> kHandlers[] = {
      {VIDIOC_QUERYCAP, &FakeV4l2System::QueryCap},
      {VIDIOC_ENUM_FMT, &FakeV4l2System::EnumFormat},
      {VIDIOC_G_FMT, &FakeV4l2System::GetFormat},
      {VIDIOC_S_FMT, &FakeV4l2System::SetFormat},
      {VIDIOC_TRY_FMT, &FakeV4l2System::SetFormat},
      {VIDIOC_G_PARM, &FakeV4l2System::StreamParm},
      {VIDIOC_S_PARM, &FakeV4l2System::StreamParm},
      {VIDIOC_REQBUFS, &FakeV4l2System::RequestBuffers},
      {VIDIOC_QUERYBUF, &FakeV4l2System::QueryBuffer},
      {VIDIOC_QBUF, &FakeV4l2System::QueueBuffer},
      {VIDIOC_DQBUF, &FakeV4l2System::DequeueBuffer},
      {VIDIOC_STREAMON, &FakeV4l2System::Stream},
      {VIDIOC_STREAMOFF, &FakeV4l2System::Stream}};
  IoctlCall call{fd, request, arg, file, dev, lock};
  for (const auto& [known, handler] : kHandlers) {
    if (known == request) return (this->*handler)(call);
  }
  return Fail(ENOTTY);
}

// VIDIOC_QUERYCAP: a capture device that streams.
int FakeV4l2System::QueryCap(IoctlCall& c) {
  const FakeDeviceConfig& cfg = c.dev->config_;
  auto* cap = static_cast<v4l2_capability*>(c.arg);
  *cap = v4l2_capability{};
  std::snprintf(reinterpret_cast<char*>(cap->driver), sizeof cap->driver, "sfrt_fake");
  std::snprintf(reinterpret_cast<char*>(cap->card), sizeof cap->card, "%s", cfg.card.c_str());
  std::snprintf(reinterpret_cast<char*>(cap->bus_info), sizeof cap->bus_info, "platform:%s",
                cfg.path.c_str());
  cap->version = (6u << 16) | (1u << 8);
  cap->device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  cap->capabilities = cap->device_caps | V4L2_CAP_DEVICE_CAPS;
  return 0;
}

// VIDIOC_ENUM_FMT: the configured formats.
int FakeV4l2System::EnumFormat(IoctlCall& c) {
  const FakeDeviceConfig& cfg = c.dev->config_;
  auto* d = static_cast<v4l2_fmtdesc*>(c.arg);
  if (d->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || d->index >= cfg.formats.size()) {
    return Fail(EINVAL);
  }
  const uint32_t index = d->index;
  *d = v4l2_fmtdesc{};
  d->index = index;
  d->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  d->pixelformat = cfg.formats[index];
  d->flags = IsJpeg(d->pixelformat) ? V4L2_FMT_FLAG_COMPRESSED : 0;
  std::snprintf(reinterpret_cast<char*>(d->description), sizeof d->description, "%c%c%c%c",
                d->pixelformat & 0xff, (d->pixelformat >> 8) & 0xff, (d->pixelformat >> 16) & 0xff,
                d->pixelformat >> 24);
  return 0;
}

// VIDIOC_G_FMT.
int FakeV4l2System::GetFormat(IoctlCall& c) {
  FakeDevice* dev = c.dev;
  auto* f = static_cast<v4l2_format*>(c.arg);
  if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return Fail(EINVAL);
  f->fmt.pix = dev->fmt_;
  return 0;
}

// VIDIOC_S_FMT and VIDIOC_TRY_FMT: the nearest format the configuration allows.
int FakeV4l2System::SetFormat(IoctlCall& c) {
  FakeDevice* dev = c.dev;
  const FakeDeviceConfig& cfg = c.dev->config_;
  auto* f = static_cast<v4l2_format*>(c.arg);
  if (f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return Fail(EINVAL);
  if (c.request == VIDIOC_S_FMT) {
    if (dev->faults_.busy_on_s_fmt) return Fail(EBUSY);
    if (!dev->bufs_.empty() || dev->streaming_) return Fail(EBUSY);
  }
  v4l2_pix_format p = f->fmt.pix;
  if (std::find(cfg.formats.begin(), cfg.formats.end(), p.pixelformat) == cfg.formats.end()) {
    p.pixelformat = cfg.formats.empty() ? V4L2_PIX_FMT_YUYV : cfg.formats[0];
  }
  p.width = static_cast<uint32_t>(
      std::clamp(static_cast<int>(p.width), cfg.min_width, cfg.max_width) & ~1);
  p.height = static_cast<uint32_t>(
      std::clamp(static_cast<int>(p.height), cfg.min_height, cfg.max_height) & ~1);
  p.field = V4L2_FIELD_NONE;
  p.colorspace = V4L2_COLORSPACE_SMPTE170M;
  const uint32_t row = MinRow(p.pixelformat, p.width);
  if (row != 0) {
    p.bytesperline = RoundUp(row, static_cast<uint32_t>(cfg.bytesperline_align));
    p.sizeimage = p.bytesperline * p.height;
    if (p.pixelformat == V4L2_PIX_FMT_NV12) p.sizeimage = p.bytesperline * p.height * 3 / 2;
  } else {
    p.bytesperline = 0;
    p.sizeimage = static_cast<uint32_t>(
        tjBufSize(static_cast<int>(p.width), static_cast<int>(p.height), TJSAMP_444));
  }
  f->fmt.pix = p;
  if (c.request == VIDIOC_S_FMT) dev->fmt_ = p;
  return 0;
}

// VIDIOC_G_PARM and VIDIOC_S_PARM: the frame rate, clamped to the configuration.
int FakeV4l2System::StreamParm(IoctlCall& c) {
  FakeDevice* dev = c.dev;
  const FakeDeviceConfig& cfg = c.dev->config_;
  auto* parm = static_cast<v4l2_streamparm*>(c.arg);
  if (parm->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return Fail(EINVAL);
  if (c.request == VIDIOC_S_PARM) {
    const v4l2_fract t = parm->parm.capture.timeperframe;
    if (t.numerator != 0 && t.denominator != 0) {
      const double want = static_cast<double>(t.denominator) / t.numerator;
      dev->fps_ = std::round(std::clamp(want, cfg.min_fps, cfg.max_fps));
    }
  }
  parm->parm.capture = v4l2_captureparm{};
  parm->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
  parm->parm.capture.timeperframe.numerator = 1000;
  parm->parm.capture.timeperframe.denominator =
      static_cast<uint32_t>(std::lround(dev->fps_ * 1000));
  parm->parm.capture.readbuffers = 2;
  return 0;
}

// VIDIOC_REQBUFS: the buffers in one memfd, mapped by the caller; count 0 frees them.
int FakeV4l2System::RequestBuffers(IoctlCall& c) {
  FakeDevice* dev = c.dev;
  const FakeDeviceConfig& cfg = c.dev->config_;
  auto* req = static_cast<v4l2_requestbuffers*>(c.arg);
  if (req->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || req->memory != V4L2_MEMORY_MMAP) {
    return Fail(EINVAL);
  }
  if (dev->owner_fd_ >= 0 && dev->owner_fd_ != c.fd) return Fail(EBUSY);
  if (dev->streaming_) return Fail(EBUSY);
  for (const auto& b : dev->bufs_) {
    if (b.mappings > 0) return Fail(EBUSY);  // strict: unmap before freeing
  }
  dev->FreeBuffers();
  req->capabilities = V4L2_BUF_CAP_SUPPORTS_MMAP;
  if (req->count == 0) {
    dev->owner_fd_ = -1;
    return 0;
  }
  const uint32_t count = std::clamp(req->count, cfg.min_buffers, cfg.max_buffers);
  const uint32_t page = static_cast<uint32_t>(sysconf(_SC_PAGESIZE));
  dev->buf_stride_ = RoundUp(dev->fmt_.sizeimage, page);
  dev->mem_size_ = static_cast<size_t>(dev->buf_stride_) * count;
  dev->memfd_ = memfd_create("sfrt-fake-v4l2", MFD_CLOEXEC);
  if (dev->memfd_ < 0 || ftruncate(dev->memfd_, static_cast<off_t>(dev->mem_size_)) != 0) {
    const int err = errno;
    dev->FreeBuffers();
    return Fail(err == 0 ? ENOMEM : err);
  }
  void* mem = RawMmap(nullptr, dev->mem_size_, PROT_READ | PROT_WRITE, MAP_SHARED, dev->memfd_, 0);
  if (mem == MAP_FAILED) {
    dev->FreeBuffers();
    return Fail(ENOMEM);
  }
  dev->mem_ = static_cast<uint8_t*>(mem);
  dev->bufs_.resize(count);
  for (uint32_t i = 0; i < count; ++i) dev->bufs_[i].offset = i * dev->buf_stride_;
  dev->owner_fd_ = c.fd;
  req->count = count;
  return 0;
}

// VIDIOC_QUERYBUF.
int FakeV4l2System::QueryBuffer(IoctlCall& c) {
  FakeDevice* dev = c.dev;
  auto* b = static_cast<v4l2_buffer*>(c.arg);
  if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->index >= dev->bufs_.size()) {
    return Fail(EINVAL);
  }
  const FakeDevice::Buf& buf = dev->bufs_[b->index];
  const uint32_t index = b->index;
  *b = buf.state == FakeDevice::Buf::kDone ? buf.meta : v4l2_buffer{};
  b->index = index;
  b->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b->memory = V4L2_MEMORY_MMAP;
  b->length = dev->fmt_.sizeimage;
  b->m.offset = buf.offset;
  b->flags &= ~(V4L2_BUF_FLAG_QUEUED | V4L2_BUF_FLAG_DONE | V4L2_BUF_FLAG_MAPPED);
  if (buf.mappings > 0) b->flags |= V4L2_BUF_FLAG_MAPPED;
  if (buf.state == FakeDevice::Buf::kQueued) b->flags |= V4L2_BUF_FLAG_QUEUED;
  if (buf.state == FakeDevice::Buf::kDone) b->flags |= V4L2_BUF_FLAG_DONE;
  return 0;
}

// VIDIOC_QBUF.
int FakeV4l2System::QueueBuffer(IoctlCall& c) {
  FakeDevice* dev = c.dev;
  auto* b = static_cast<v4l2_buffer*>(c.arg);
  if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_MMAP ||
      b->index >= dev->bufs_.size()) {
    return Fail(EINVAL);
  }
  if (dev->owner_fd_ != c.fd) return Fail(EBUSY);
  FakeDevice::Buf& buf = dev->bufs_[b->index];
  if (buf.state != FakeDevice::Buf::kDequeued) return Fail(EINVAL);
  buf.state = FakeDevice::Buf::kQueued;
  dev->queued_.push_back(b->index);
  b->flags = V4L2_BUF_FLAG_QUEUED | (buf.mappings > 0 ? V4L2_BUF_FLAG_MAPPED : 0);
  return 0;
}

// VIDIOC_DQBUF: the oldest done buffer; on a blocking fd, waits for the next frame.
int FakeV4l2System::DequeueBuffer(IoctlCall& c) {
  FakeDevice* dev = c.dev;
  File& file = c.file;
  std::unique_lock<std::mutex>& lock = c.lock;
  auto* b = static_cast<v4l2_buffer*>(c.arg);
  if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_MMAP) {
    return Fail(EINVAL);
  }
  if (dev->owner_fd_ != c.fd) return Fail(EBUSY);
  if (!dev->streaming_) return Fail(EINVAL);
  CatchUp(dev);
  while (dev->done_.empty()) {
    if (file.nonblocking || dev->faults_.stalled) return Fail(EAGAIN);
    // Blocking fd: wait for the next frame.
    const int64_t due = dev->FrameDue(dev->slot_);
    if (mode_ == ClockMode::kVirtual) {
      virtual_now_ = std::max(virtual_now_, due);
    } else {
      const int64_t wait = due - NowLocked();
      lock.unlock();
      RawPoll(nullptr, 0, std::max<int64_t>(wait, 0));
      lock.lock();
      if (file.generation != dev->generation_) return Fail(ENODEV);
      if (!dev->streaming_) return Fail(EINVAL);
    }
    CatchUp(dev);
  }
  const uint32_t index = dev->done_.front();
  dev->done_.pop_front();
  FakeDevice::Buf& buf = dev->bufs_[index];
  buf.state = FakeDevice::Buf::kDequeued;
  UpdateReadable(dev);
  if (dev->faults_.eio_next_dqbuf > 0) {
    // As the kernel may: the buffer left the queue but the caller is not told which.
    --dev->faults_.eio_next_dqbuf;
    return Fail(EIO);
  }
  *b = buf.meta;
  if (buf.mappings > 0) b->flags |= V4L2_BUF_FLAG_MAPPED;
  ++dev->stats_.frames_dequeued;
  if (dev->faults_.unplug_after_dqbufs > 0 && --dev->faults_.unplug_after_dqbufs == 0) {
    // The caller's mapping of this buffer stays valid; its QBUF will fail with ENODEV.
    dev->UnplugLocked();
    const int64_t after = dev->faults_.replug_after_ns;
    dev->replug_at_ = after < 0 ? -1 : NowLocked() + after;
  }
  return 0;
}

// VIDIOC_STREAMON and VIDIOC_STREAMOFF.
int FakeV4l2System::Stream(IoctlCall& c) {
  FakeDevice* dev = c.dev;
  const FakeDeviceConfig& cfg = c.dev->config_;
  const int type = *static_cast<int*>(c.arg);
  if (type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return Fail(EINVAL);
  if (dev->owner_fd_ != c.fd) return Fail(dev->owner_fd_ < 0 ? EINVAL : EBUSY);
  if (c.request == VIDIOC_STREAMON) {
    if (dev->streaming_) return 0;
    if (dev->bufs_.empty()) return Fail(EINVAL);
    if (dev->faults_.nospc_on_streamon) return Fail(ENOSPC);
    dev->streaming_ = true;
    dev->stream_t0_ = NowLocked();
    if (cfg.align_to_epoch) {
      const int64_t period = std::llround(1e9 / dev->fps_);
      dev->stream_t0_ -= dev->stream_t0_ % period;
    }
    dev->slot_ = 0;
    dev->sequence_ = cfg.first_sequence;
    ++dev->stats_.streamons;
    return 0;
  }
  // STREAMOFF: every buffer returns to the dequeued state.
  dev->streaming_ = false;
  for (auto& b : dev->bufs_) b.state = FakeDevice::Buf::kDequeued;
  dev->queued_.clear();
  dev->done_.clear();
  UpdateReadable(dev);
  return 0;
}

}  // namespace sfrt::v4l2::testing
