// Status and Result<T>: how every sfrt function that can fail reports it, in every module (the
// runtime, camera capture and files, the exporter, the pipeline, the tools), declared once here so
// that modules that may not use one another (camera/ and runtime/) still share one type.
//
// A failure carries one line (no trailing newline) naming the file or device, the call, key or
// field, and the offending value. No exceptions cross sfrt APIs.
//
// A failure also carries what a caller needs to decide what to do next without parsing the text:
// an ErrorKind (unplugged? busy? no USB bandwidth? watchdog?) and, when a system call failed, its
// errno. Capture gives every error a specific kind, e.g.
//   Status::Error(ErrorKind::kNoBandwidth,
//                 "/dev/video0: VIDIOC_STREAMON: ENOSPC (No space left on device): ...", ENOSPC)
// Errors whose kind would change nothing for the caller (a missing file, a bad model field) use
// Status::Error(message), whose kind is kGeneric and errno 0. An ok Status holds no heap memory,
// so returning one allocates nothing.
#pragma once

#include <cassert>
#include <optional>
#include <string>
#include <utility>

namespace sfrt {

enum class ErrorKind {
  kNone = 0,         // not an error: the kind of an ok Status
  kInvalidArgument,  // the caller asked for something impossible (bad config, not open)
  kNotV4l2,          // the path is not a V4L2 capture device with streaming I/O
  kUnsupported,      // no pixel format / memory mode we can use
  kBusy,             // EBUSY: another process holds the device or its buffers
  kNoBandwidth,      // ENOSPC at STREAMON: the USB controller cannot carry this stream
  kDisconnected,     // ENODEV/ENXIO or POLLERR|POLLHUP confirmed: the device was removed
  kTimeout,          // the watchdog expired: no frame within the configured time
  kIo,               // EIO and other errors the driver reports while streaming
  kFrameError,       // one frame could not be used (corrupt MJPEG, short buffer); the next may
  kSystem,           // any other failing system call
  kGeneric,          // no particular kind; the message says what failed (Status::Error(message))
  kCancelled,        // the caller's cancel flag ended a wait (a stop request during a back-off)
};

// A short lower-case name for a kind ("busy", "disconnected", ...), for logs.
constexpr const char* ErrorKindName(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::kNone:
      return "ok";
    case ErrorKind::kInvalidArgument:
      return "invalid argument";
    case ErrorKind::kNotV4l2:
      return "not a V4L2 capture device";
    case ErrorKind::kUnsupported:
      return "unsupported";
    case ErrorKind::kBusy:
      return "busy";
    case ErrorKind::kNoBandwidth:
      return "no USB bandwidth";
    case ErrorKind::kDisconnected:
      return "disconnected";
    case ErrorKind::kTimeout:
      return "timeout";
    case ErrorKind::kIo:
      return "I/O error";
    case ErrorKind::kFrameError:
      return "frame error";
    case ErrorKind::kSystem:
      return "system error";
    case ErrorKind::kGeneric:
      return "error";
    case ErrorKind::kCancelled:
      return "cancelled";
  }
  return "unknown";
}

class [[nodiscard]] Status {
 public:
  Status() = default;  // OK
  static Status Ok() { return Status(); }
  // A failure of no particular kind (kGeneric, errno 0).
  static Status Error(std::string message) {
    return Status(ErrorKind::kGeneric, std::move(message), 0);
  }
  // A failure of the given kind; sys_errno is the errno of the failing system call, 0 if none.
  // kNone is not a failure kind: it asserts, and becomes kGeneric when asserts are off, so an
  // error never reads as ok.
  static Status Error(ErrorKind kind, std::string message, int sys_errno = 0) {
    assert(kind != ErrorKind::kNone && "an error needs a kind other than kNone");
    if (kind == ErrorKind::kNone) kind = ErrorKind::kGeneric;
    return Status(kind, std::move(message), sys_errno);
  }

  bool ok() const { return kind_ == ErrorKind::kNone; }
  explicit operator bool() const { return ok(); }
  // kNone when ok().
  ErrorKind kind() const { return kind_; }
  // errno of the failing call, 0 when the error is not from a system call (and when ok()).
  int sys_errno() const { return errno_; }
  // The one-line description of the failure; empty when ok().
  const std::string& message() const { return message_; }

 private:
  Status(ErrorKind kind, std::string message, int sys_errno)
      : kind_(kind), errno_(sys_errno), message_(std::move(message)) {}
  ErrorKind kind_ = ErrorKind::kNone;
  int errno_ = 0;
  std::string message_;
};

// Either a value or the Status explaining why there is none.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}       // NOLINT: implicit by design
  Result(Status error) : status_(std::move(error)) {  // NOLINT: implicit by design
    assert(!status_.ok() && "a Result built from a Status must carry an error");
  }

  bool ok() const { return value_.has_value(); }
  explicit operator bool() const { return ok(); }
  const Status& status() const { return status_; }
  const std::string& message() const { return status_.message(); }

  T& value() & {
    assert(ok());
    return *value_;
  }
  const T& value() const& {
    assert(ok());
    return *value_;
  }
  T&& value() && {
    assert(ok());
    return std::move(*value_);
  }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace sfrt
