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
//                      create: creating an affected file with mkstemp() fails (as in a read-only
//                      directory).
//   SFRT_FAULT_AFTER_BYTES  see above (default 0).
#include <dlfcn.h>
#include <errno.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include <atomic>
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
