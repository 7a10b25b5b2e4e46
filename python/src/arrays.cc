#include "arrays.h"

#include <cstdint>
#include <limits>
#include <string>

namespace py = pybind11;

namespace sfrt::python {
namespace {

std::string ShapeText(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) {
    s += (i ? ", " : "") + std::to_string(a.shape(i));
  }
  return s + (a.ndim() == 1 ? ",)" : ")");
}

std::string DtypeText(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

// The object as an array, or a TypeError naming the argument and what it expected.
py::array AsArray(const py::object& object, const char* name, const char* expected) {
  if (!py::isinstance<py::array>(object)) {
    throw py::type_error(std::string(name) + ": expected a numpy array " + expected + ", got " +
                         py::str(py::type::of(object).attr("__name__")).cast<std::string>());
  }
  return py::reinterpret_borrow<py::array>(object);
}

bool IsDtype(const py::array& a, char kind, py::ssize_t bytes) {
  return a.dtype().kind() == kind && a.itemsize() == bytes &&
         (bytes == 1 || a.dtype().attr("isnative").cast<bool>());
}

// Rows and columns that fit an int and are not zero.
void CheckSides(const py::array& a, const char* name, const char* expected) {
  for (int i = 0; i < 2; ++i) {
    if (a.shape(i) <= 0 || a.shape(i) > std::numeric_limits<int>::max()) {
      throw py::value_error(std::string(name) + ": shape " + ShapeText(a) + "; expected " +
                            expected + " with H and W at least 1");
    }
  }
}

// A cv::Mat over the array when each row's pixels are packed (element stride `elem`, pixel
// stride `pixel` bytes); else over a packed copy held in *keep.
template <typename T>
cv::Mat View(const py::array& a, int rows, int cols, int type, py::ssize_t pixel, py::array* keep) {
  const bool packed = a.strides(1) == pixel &&
                      (a.ndim() == 2 || a.strides(2) == static_cast<py::ssize_t>(sizeof(T))) &&
                      a.strides(0) >= pixel * cols &&
                      a.strides(0) % static_cast<py::ssize_t>(sizeof(T)) == 0 &&
                      reinterpret_cast<uintptr_t>(a.data()) % alignof(T) == 0;
  if (packed) {
    return cv::Mat(rows, cols, type, const_cast<void*>(a.data()),
                   static_cast<size_t>(a.strides(0)));
  }
  *keep = py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(a);
  return cv::Mat(rows, cols, type, keep->mutable_data());
}

}  // namespace

cv::Mat ImageView(const py::object& image, const char* name, py::array* keep) {
  constexpr char kExpected[] = "(H, W, 3) of uint8";
  py::array a = AsArray(image, name, kExpected);
  if (a.ndim() != 3 || a.shape(2) != 3) {
    throw py::value_error(std::string(name) + ": shape " + ShapeText(a) + "; expected " +
                          kExpected + " (a colour image)");
  }
  if (!IsDtype(a, 'u', 1)) {
    throw py::value_error(std::string(name) + ": dtype " + DtypeText(a) + "; expected " +
                          kExpected + " (convert with .astype(numpy.uint8) if it is 0..255)");
  }
  CheckSides(a, name, kExpected);
  return View<uint8_t>(a, static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC3, 3,
                       keep);
}

cv::Mat DepthView(const py::object& depth, const char* name, py::array* keep) {
  constexpr char kExpected[] = "(H, W) of uint16 (depth units) or float32 (metres)";
  py::array a = AsArray(depth, name, kExpected);
  if (a.ndim() != 2 && !(a.ndim() == 3 && a.shape(2) == 1)) {
    throw py::value_error(std::string(name) + ": shape " + ShapeText(a) + "; expected " +
                          kExpected);
  }
  CheckSides(a, name, kExpected);
  const int rows = static_cast<int>(a.shape(0));
  const int cols = static_cast<int>(a.shape(1));
  if (IsDtype(a, 'u', 2)) return View<uint16_t>(a, rows, cols, CV_16UC1, 2, keep);
  if (IsDtype(a, 'f', 4)) return View<float>(a, rows, cols, CV_32FC1, 4, keep);
  throw py::value_error(std::string(name) + ": dtype " + DtypeText(a) + "; expected " + kExpected);
}

std::span<const float> TensorView::data() const {
  return {array.data(), static_cast<size_t>(array.size())};
}

TensorView FloatTensor(const py::object& tensor, const char* name, int channels) {
  const std::string expected = "(H, W, " + std::to_string(channels) + ") or (1, H, W, " +
                               std::to_string(channels) + ") of float32, the network's input";
  py::array a = AsArray(tensor, name, expected.c_str());
  const bool batched = a.ndim() == 4 && a.shape(0) == 1;
  if ((a.ndim() != 3 && !batched) || a.shape(a.ndim() - 1) != channels) {
    throw py::value_error(std::string(name) + ": shape " + ShapeText(a) + "; expected " + expected);
  }
  if (!IsDtype(a, 'f', 4)) {
    throw py::value_error(std::string(name) + ": dtype " + DtypeText(a) + "; expected " + expected);
  }
  TensorView v;
  v.array = py::array_t<float, py::array::c_style>::ensure(a);  // a copy only when not packed
  const py::ssize_t first = batched ? 1 : 0;
  for (py::ssize_t i = first; i < first + 2; ++i) {
    if (a.shape(i) <= 0 || a.shape(i) > std::numeric_limits<int>::max()) {
      throw py::value_error(std::string(name) + ": shape " + ShapeText(a) + "; expected " +
                            expected + " with H and W at least 1");
    }
  }
  v.height = static_cast<int>(a.shape(first));
  v.width = static_cast<int>(a.shape(first + 1));
  v.channels = channels;
  return v;
}

py::array_t<float> OutputArray(const py::object& out, const TensorShape& shape) {
  const std::string expected = "(" + std::to_string(shape.height) + ", " +
                               std::to_string(shape.width) + ", " + std::to_string(shape.channels) +
                               ") of float32, C-contiguous and writeable";
  if (out.is_none()) return py::array_t<float>({shape.height, shape.width, shape.channels});
  py::array a = AsArray(out, "out", expected.c_str());
  if (!IsDtype(a, 'f', 4)) {
    throw py::value_error("out: dtype " + DtypeText(a) + "; expected " + expected);
  }
  if (a.ndim() != 3 || a.shape(0) != shape.height || a.shape(1) != shape.width ||
      a.shape(2) != shape.channels) {
    throw py::value_error("out: shape " + ShapeText(a) + "; expected " + expected);
  }
  if (!(a.flags() & py::array::c_style)) {
    throw py::value_error("out: not C-contiguous; expected " + expected);
  }
  if (!a.writeable()) throw py::value_error("out: read-only; expected " + expected);
  return py::reinterpret_borrow<py::array_t<float>>(a);
}

std::span<float> Floats(py::array_t<float>& array) {
  return {array.mutable_data(), static_cast<size_t>(array.size())};
}

}  // namespace sfrt::python
