#include "errors.h"

#include <unistd.h>

#include <cerrno>
#include <filesystem>

namespace py = pybind11;

namespace sfrt::python {

void RegisterErrors(py::module_& m) {
  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  error.doc() =
      "A failure of the sfrt library (a model that does not load or verify, a session that "
      "cannot be planned, a run that fails); the message is the C++ library's, naming the file, "
      "field and value.";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
      PyErr_SetString(error.ptr(), e.what());
    } catch (const PathError& e) {
      PyObject* type = e.err() == EACCES || e.err() == EPERM ? PyExc_PermissionError
                       : e.err() == EISDIR                   ? PyExc_IsADirectoryError
                       : e.err() == ENOTDIR                  ? PyExc_NotADirectoryError
                                                             : PyExc_FileNotFoundError;
      py::object args = py::make_tuple(e.err(), e.what(), e.path());
      PyErr_SetObject(type, args.ptr());
    }
  });
}

void ThrowIfError(const Status& status) {
  if (!status.ok()) throw Error(status.message());
}

void ThrowValueIfError(const Status& status) {
  if (!status.ok()) throw py::value_error(status.message());
}

void CheckReadablePath(const std::string& path, const std::string& what, bool want_directory) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (path.empty() || !fs::exists(st)) {
    throw PathError(ENOENT, what + " '" + path + "' does not exist", path);
  }
  if (want_directory && !fs::is_directory(st)) {
    throw PathError(ENOTDIR, what + " '" + path + "' is not a directory", path);
  }
  if (!want_directory && fs::is_directory(st)) {
    throw PathError(EISDIR, what + " '" + path + "' is a directory, not a file", path);
  }
  if (::access(path.c_str(), R_OK) != 0) {
    throw PathError(errno, what + " '" + path + "' cannot be read (permission denied)", path);
  }
}

}  // namespace sfrt::python
