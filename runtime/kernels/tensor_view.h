// Views of NHWC activations (one image) shared by every kernel tier. Pixels are dense (channel
// stride 1, pixel stride = channels); rows may be further apart than width * channels, which is
// how a crop becomes a view instead of a copy.
#pragma once

#include <cstddef>

namespace sfrt {

struct ConstTensorView {
  const float* data = nullptr;
  int height = 0;
  int width = 0;
  int channels = 0;
  ptrdiff_t row_stride = 0;  // in floats

  const float* pixel(int y, int x) const {
    return data + y * row_stride + static_cast<ptrdiff_t>(x) * channels;
  }
};

struct TensorView {
  float* data = nullptr;
  int height = 0;
  int width = 0;
  int channels = 0;
  ptrdiff_t row_stride = 0;  // in floats

  float* pixel(int y, int x) const {
    return data + y * row_stride + static_cast<ptrdiff_t>(x) * channels;
  }
  operator ConstTensorView() const { return {data, height, width, channels, row_stride}; }
};

inline TensorView DenseView(float* data, int height, int width, int channels) {
  return {data, height, width, channels, static_cast<ptrdiff_t>(width) * channels};
}

}  // namespace sfrt
