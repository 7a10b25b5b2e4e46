// sfrt.Session: a model planned for one input size (arena, packed weights, kernels), run on
// four images, two RGB-D frames or the network's input tensor.
#pragma once

#include <pybind11/pybind11.h>

namespace sfrt::python {

void BindSession(pybind11::module_& m);

}  // namespace sfrt::python
