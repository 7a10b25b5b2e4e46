// Proves the promise of session.h that Run() does no I/O. This program defines libc's file I/O
// entry points itself (open/openat/creat, read/write and their positioned and vectored forms,
// close, lseek, fstat/stat, fsync/fdatasync, ioctl, mmap of a file and munmap of such a mapping,
// and stdio: fopen, fread, fgets, fwrite, fputs, puts, fputc, putc, fprintf, vfprintf, printf,
// fflush, fclose, and the _FORTIFY_SOURCE variants) and, while a global flag is armed, counts every
// call from any thread (the session's workers included), remembering which function was hit
// first, in fixed storage: the hooks never allocate. Each hook forwards to the next definition
// (dlsym(RTLD_NEXT): libc's, or under ASan its interceptor, which forwards to libc), so the
// program keeps working. The runtime is linked statically, so its calls bind here; the executable
// exports the symbols, so calls from shared libraries (libstdc++'s streams) bind here too.
// glibc's calls inside itself (fopen's open, say) do not pass through these symbols, which is why
// each public entry point is hooked. The tests of Run() create each session unarmed, arm only
// around its Run() calls (every supported ISA, one and two threads, both frame sizes and both
// overloads), and disarm before anything is asserted or printed (GoogleTest writes to stdout).
// Two tests show that the hooks see I/O from this program, from a shared library on another
// thread and from the runtime itself (Model::LoadFile), so the tests of Run() cannot pass
// vacuously.
#include <dlfcn.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <stdarg.h>
#include <stdio.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "common/bf16_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "common/unet_spec.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/session.h"

// The fortified variants GCC emits under _FORTIFY_SOURCE (Debian builds its libraries with it),
// declared by glibc's headers only when it is defined.
extern "C" {
int __fprintf_chk(FILE* stream, int flag, const char* format, ...);
int __vfprintf_chk(FILE* stream, int flag, const char* format, va_list ap);
int __printf_chk(int flag, const char* format, ...);
ssize_t __read_chk(int fd, void* buf, size_t count, size_t buflen);
ssize_t __pread_chk(int fd, void* buf, size_t count, off_t offset, size_t buflen);
ssize_t __pread64_chk(int fd, void* buf, size_t count, off64_t offset, size_t buflen);
}

