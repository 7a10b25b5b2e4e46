// sfrt.evaluate(): `sfrt eval` over a dataset with ground truth, as the dict its --json writes.
#pragma once

#include <pybind11/pybind11.h>

namespace sfrt::python {

void BindEvaluate(pybind11::module_& m);

}  // namespace sfrt::python
