// Views of NHWC activations (one image) shared by every kernel tier. Float32 pixels are dense
// (channel stride 1, pixel stride = channels); rows may be further apart than width * channels,
// which is how a crop becomes a view instead of a copy.
#pragma once

#include <cstddef>
#include <cstdint>

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

// The same for the reduced-precision tensors: uint8 (int8 convolutions) and bf16 bits (bf16
// convolutions). row_stride is in elements. Their pixels may also lie further apart than
// `channels` (pixel_stride, in elements; 0 means dense): a uint8 tensor that a session places in
// its slice of a Concat's tensor is a view with the Concat's pixel and row strides, which its
// producer writes and its other readers read in place.
template <typename T>
struct ConstPlaneView {
  const T* data = nullptr;
  int height = 0;
  int width = 0;
  int channels = 0;
  ptrdiff_t row_stride = 0;
  ptrdiff_t pixel_stride = 0;

  ptrdiff_t stride() const { return pixel_stride != 0 ? pixel_stride : channels; }
  const T* pixel(int y, int x) const { return data + y * row_stride + x * stride(); }
};

template <typename T>
struct PlaneView {
  T* data = nullptr;
  int height = 0;
  int width = 0;
  int channels = 0;
  ptrdiff_t row_stride = 0;
  ptrdiff_t pixel_stride = 0;

  ptrdiff_t stride() const { return pixel_stride != 0 ? pixel_stride : channels; }
  T* pixel(int y, int x) const { return data + y * row_stride + x * stride(); }
  operator ConstPlaneView<T>() const {
    return {data, height, width, channels, row_stride, pixel_stride};
  }
};

template <typename T>
PlaneView<T> DensePlaneView(T* data, int height, int width, int channels) {
  return {data, height, width, channels, static_cast<ptrdiff_t>(width) * channels};
}

using ConstByteView = ConstPlaneView<uint8_t>;
using ByteView = PlaneView<uint8_t>;
using ConstBf16View = ConstPlaneView<uint16_t>;
using Bf16View = PlaneView<uint16_t>;

inline ByteView DenseByteView(uint8_t* data, int height, int width, int channels) {
  return DensePlaneView(data, height, width, channels);
}
inline Bf16View DenseBf16View(uint16_t* data, int height, int width, int channels) {
  return DensePlaneView(data, height, width, channels);
}

}  // namespace sfrt