namespace {

// Every hooked function: its Fn, and its name in failure messages.
#define SFRT_HOOKED_FUNCTIONS(X)            \
  X(kOpen, "open")                          \
  X(kOpen64, "open64")                      \
  X(kOpenat, "openat")                      \
  X(kOpenat64, "openat64")                  \
  X(kCreat, "creat")                        \
  X(kCreat64, "creat64")                    \
  X(kClose, "close")                        \
  X(kRead, "read")                          \
  X(kReadChk, "__read_chk")                 \
  X(kWrite, "write")                        \
  X(kPread, "pread")                        \
  X(kPread64, "pread64")                    \
  X(kPreadChk, "__pread_chk")               \
  X(kPread64Chk, "__pread64_chk")           \
  X(kPwrite, "pwrite")                      \
  X(kPwrite64, "pwrite64")                  \
  X(kReadv, "readv")                        \
  X(kWritev, "writev")                      \
  X(kPreadv, "preadv")                      \
  X(kPreadv64, "preadv64")                  \
  X(kPwritev, "pwritev")                    \
  X(kPwritev64, "pwritev64")                \
  X(kLseek, "lseek")                        \
  X(kLseek64, "lseek64")                    \
  X(kFstat, "fstat")                        \
  X(kStat, "stat")                          \
  X(kFsync, "fsync")                        \
  X(kFdatasync, "fdatasync")                \
  X(kIoctl, "ioctl")                        \
  X(kMmapFile, "mmap (a file)")             \
  X(kMunmapFile, "munmap (a file mapping)") \
  X(kFopen, "fopen")                        \
  X(kFopen64, "fopen64")                    \
  X(kFclose, "fclose")                      \
  X(kFread, "fread")                        \
  X(kFgets, "fgets")                        \
  X(kFwrite, "fwrite")                      \
  X(kFputs, "fputs")                        \
  X(kPuts, "puts")                          \
  X(kFputc, "fputc")                        \
  X(kPutc, "putc")                          \
  X(kFflush, "fflush")                      \
  X(kFprintf, "fprintf")                    \
  X(kFprintfChk, "__fprintf_chk")           \
  X(kVfprintf, "vfprintf")                  \
  X(kVfprintfChk, "__vfprintf_chk")         \
  X(kPrintf, "printf")                      \
  X(kPrintfChk, "__printf_chk")

enum Fn : int {
#define SFRT_FN_ENUM(fn, name) fn,
  SFRT_HOOKED_FUNCTIONS(SFRT_FN_ENUM)
#undef SFRT_FN_ENUM
};

constexpr const char* kFnNames[] = {
#define SFRT_FN_NAME(fn, name) name,
    SFRT_HOOKED_FUNCTIONS(SFRT_FN_NAME)
#undef SFRT_FN_NAME
};
constexpr int kFnCount = static_cast<int>(std::size(kFnNames));

// Constant-initialised, so hooks called before main (or by other static initialisers) find them.
std::atomic<bool> g_armed{false};
std::array<std::atomic<long>, kFnCount> g_calls{};
std::atomic<int> g_first{-1};  // the Fn hit first since Arm(); -1: none
// What the first hit was about (a path, or "fd N"), written by the thread that claimed g_first
// and published by g_first_detail_ready. A fixed buffer: the hooks must not allocate.
char g_first_detail[96];
std::atomic<bool> g_first_detail_ready{false};

void Copy(const char* from, char* to, size_t capacity) {
  size_t i = 0;
  for (; from != nullptr && from[i] != '\0' && i + 1 < capacity; ++i) to[i] = from[i];
  to[i] = '\0';
}

constexpr long kNoFd = -1000000;  // Count()'s fd when the call names none (a FILE*, a path)

void Count(Fn fn, const char* path = nullptr, long fd = kNoFd) {
  if (!g_armed.load(std::memory_order_acquire)) return;
  g_calls[fn].fetch_add(1, std::memory_order_relaxed);
  int expected = -1;
  if (!g_first.compare_exchange_strong(expected, fn)) return;
  if (path != nullptr) {
    Copy(path, g_first_detail, sizeof g_first_detail);
  } else if (fd != kNoFd) {
    char* out = g_first_detail;
    Copy(fd < 0 ? "fd -" : "fd ", out, sizeof g_first_detail);
    out += fd < 0 ? 4 : 3;
    unsigned long v = fd < 0 ? static_cast<unsigned long>(-fd) : static_cast<unsigned long>(fd);
    char digits[24];
    int n = 0;
    do {
      digits[n++] = static_cast<char>('0' + v % 10);
      v /= 10;
    } while (v > 0);
    while (n > 0) *out++ = digits[--n];
    *out = '\0';
  } else {
    g_first_detail[0] = '\0';
  }
  g_first_detail_ready.store(true, std::memory_order_release);
}

template <typename F>
F Next(const char* name) {
  void* f = dlsym(RTLD_NEXT, name);
  if (f == nullptr) abort();
  return reinterpret_cast<F>(f);
}

// The file mappings the mmap hooks made (armed or not), so that munmap can tell an unmapping of a
// file from one of anonymous memory without allocating. A full table only loses that knowledge.
struct Mapping {
  std::atomic<uintptr_t> start{0};
  std::atomic<size_t> length{0};
};
std::array<Mapping, 64> g_file_mappings{};

void RememberFileMapping(void* start, size_t length) {
  for (Mapping& m : g_file_mappings) {
    uintptr_t empty = 0;
    if (m.start.compare_exchange_strong(empty, reinterpret_cast<uintptr_t>(start))) {
      m.length.store(length);
      return;
    }
  }
}

bool UnmapsAFile(void* start, size_t length) {
  const uintptr_t begin = reinterpret_cast<uintptr_t>(start);
  bool file = false;
  for (Mapping& m : g_file_mappings) {
    const uintptr_t s = m.start.load();
    if (s == 0) continue;
    const size_t n = m.length.load();
    if (begin < s + n && s < begin + length) file = true;
    if (begin <= s && s + n <= begin + length) m.start.store(0);  // wholly unmapped: forget it
  }
  return file;
}

// As glibc's __OPEN_NEEDS_MODE: the calls that pass a mode.
bool NeedsMode(int flags) { return (flags & O_CREAT) != 0 || (flags & O_TMPFILE) == O_TMPFILE; }

}  // namespace

