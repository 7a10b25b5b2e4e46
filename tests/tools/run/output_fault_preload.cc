// LD_PRELOAD shim that makes file output fail the way a full disk or a read-only directory does,
// deterministically, for an unmodified binary (fault_check.py runs `sfrt run` under it).
//
// Environment (read once):
//   SFRT_FAULT_ERRNO   ENOSPC (default), EROFS, EIO or EDQUOT: the errno of the failure.
//   SFRT_FAULT_MATCH   only files whose path contains this text are affected ("" = every
//                      regular file the process writes).
//   SFRT_FAULT_OP      write (default): write() to an affected file fails once
//                      SFRT_FAULT_AFTER_BYTES bytes have gone to affected files in total (the
//                      write that crosses the limit is cut short, as on a real full disk);
//                      create: creating an affected file (open() with O_CREAT, or mkstemp())
//                      fails (as in a read-only directory).
//   SFRT_FAULT_AFTER_BYTES  see above (default 0).
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include <atomic>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

struct Config {
  bool loaded = false;
  int err = ENOSPC;
  std::string match;
  bool on_create = false;
  long long after_bytes = 0;
};

const Config& GetConfig() {
  static const Config config = [] {
    Config c;
    c.loaded = true;
    if (const char* e = std::getenv("SFRT_FAULT_ERRNO")) {
      const std::string name = e;
      c.err = name == "EROFS" ? EROFS : name == "EIO" ? EIO : name == "EDQUOT" ? EDQUOT : ENOSPC;
    }
    if (const char* m = std::getenv("SFRT_FAULT_MATCH")) c.match = m;
    if (const char* op = std::getenv("SFRT_FAULT_OP")) c.on_create = std::strcmp(op, "create") == 0;
    if (const char* n = std::getenv("SFRT_FAULT_AFTER_BYTES")) c.after_bytes = std::atoll(n);
    return c;
  }();
  return config;
}

std::atomic<long long> g_written{0};

bool Matches(const char* path) {
  const Config& c = GetConfig();
  return c.match.empty() || std::strstr(path, c.match.c_str()) != nullptr;
}

// Whether `fd` is a regular file whose path matches.
bool AffectedFd(int fd) {
  struct stat st;
  if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) return false;
  char link[64];
  std::snprintf(link, sizeof(link), "/proc/self/fd/%d", fd);
  char path[4096];
  const ssize_t n = readlink(link, path, sizeof(path) - 1);
  if (n <= 0) return false;
  path[n] = '\0';
  return Matches(path);
}

using WriteFn = ssize_t (*)(int, const void*, size_t);
using MkstempFn = int (*)(char*);
using OpenFn = int (*)(const char*, int, ...);

template <typename Fn>
Fn Next(const char* name) {
  return reinterpret_cast<Fn>(dlsym(RTLD_NEXT, name));
}

int Mkstemp(const char* name, char* tmpl) {
  static MkstempFn real = Next<MkstempFn>(name);
  const Config& c = GetConfig();
  if (c.on_create && Matches(tmpl)) {
    errno = c.err;
    return -1;
  }
  return real(tmpl);
}

int Open(const char* name, const char* path, int flags, mode_t mode) {
  static OpenFn real = Next<OpenFn>(name);
  const Config& c = GetConfig();
  if (c.on_create && (flags & O_CREAT) != 0 && Matches(path)) {
    errno = c.err;
    return -1;
  }
  return real(path, flags, mode);
}

// open()'s mode argument is there only when the flags create a file.
mode_t ModeArgument(int flags, va_list args) {
  return (flags & (O_CREAT | O_TMPFILE)) != 0 ? static_cast<mode_t>(va_arg(args, int)) : 0;
}

}  // namespace

extern "C" __attribute__((visibility("default"))) ssize_t write(int fd, const void* buf,
                                                                size_t count) {
  static WriteFn real = Next<WriteFn>("write");
  const Config& c = GetConfig();
  if (c.on_create || count == 0 || !AffectedFd(fd)) return real(fd, buf, count);
  const long long room = c.after_bytes - g_written.load();
  if (room <= 0) {
    errno = c.err;
    return -1;
  }
  const size_t n = static_cast<size_t>(room) < count ? static_cast<size_t>(room) : count;
  const ssize_t done = real(fd, buf, n);
  if (done > 0) g_written += done;
  return done;
}

extern "C" __attribute__((visibility("default"))) int mkstemp(char* tmpl) {
  return Mkstemp("mkstemp", tmpl);
}

extern "C" __attribute__((visibility("default"))) int mkstemp64(char* tmpl) {
  return Mkstemp("mkstemp64", tmpl);
}

extern "C" __attribute__((visibility("default"))) int open(const char* path, int flags, ...) {
  va_list args;
  va_start(args, flags);
  const mode_t mode = ModeArgument(flags, args);
  va_end(args);
  return Open("open", path, flags, mode);
}

extern "C" __attribute__((visibility("default"))) int open64(const char* path, int flags, ...) {
  va_list args;
  va_start(args, flags);
  const mode_t mode = ModeArgument(flags, args);
  va_end(args);
  return Open("open64", path, flags, mode);
}
