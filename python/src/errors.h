// How the package reports failures: every C++ Status becomes a Python exception carrying its
// message unchanged.
//   sfrt.Error (a RuntimeError)   a load, plan or run failure (Status from the library)
//   ValueError                    an argument of the wrong dtype, rank, channel count or size,
//                                 naming the argument and what was expected
//   FileNotFoundError, PermissionError, IsADirectoryError (OSError)
//                                 a path that cannot be read, with errno and the path set
// The C++ exceptions below are plain (no Python object): they may be thrown with the GIL
// released; pybind11 turns them into Python exceptions on the way out.
#pragma once

#include <pybind11/pybind11.h>

#include <stdexcept>
#include <string>

#include "sfrt/status.h"

namespace sfrt::python {

// sfrt.Error.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// An OSError subclass chosen from the errno, with errno, message and path.
class PathError : public std::runtime_error {
 public:
  PathError(int err, const std::string& message, std::string path)
      : std::runtime_error(message), errno_(err), path_(std::move(path)) {}
  int err() const { return errno_; }
  const std::string& path() const { return path_; }

 private:
  int errno_;
  std::string path_;
};

// Registers sfrt.Error and the translators; once, from the module's init.
void RegisterErrors(pybind11::module_& m);

// Throws sfrt.Error with the status's message when it is an error.
void ThrowIfError(const Status& status);
// Throws ValueError with the status's message when it is an error.
void ThrowValueIfError(const Status& status);

// A path to read: a FileNotFoundError, PermissionError or IsADirectoryError naming `what` and the
// path when it cannot be opened for reading as a regular file (want_directory: a directory).
void CheckReadablePath(const std::string& path, const std::string& what, bool want_directory);

}  // namespace sfrt::python