extern "C" {

// --- Opening and closing descriptors ---------------------------------------------------------
int open(const char* path, int flags, ...) {
  static const auto next = Next<int (*)(const char*, int, ...)>("open");
  mode_t mode = 0;
  if (NeedsMode(flags)) {
    va_list ap;
    va_start(ap, flags);
    mode = va_arg(ap, mode_t);
    va_end(ap);
  }
  Count(kOpen, path);
  return next(path, flags, mode);
}
int open64(const char* path, int flags, ...) {
  static const auto next = Next<int (*)(const char*, int, ...)>("open64");
  mode_t mode = 0;
  if (NeedsMode(flags)) {
    va_list ap;
    va_start(ap, flags);
    mode = va_arg(ap, mode_t);
    va_end(ap);
  }
  Count(kOpen64, path);
  return next(path, flags, mode);
}
int openat(int dirfd, const char* path, int flags, ...) {
  static const auto next = Next<int (*)(int, const char*, int, ...)>("openat");
  mode_t mode = 0;
  if (NeedsMode(flags)) {
    va_list ap;
    va_start(ap, flags);
    mode = va_arg(ap, mode_t);
    va_end(ap);
  }
  Count(kOpenat, path);
  return next(dirfd, path, flags, mode);
}
int openat64(int dirfd, const char* path, int flags, ...) {
  static const auto next = Next<int (*)(int, const char*, int, ...)>("openat64");
  mode_t mode = 0;
  if (NeedsMode(flags)) {
    va_list ap;
    va_start(ap, flags);
    mode = va_arg(ap, mode_t);
    va_end(ap);
  }
  Count(kOpenat64, path);
  return next(dirfd, path, flags, mode);
}
int creat(const char* path, mode_t mode) {
  static const auto next = Next<int (*)(const char*, mode_t)>("creat");
  Count(kCreat, path);
  return next(path, mode);
}
int creat64(const char* path, mode_t mode) {
  static const auto next = Next<int (*)(const char*, mode_t)>("creat64");
  Count(kCreat64, path);
  return next(path, mode);
}
int close(int fd) {
  static const auto next = Next<int (*)(int)>("close");
  Count(kClose, nullptr, fd);
  return next(fd);
}

// --- Reading and writing descriptors ---------------------------------------------------------
ssize_t read(int fd, void* buf, size_t count) {
  static const auto next = Next<ssize_t (*)(int, void*, size_t)>("read");
  Count(kRead, nullptr, fd);
  return next(fd, buf, count);
}
ssize_t __read_chk(int fd, void* buf, size_t count, size_t buflen) {
  static const auto next = Next<ssize_t (*)(int, void*, size_t, size_t)>("__read_chk");
  Count(kReadChk, nullptr, fd);
  return next(fd, buf, count, buflen);
}
ssize_t write(int fd, const void* buf, size_t count) {
  static const auto next = Next<ssize_t (*)(int, const void*, size_t)>("write");
  Count(kWrite, nullptr, fd);
  return next(fd, buf, count);
}
ssize_t pread(int fd, void* buf, size_t count, off_t offset) {
  static const auto next = Next<ssize_t (*)(int, void*, size_t, off_t)>("pread");
  Count(kPread, nullptr, fd);
  return next(fd, buf, count, offset);
}
ssize_t pread64(int fd, void* buf, size_t count, off64_t offset) {
  static const auto next = Next<ssize_t (*)(int, void*, size_t, off64_t)>("pread64");
  Count(kPread64, nullptr, fd);
  return next(fd, buf, count, offset);
}
ssize_t __pread_chk(int fd, void* buf, size_t count, off_t offset, size_t buflen) {
  static const auto next = Next<ssize_t (*)(int, void*, size_t, off_t, size_t)>("__pread_chk");
  Count(kPreadChk, nullptr, fd);
  return next(fd, buf, count, offset, buflen);
}
ssize_t __pread64_chk(int fd, void* buf, size_t count, off64_t offset, size_t buflen) {
  static const auto next = Next<ssize_t (*)(int, void*, size_t, off64_t, size_t)>("__pread64_chk");
  Count(kPread64Chk, nullptr, fd);
  return next(fd, buf, count, offset, buflen);
}
ssize_t pwrite(int fd, const void* buf, size_t count, off_t offset) {
  static const auto next = Next<ssize_t (*)(int, const void*, size_t, off_t)>("pwrite");
  Count(kPwrite, nullptr, fd);
  return next(fd, buf, count, offset);
}
ssize_t pwrite64(int fd, const void* buf, size_t count, off64_t offset) {
  static const auto next = Next<ssize_t (*)(int, const void*, size_t, off64_t)>("pwrite64");
  Count(kPwrite64, nullptr, fd);
  return next(fd, buf, count, offset);
}
ssize_t readv(int fd, const struct iovec* iov, int iovcnt) {
  static const auto next = Next<ssize_t (*)(int, const struct iovec*, int)>("readv");
  Count(kReadv, nullptr, fd);
  return next(fd, iov, iovcnt);
}
ssize_t writev(int fd, const struct iovec* iov, int iovcnt) {
  static const auto next = Next<ssize_t (*)(int, const struct iovec*, int)>("writev");
  Count(kWritev, nullptr, fd);
  return next(fd, iov, iovcnt);
}
ssize_t preadv(int fd, const struct iovec* iov, int iovcnt, off_t offset) {
  static const auto next = Next<ssize_t (*)(int, const struct iovec*, int, off_t)>("preadv");
  Count(kPreadv, nullptr, fd);
  return next(fd, iov, iovcnt, offset);
}
ssize_t preadv64(int fd, const struct iovec* iov, int iovcnt, off64_t offset) {
  static const auto next = Next<ssize_t (*)(int, const struct iovec*, int, off64_t)>("preadv64");
  Count(kPreadv64, nullptr, fd);
  return next(fd, iov, iovcnt, offset);
}
ssize_t pwritev(int fd, const struct iovec* iov, int iovcnt, off_t offset) {
  static const auto next = Next<ssize_t (*)(int, const struct iovec*, int, off_t)>("pwritev");
  Count(kPwritev, nullptr, fd);
  return next(fd, iov, iovcnt, offset);
}
ssize_t pwritev64(int fd, const struct iovec* iov, int iovcnt, off64_t offset) {
  static const auto next = Next<ssize_t (*)(int, const struct iovec*, int, off64_t)>("pwritev64");
  Count(kPwritev64, nullptr, fd);
  return next(fd, iov, iovcnt, offset);
}

// --- Seeking, metadata, syncing, device control ----------------------------------------------
off_t lseek(int fd, off_t offset, int whence) {
  static const auto next = Next<off_t (*)(int, off_t, int)>("lseek");
  Count(kLseek, nullptr, fd);
  return next(fd, offset, whence);
}
off64_t lseek64(int fd, off64_t offset, int whence) {
  static const auto next = Next<off64_t (*)(int, off64_t, int)>("lseek64");
  Count(kLseek64, nullptr, fd);
  return next(fd, offset, whence);
}
int fstat(int fd, struct stat* st) {
  static const auto next = Next<int (*)(int, struct stat*)>("fstat");
  Count(kFstat, nullptr, fd);
  return next(fd, st);
}
int stat(const char* path, struct stat* st) {
  static const auto next = Next<int (*)(const char*, struct stat*)>("stat");
  Count(kStat, path);
  return next(path, st);
}
int fsync(int fd) {
  static const auto next = Next<int (*)(int)>("fsync");
  Count(kFsync, nullptr, fd);
  return next(fd);
}
int fdatasync(int fd) {
  static const auto next = Next<int (*)(int)>("fdatasync");
  Count(kFdatasync, nullptr, fd);
  return next(fd);
}
int ioctl(int fd, unsigned long request, ...) {
  static const auto next = Next<int (*)(int, unsigned long, ...)>("ioctl");
  va_list ap;
  va_start(ap, request);
  void* arg = va_arg(ap, void*);  // glibc's ioctl passes one argument on
  va_end(ap);
  Count(kIoctl, nullptr, fd);
  return next(fd, request, arg);
}

// --- Mapping files (anonymous memory is not I/O) ---------------------------------------------
void* mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) {
  static const auto next = Next<void* (*)(void*, size_t, int, int, int, off_t)>("mmap");
  const bool file = fd >= 0 && (flags & MAP_ANONYMOUS) == 0;
  if (file) Count(kMmapFile, nullptr, fd);
  void* result = next(addr, length, prot, flags, fd, offset);
  if (file && result != MAP_FAILED) RememberFileMapping(result, length);
  return result;
}
void* mmap64(void* addr, size_t length, int prot, int flags, int fd, off64_t offset) {
  static const auto next = Next<void* (*)(void*, size_t, int, int, int, off64_t)>("mmap64");
  const bool file = fd >= 0 && (flags & MAP_ANONYMOUS) == 0;
  if (file) Count(kMmapFile, nullptr, fd);
  void* result = next(addr, length, prot, flags, fd, offset);
  if (file && result != MAP_FAILED) RememberFileMapping(result, length);
  return result;
}
int munmap(void* addr, size_t length) {
  static const auto next = Next<int (*)(void*, size_t)>("munmap");
  if (UnmapsAFile(addr, length)) Count(kMunmapFile);
  return next(addr, length);
}

