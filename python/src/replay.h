// sfrt.replay(): the windows `sfrt run` would write for a replay (files, a Scene Flow dataset, a
// video or a bag), as a Python iterator.
#pragma once

#include <pybind11/pybind11.h>

namespace sfrt::python {

void BindReplay(pybind11::module_& m);

}  // namespace sfrt::python
