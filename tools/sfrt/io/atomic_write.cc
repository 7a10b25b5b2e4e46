#include "sfrt/io/atomic_write.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

namespace sfrt::tools {
namespace {

std::string ErrnoText(int err) { return std::strerror(err); }

}  // namespace

Status WriteFileAtomically(const std::string& path, std::span<const uint8_t> bytes) {
  if (path.empty()) return Status::Error("cannot write a file with an empty name");
  // mkstemp needs a writable template in the destination directory so rename() stays atomic.
  std::string tmpl = path + ".tmp.XXXXXX";
  int fd = ::mkstemp(tmpl.data());
  if (fd < 0) {
    return Status::Error("cannot create a temporary file beside '" + path +
                         "': " + ErrnoText(errno));
  }
  auto fail = [&](const std::string& step, int err) {
    ::close(fd);
    ::unlink(tmpl.c_str());
    return Status::Error("cannot write '" + path + "' (" + step + "): " + ErrnoText(err));
  };
  // mkstemp creates the file 0600; give it the usual permissions, as open(O_CREAT) would.
  mode_t mask = ::umask(0);
  ::umask(mask);
  if (::fchmod(fd, 0666 & ~mask) != 0) return fail("chmod", errno);

  size_t done = 0;
  while (done < bytes.size()) {
    ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return fail("write", errno);
    }
    done += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) return fail("fsync", errno);
  if (::close(fd) != 0) {
    int err = errno;
    ::unlink(tmpl.c_str());
    return Status::Error("cannot write '" + path + "' (close): " + ErrnoText(err));
  }
  if (::rename(tmpl.c_str(), path.c_str()) != 0) {
    int err = errno;
    ::unlink(tmpl.c_str());
    return Status::Error("cannot write '" + path + "' (rename): " + ErrnoText(err));
  }
  return Status::Ok();
}

Result<std::string> ReadWholeFile(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    return Status::Error("cannot read '" + path + "': it is a directory");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::Error("cannot open '" + path + "': " + ErrnoText(errno));
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return Status::Error("cannot read '" + path + "': I/O error");
  return data;
}

}  // namespace sfrt::tools