// --- stdio -----------------------------------------------------------------------------------
FILE* fopen(const char* path, const char* mode) {
  static const auto next = Next<FILE* (*)(const char*, const char*)>("fopen");
  Count(kFopen, path);
  return next(path, mode);
}
FILE* fopen64(const char* path, const char* mode) {
  static const auto next = Next<FILE* (*)(const char*, const char*)>("fopen64");
  Count(kFopen64, path);
  return next(path, mode);
}
int fclose(FILE* stream) {
  static const auto next = Next<int (*)(FILE*)>("fclose");
  Count(kFclose);
  return next(stream);
}
size_t fread(void* ptr, size_t size, size_t n, FILE* stream) {
  static const auto next = Next<size_t (*)(void*, size_t, size_t, FILE*)>("fread");
  Count(kFread);
  return next(ptr, size, n, stream);
}
char* fgets(char* s, int size, FILE* stream) {
  static const auto next = Next<char* (*)(char*, int, FILE*)>("fgets");
  Count(kFgets);
  return next(s, size, stream);
}
size_t fwrite(const void* ptr, size_t size, size_t n, FILE* stream) {
  static const auto next = Next<size_t (*)(const void*, size_t, size_t, FILE*)>("fwrite");
  Count(kFwrite);
  return next(ptr, size, n, stream);
}
int fputs(const char* s, FILE* stream) {
  static const auto next = Next<int (*)(const char*, FILE*)>("fputs");
  Count(kFputs);
  return next(s, stream);
}
int puts(const char* s) {
  static const auto next = Next<int (*)(const char*)>("puts");
  Count(kPuts);
  return next(s);
}
int fputc(int c, FILE* stream) {
  static const auto next = Next<int (*)(int, FILE*)>("fputc");
  Count(kFputc);
  return next(c, stream);
}
int putc(int c, FILE* stream) {
  static const auto next = Next<int (*)(int, FILE*)>("putc");
  Count(kPutc);
  return next(c, stream);
}
int fflush(FILE* stream) {
  static const auto next = Next<int (*)(FILE*)>("fflush");
  Count(kFflush);
  return next(stream);
}
int vfprintf(FILE* stream, const char* format, va_list ap) {
  static const auto next = Next<int (*)(FILE*, const char*, va_list)>("vfprintf");
  Count(kVfprintf);
  return next(stream, format, ap);
}
int __vfprintf_chk(FILE* stream, int flag, const char* format, va_list ap) {
  static const auto next = Next<int (*)(FILE*, int, const char*, va_list)>("__vfprintf_chk");
  Count(kVfprintfChk);
  return next(stream, flag, format, ap);
}
// The variadic ones forward to the next va_list function (not to the hooks above: one call
// counts once).
int fprintf(FILE* stream, const char* format, ...) {
  static const auto next = Next<int (*)(FILE*, const char*, va_list)>("vfprintf");
  Count(kFprintf);
  va_list ap;
  va_start(ap, format);
  const int n = next(stream, format, ap);
  va_end(ap);
  return n;
}
int __fprintf_chk(FILE* stream, int flag, const char* format, ...) {
  static const auto next = Next<int (*)(FILE*, int, const char*, va_list)>("__vfprintf_chk");
  Count(kFprintfChk);
  va_list ap;
  va_start(ap, format);
  const int n = next(stream, flag, format, ap);
  va_end(ap);
  return n;
}
int printf(const char* format, ...) {
  static const auto next = Next<int (*)(const char*, va_list)>("vprintf");
  Count(kPrintf);
  va_list ap;
  va_start(ap, format);
  const int n = next(format, ap);
  va_end(ap);
  return n;
}
int __printf_chk(int flag, const char* format, ...) {
  static const auto next = Next<int (*)(int, const char*, va_list)>("__vprintf_chk");
  Count(kPrintfChk);
  va_list ap;
  va_start(ap, format);
  const int n = next(flag, format, ap);
  va_end(ap);
  return n;
}

}  // extern "C"

