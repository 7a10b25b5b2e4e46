// The `sfrt._sfrt` extension module: the classes and functions sfrt/__init__.py re-exports.
#include <pybind11/pybind11.h>

#include "errors.h"
#include "evaluate.h"
#include "model.h"
#include "replay.h"
#include "session.h"

PYBIND11_MODULE(_sfrt, m) {
  m.doc() = "sfrt: SceneEDNet scene flow on the CPU (the C++ library's Python binding)";
  m.attr("__version__") = SFRT_VERSION;
  sfrt::python::RegisterErrors(m);
  sfrt::python::BindModel(m);
  sfrt::python::BindSession(m);
  sfrt::python::BindReplay(m);
  sfrt::python::BindEvaluate(m);
}
