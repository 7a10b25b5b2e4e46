// numpy arrays in and out of the library, without a copy where the layout allows one.
//   in:  a uint8 (H, W, 3) image whose pixels are packed (strides (any, 3, 1): C-contiguous, or a
//        crop of one) is read in place as a cv::Mat; another layout is copied once into a packed
//        array the caller keeps alive for the call. Depth maps likewise (uint16 or float32).
//   out: the caller's `out=` array (float32, C-contiguous, writeable, of the output's shape) is
//        written in place; otherwise a new array owns its memory.
// Every refusal is a ValueError naming the argument and what was expected.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <opencv2/core.hpp>
#include <span>

#include "sfrt/shapes.h"

namespace sfrt::python {

// A colour image: uint8 of shape (H, W, 3). `keep` holds a packed copy when one was needed.
cv::Mat ImageView(const pybind11::object& image, const char* name, pybind11::array* keep);

// A depth map: uint16 (units per metre) or float32 (metres), shape (H, W) or (H, W, 1).
cv::Mat DepthView(const pybind11::object& depth, const char* name, pybind11::array* keep);

// A float32 tensor of shape (H, W, C) or (1, H, W, C), C-contiguous (copied once if not).
struct TensorView {
  pybind11::array_t<float> array;  // keeps the memory alive
  int height = 0;
  int width = 0;
  int channels = 0;
  std::span<const float> data() const;
};
TensorView FloatTensor(const pybind11::object& tensor, const char* name, int channels);

// The array the output goes to: `out` when given (checked: float32, C-contiguous, writeable,
// exactly `shape`), else a new (H, W, C) float32 array.
pybind11::array_t<float> OutputArray(const pybind11::object& out, const TensorShape& shape);
std::span<float> Floats(pybind11::array_t<float>& array);

}  // namespace sfrt::python