namespace sfrt {
namespace {

// What the hooks saw between Arm() and Disarm().
struct IoCalls {
  std::array<long, kFnCount> calls{};
  int first = -1;
  std::string first_detail;

  long total() const {
    long n = 0;
    for (long c : calls) n += c;
    return n;
  }
  long of(Fn fn) const { return calls[fn]; }
  // "2 calls: open x1, close x1; first: open (/tmp/x)", for failure messages.
  std::string Describe() const {
    std::string s = std::to_string(total()) + " calls:";
    for (int f = 0; f < kFnCount; ++f) {
      if (calls[f] != 0) s += std::string(" ") + kFnNames[f] + " x" + std::to_string(calls[f]);
    }
    if (first >= 0) s += std::string("; first: ") + kFnNames[first];
    if (!first_detail.empty()) s += " (" + first_detail + ")";
    return s;
  }
};

void Arm() {
  for (auto& c : g_calls) c.store(0);
  g_first_detail_ready.store(false);
  g_first.store(-1);
  g_armed.store(true);
}

IoCalls Disarm() {
  g_armed.store(false);
  IoCalls seen;
  for (int f = 0; f < kFnCount; ++f) seen.calls[f] = g_calls[f].load();
  seen.first = g_first.load();
  if (g_first_detail_ready.load(std::memory_order_acquire)) seen.first_detail = g_first_detail;
  return seen;
}

constexpr int kMaxHeight = 96;
constexpr int kMaxWidth = 128;

// Runs `runs` frames on a session of `model` (created unarmed: only Run() is promised), armed
// throughout: both frame sizes, and both Run() overloads.
IoCalls CountDuringRuns(const std::shared_ptr<const Model>& model, Isa isa, int threads, int runs) {
  SessionOptions options;
  options.max_height = kMaxHeight;
  options.max_width = kMaxWidth;
  options.isa = isa;
  options.threads = threads;
  auto session = Session::Create(model, options);
  EXPECT_TRUE(session.ok()) << session.message();
  if (!session.ok()) return {};
  Session& s = **session;
  std::vector<float> input(kMaxHeight * kMaxWidth * 12), output(kMaxHeight * kMaxWidth * 3);
  for (size_t i = 0; i < input.size(); ++i) input[i] = static_cast<float>((i * 37) % 255);
  std::vector<int64_t> step_end_ns(s.steps().size() + 1);
  bool all_ok = true;
  Arm();
  for (int i = 0; i < runs; ++i) {
    const int h = i % 2 == 0 ? kMaxHeight : 67, w = i % 2 == 0 ? kMaxWidth : 121;
    const std::span<const float> in(input.data(), static_cast<size_t>(h) * w * 12);
    const std::span<float> out(output.data(), static_cast<size_t>(h) * w * 3);
    all_ok &= (i % 3 == 2 ? s.Run(in, h, w, out, step_end_ns) : s.Run(in, h, w, out)).ok();
  }
  const IoCalls seen = Disarm();
  EXPECT_TRUE(all_ok);
  return seen;
}

// Every supported ISA, at one and two threads: Run() calls none of the hooked functions.
void ExpectRunDoesNoIo(const exporter::ModelSpec& spec, Precision precision) {
  const auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  for (Isa isa : SupportedIsas()) {
    for (int threads : {1, 2}) {
      SCOPED_TRACE(std::string(IsaName(isa)) + ", threads " + std::to_string(threads));
      // The scalar reference is ~50x slower than the SIMD paths, its bf16 kernel (double sums)
      // slower still: fewer runs there.
      const bool slow =
          isa == Isa::kRef || (precision == Precision::kBFloat16 && !Bf16KernelsAvailable(isa));
      const IoCalls seen = CountDuringRuns(model, isa, threads, slow ? 4 : 30);
      EXPECT_EQ(seen.total(), 0) << seen.Describe();
    }
  }
}

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "sfrt_no_io_test_" + std::to_string(getpid()) + "_" + name;
}

TEST(NoIo, HooksCountFileIoFromThisProgramAndFromSharedLibraries) {
  // This program's own calls (bound at link time, as the runtime's are).
  Arm();
  const int fd = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  const ssize_t written = fd >= 0 ? ::write(fd, "x", 1) : -1;
  const int closed = fd >= 0 ? ::close(fd) : -1;
  FILE* f = std::fopen("/dev/null", "w");
  const size_t put = f != nullptr ? std::fwrite("xy", 1, 2, f) : 0;
  if (f != nullptr) std::fprintf(f, "%d\n", 42);
  const int flushed = f != nullptr ? std::fflush(f) : -1;
  if (f != nullptr) std::fclose(f);
  IoCalls seen = Disarm();
  ASSERT_GE(fd, 0);
  EXPECT_EQ(written, 1);
  EXPECT_EQ(closed, 0);
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(put, 2u);
  EXPECT_EQ(flushed, 0);
  EXPECT_EQ(seen.of(kOpen), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kWrite), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kClose), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kFopen), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kFwrite), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kFprintf), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kVfprintf), 0) << "fprintf counted twice: " << seen.Describe();
  EXPECT_EQ(seen.of(kFflush), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kFclose), 1) << seen.Describe();
  EXPECT_EQ(seen.first, kOpen);
  EXPECT_EQ(seen.first_detail, "/dev/null");

  // A shared library's calls (libstdc++'s file streams), through the exported symbols, from
  // another thread too.
  const std::string path = TempPath("stream");
  Arm();
  std::thread writer([&] {
    std::ofstream out(path, std::ios::binary);
    out << "scene flow\n";
  });
  writer.join();
  seen = Disarm();
  EXPECT_GE(seen.total(), 3) << seen.Describe();  // open, write, close in some form
  EXPECT_GE(seen.of(kFopen) + seen.of(kFopen64) + seen.of(kOpen) + seen.of(kOpen64), 1)
      << seen.Describe();
  EXPECT_GE(seen.of(kWrite) + seen.of(kWritev), 1) << seen.Describe();
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "scene flow");
  std::remove(path.c_str());
}

