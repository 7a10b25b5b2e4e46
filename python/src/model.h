// sfrt.Model: a loaded, verified model file, shared by any number of sessions (they keep it
// alive) and threads (it is immutable after loading).
#pragma once

#include <pybind11/pybind11.h>

#include <memory>
#include <string>

#include "sfrt/isa.h"
#include "sfrt/model.h"

namespace sfrt::python {

struct PyModel {
  std::shared_ptr<const Model> model;
  std::string path;
};

void BindModel(pybind11::module_& m);

// The size a session or replay runs at: `size` as (H, W), or None for the size a trained model
// records; a ValueError naming `size` otherwise.
void SessionSize(const PyModel& model, const pybind11::object& size, int* height, int* width);

// A thread count within the command line's limits (0: one per CPU); a ValueError otherwise.
int ThreadsArgument(int threads);

// An ISA name ("auto", "avx512", ...), checked against this CPU: a ValueError listing the ones
// it runs otherwise.
Isa ParseIsaArgument(const std::string& name);

}  // namespace sfrt::python
