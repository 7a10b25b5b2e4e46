#include "sfrt/pipeline/io/atomic_write.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

namespace sfrt::io {
namespace {

std::string ErrnoText(int err) { return std::strerror(err); }

constexpr int kMaxLinks = 40;  // as the kernel's own limit on a chain of symbolic links

// Writes all of `bytes` to `fd`, retrying short writes and EINTR. Returns 0 or the errno.
int WriteAll(int fd, const uint8_t* data, size_t size) {
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (n == 0) return EIO;  // a write that makes no progress would loop forever
    done += static_cast<size_t>(n);
  }
  return 0;
}

Status WriteError(const std::string& path, const std::string& step, int err) {
  return Status::Error("cannot write '" + path + "' (" + step + "): " + ErrnoText(err));
}

// The in-place write of a character device or FIFO: no create, no truncate, no rename.
Status WriteInPlace(const OutputTarget& target, std::span<const uint8_t> bytes) {
  const int fd = ::open(target.path.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) return WriteError(target.path, "open " + target.what, errno);
  if (int err = WriteAll(fd, bytes.data(), bytes.size()); err != 0) {
    ::close(fd);
    return WriteError(target.path, "write", err);
  }
  if (::close(fd) != 0) return WriteError(target.path, "close", errno);
  return Status::Ok();
}

// Creates a new file beside `path` for writing, named "<path>.tmp.<pid>.<n>", and returns its
// descriptor (or -1 with errno set). open() applies the process's umask to 0666 as it does for
// any new file, so the final file gets the usual permissions without reading the umask (which
// only umask() can, by changing it for every thread a moment). O_EXCL: a name another writer
// holds is never reused; the counter moves on.
int CreateTemporaryBeside(const std::string& path, std::string* tmp) {
  static std::atomic<uint64_t> counter{0};
  constexpr int kAttempts = 100;
  for (int i = 0; i < kAttempts; ++i) {
    *tmp = path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
    const int fd = ::open(tmp->c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOCTTY, 0666);
    if (fd >= 0 || errno != EEXIST) return fd;
  }
  errno = EEXIST;
  return -1;
}

Status ReplaceAtomically(const std::string& path, std::span<const uint8_t> bytes, Flush flush) {
  // The temporary file is in the destination directory so that rename() stays atomic.
  std::string tmpl;
  const int fd = CreateTemporaryBeside(path, &tmpl);
  if (fd < 0) {
    return Status::Error("cannot create a temporary file beside '" + path +
                         "': " + ErrnoText(errno));
  }
  auto fail = [&](const std::string& step, int err) {
    ::close(fd);
    ::unlink(tmpl.c_str());
    return WriteError(path, step, err);
  };
  if (int err = WriteAll(fd, bytes.data(), bytes.size()); err != 0) return fail("write", err);
  if (flush == Flush::kBeforeRename && ::fsync(fd) != 0) return fail("fsync", errno);
  if (::close(fd) != 0) {
    int err = errno;
    ::unlink(tmpl.c_str());
    return WriteError(path, "close", err);
  }
  if (::rename(tmpl.c_str(), path.c_str()) != 0) {
    int err = errno;
    ::unlink(tmpl.c_str());
    return WriteError(path, "rename", err);
  }
  return Status::Ok();
}

}  // namespace

Result<OutputTarget> ResolveOutputTarget(const std::string& path) {
  if (path.empty()) return Status::Error("cannot write a file with an empty name");
  std::filesystem::path p(path);
  for (int links = 0;; ++links) {
    struct stat st;
    if (::lstat(p.c_str(), &st) != 0) {
      if (errno == ENOENT)
        return OutputTarget{p.string(), OutputTarget::Kind::kReplace, "a new file"};
      return Status::Error("cannot write '" + p.string() + "': " + ErrnoText(errno));
    }
    if (S_ISLNK(st.st_mode)) {
      if (links == kMaxLinks) {
        return Status::Error("cannot write '" + path + "': more than " + std::to_string(kMaxLinks) +
                             " symbolic links to follow (a loop?)");
      }
      std::error_code ec;
      const std::filesystem::path target = std::filesystem::read_symlink(p, ec);
      if (ec)
        return Status::Error("cannot read the symbolic link '" + p.string() + "': " + ec.message());
      p = target.is_absolute() ? target : p.parent_path() / target;
      continue;
    }
    const std::string at =
        p.string() == path ? "'" + path + "'" : "'" + path + "' (-> '" + p.string() + "')";
    if (S_ISREG(st.st_mode))
      return OutputTarget{p.string(), OutputTarget::Kind::kReplace, "a regular file"};
    if (S_ISCHR(st.st_mode))
      return OutputTarget{p.string(), OutputTarget::Kind::kInPlace, "a character device"};
    if (S_ISFIFO(st.st_mode))
      return OutputTarget{p.string(), OutputTarget::Kind::kInPlace, "a FIFO"};
    if (S_ISDIR(st.st_mode)) return Status::Error("cannot write " + at + ": it is a directory");
    if (S_ISSOCK(st.st_mode)) return Status::Error("cannot write " + at + ": it is a socket");
    if (S_ISBLK(st.st_mode)) {
      return Status::Error("cannot write " + at +
                           ": it is a block device (sfrt does not write onto disks)");
    }
    return Status::Error("cannot write " + at + ": not a regular file, character device or FIFO");
  }
}