TEST(NoIo, HooksCountTheRuntimesOwnFileIoWhenItLoadsAModelFile) {
  // Model::LoadFile opens, maps and closes the file; destroying the Model unmaps it. The runtime
  // is linked into this program, so this is the path any I/O in Run() would take.
  const std::vector<uint8_t> bytes = testing::SerializeOrDie(exporter::SceneEdNetSpec(16));
  const std::string path = TempPath("model.sfrt");
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
  }
  Arm();
  auto loaded = Model::LoadFile(path);
  IoCalls seen = Disarm();
  std::remove(path.c_str());
  ASSERT_TRUE(loaded.ok()) << loaded.message();
  EXPECT_EQ(seen.of(kOpen), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kFstat), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kMmapFile), 1) << seen.Describe();
  EXPECT_EQ(seen.of(kClose), 1) << seen.Describe();
  EXPECT_EQ(seen.first, kOpen);
  EXPECT_EQ(seen.first_detail, path);
  std::shared_ptr<const Model> model = std::move(loaded).value();

  // A model read through that mapping runs without I/O too.
  const IoCalls during_runs = CountDuringRuns(model, BestIsa(), 2, 10);
  EXPECT_EQ(during_runs.total(), 0) << during_runs.Describe();

  Arm();
  model.reset();
  seen = Disarm();
  EXPECT_EQ(seen.of(kMunmapFile), 1) << seen.Describe();
}

TEST(NoIo, SessionRunDoesNoFileIoInFloat32) {
  ExpectRunDoesNoIo(exporter::SceneEdNetSpec(16), Precision::kFloat32);
}

TEST(NoIo, SessionRunDoesNoFileIoInInt8) {
  ExpectRunDoesNoIo(testing::Int8Spec(exporter::SceneEdNetSpec(16)), Precision::kInt8);
}

TEST(NoIo, SessionRunDoesNoFileIoInBf16) {
  ExpectRunDoesNoIo(testing::Bf16Spec(exporter::SceneEdNetSpec(16)), Precision::kBFloat16);
}

TEST(NoIo, SessionRunDoesNoFileIoOnAGraphWithSkipsAndAResidualAdd) {
  ExpectRunDoesNoIo(testing::SceneEdNetUSpec(16, 1, true), Precision::kFloat32);
}

}  // namespace
}  // namespace sfrt
