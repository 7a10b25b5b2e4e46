// How the tool writes its output files: atomic replacement of regular files, in-place writes to
// devices and FIFOs, and a checked stream for files written as they go (the latency log).
//
// The rule every sfrt output follows (the contract of this header):
//   - A path that does not exist yet, or names a regular file, is replaced atomically: the data
//     goes to a temporary file in the same directory, which is flushed to disk (fsync) and then
//     renamed over the path. On any failure the temporary file is removed and the path is left
//     as it was. A writer of files at frame rate may defer the flush (Flush::kLater): the file
//     is still renamed into place whole, so no reader and no crash of the program ever sees part
//     of it, but a power cut before the kernel writes it back can leave it missing or empty; such a
//     writer calls FlushFileSystemOf() when it stops.
//   - A symbolic link is followed, through any chain of links (at most 40), and the rule applies
//     to the path it finally names: a regular file there is replaced atomically at that path, so
//     the link survives and points at the new file. A dangling link creates the file it names;
//     that file's directory must exist. A relative link target is relative to the link's
//     directory.
//   - A character device or a FIFO (/dev/stdout, /dev/null, a pipe read by a logger) is written
//     in place: opened for writing without creating or truncating it (opening a FIFO waits for
//     its reader), every write() and the close() checked. It is never replaced.
//   - A directory, a socket or a block device is refused.
//   - Success is reported only when every byte was written and the file was closed (and, for a
//     regular file, flushed). Errors name the file, the failing step and the system's reason,
//     e.g. "cannot write '/dev/full' (write): No space left on device".
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>

#include "sfrt/status.h"

namespace sfrt::io {

// Where and how an output path is written, after following symbolic links.
struct OutputTarget {
  enum class Kind {
    kReplace,  // regular file or a path that does not exist: temporary file + rename
    kInPlace,  // character device or FIFO: opened and written as it is
  };
  std::string path;  // the path finally written (the link's target for a symbolic link)
  Kind kind = Kind::kReplace;
  std::string what;  // "a regular file", "a new file", "a character device", "a FIFO"
};

// Follows `path` through symbolic links and classifies what it names, by the rule above.
// Refused (error naming the path): a directory, a socket, a block device, a loop of links.
Result<OutputTarget> ResolveOutputTarget(const std::string& path);

// When a replaced file's data is flushed to disk.
enum class Flush {
  kBeforeRename,  // fsync before the rename: on disk when the call returns (the default)
  kLater,         // left to the kernel's writeback, or to FlushFileSystemOf() (per-frame files:
                  // an fsync a frame costs 0.2-0.5 ms on this VM and far more on a robot's eMMC)
};

// Writes `bytes` to `path` by the rule above: atomically for regular files and new paths, in
// place for character devices and FIFOs.
Status WriteFileAtomically(const std::string& path, std::span<const uint8_t> bytes,
                           Flush flush = Flush::kBeforeRename);

// Flushes to disk everything written to the file system that holds directory `dir` (syncfs), so
// the files written there with Flush::kLater are on disk when it returns. Errors name `dir`.
Status FlushFileSystemOf(const std::string& dir);

// A file written piece by piece while the program runs (sfrt run --latency-log). A regular file
// (or new path) is created or truncated and written directly, not via a temporary file, so a
// reader sees it grow; a character device or FIFO is written in place; the rest is refused, as
// above. Each Write() is one checked write() (no user-space buffer), so a full disk is reported
// by the write that hit it.
class StreamedFile {
 public:
  StreamedFile() = default;
  StreamedFile(const StreamedFile&) = delete;
  StreamedFile& operator=(const StreamedFile&) = delete;
  StreamedFile(StreamedFile&& other) noexcept;
  StreamedFile& operator=(StreamedFile&& other) noexcept;
  ~StreamedFile();  // closes without reporting; call Close() to know whether it worked

  static Result<StreamedFile> Open(const std::string& path);
  bool is_open() const { return fd_ >= 0; }
  const std::string& path() const { return path_; }

  // Writes all of `text`. Errors name the file and the system's reason.
  Status Write(std::string_view text);
  // Flushes a regular file to disk (fsync) and closes. Errors name the file.
  Status Close();

 private:
  StreamedFile(int fd, std::string path, bool regular)
      : fd_(fd), path_(std::move(path)), regular_(regular) {}
  int fd_ = -1;
  std::string path_;
  bool regular_ = false;
};

// Reads a whole file. Errors name the file.
Result<std::string> ReadWholeFile(const std::string& path);

// Empty when files can be created in the directory `path`, or, if it does not exist yet, in its
// nearest existing ancestor (so creating it would work); otherwise a message naming `what` (an
// option, e.g. "--out"), the path and the reason. Tests by creating and removing a file: nothing
// is left behind. For checking every output location before the first frame.
std::string CheckWritableDirectory(const std::string& path, std::string_view what);

}  // namespace sfrt::io