Status WriteFileAtomically(const std::string& path, std::span<const uint8_t> bytes, Flush flush) {
  Result<OutputTarget> target = ResolveOutputTarget(path);
  if (!target.ok()) return target.status();
  if (target->kind == OutputTarget::Kind::kInPlace) return WriteInPlace(*target, bytes);
  return ReplaceAtomically(target->path, bytes, flush);
}

Status FlushFileSystemOf(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return WriteError(dir, "open the directory to flush it", errno);
  if (::syncfs(fd) != 0) {
    const int err = errno;
    ::close(fd);
    return WriteError(dir, "syncfs", err);
  }
  ::close(fd);
  return Status::Ok();
}

StreamedFile::StreamedFile(StreamedFile&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), path_(std::move(other.path_)), regular_(other.regular_) {}

StreamedFile& StreamedFile::operator=(StreamedFile&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    path_ = std::move(other.path_);
    regular_ = other.regular_;
  }
  return *this;
}

StreamedFile::~StreamedFile() {
  if (fd_ >= 0) ::close(fd_);
}

Result<StreamedFile> StreamedFile::Open(const std::string& path) {
  Result<OutputTarget> target = ResolveOutputTarget(path);
  if (!target.ok()) return target.status();
  const bool regular = target->kind == OutputTarget::Kind::kReplace;
  const int flags = O_WRONLY | O_CLOEXEC | O_NOCTTY | (regular ? O_CREAT | O_TRUNC : 0);
  const int fd = ::open(target->path.c_str(), flags, 0666);
  if (fd < 0) return WriteError(path, "open " + target->what, errno);
  return StreamedFile(fd, path, regular);
}

Status StreamedFile::Write(std::string_view text) {
  if (fd_ < 0) return Status::Error("cannot write '" + path_ + "': it is not open");
  if (int err = WriteAll(fd_, reinterpret_cast<const uint8_t*>(text.data()), text.size());
      err != 0) {
    return WriteError(path_, "write", err);
  }
  return Status::Ok();
}

Status StreamedFile::Close() {
  if (fd_ < 0) return Status::Ok();
  const int fd = std::exchange(fd_, -1);
  if (regular_ && ::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    return WriteError(path_, "fsync", err);
  }
  if (::close(fd) != 0) return WriteError(path_, "close", errno);
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

std::string CheckWritableDirectory(const std::string& path, std::string_view what) {
  namespace fs = std::filesystem;
  const std::string head = std::string(what) + " '" + path + "': ";
  fs::path dir = fs::path(path).lexically_normal();
  if (!dir.empty() && dir.filename().empty()) dir = dir.parent_path();  // "out/" -> "out"
  std::error_code ec;
  while (!dir.empty() && !fs::exists(fs::symlink_status(dir, ec)) && !fs::exists(dir, ec)) {
    dir = dir.parent_path();
  }
  if (dir.empty()) dir = ".";
  if (!fs::is_directory(dir, ec)) {
    return head + "'" + dir.string() + "' exists and is not a directory";
  }
  std::string probe = (dir / ".sfrt-write-test-XXXXXX").string();
  const int fd = ::mkstemp(probe.data());
  if (fd < 0)
    return head + "cannot create files in '" + dir.string() + "' (" + ErrnoText(errno) + ")";
  ::close(fd);
  ::unlink(probe.c_str());
  return "";
}

}  // namespace sfrt::io
