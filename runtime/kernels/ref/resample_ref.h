// Reference data-movement kernels: nearest upsampling and copying a (cropped) view.
#pragma once

#include <cstring>

#include "kernels/tensor_view.h"

namespace sfrt::ref {

// out[y][x][c] = in[y / factor_h][x / factor_w][c]; out is (in.height*factor_h, in.width*factor_w).
void UpsampleNearest(const ConstTensorView& in, int factor_h, int factor_w, const TensorView& out);
// The same on output rows [row_begin, row_end) only.
void UpsampleNearestRows(const ConstTensorView& in, int factor_h, int factor_w,
                         const TensorView& out, int row_begin, int row_end);

// out = in, element by element; both views have the same shape.
void Copy(const ConstTensorView& in, const TensorView& out);

// The same two on the reduced-precision tensors (uint8 for int8 layers, bf16 bits for bf16).
template <typename T>
void UpsampleNearestPlane(const ConstPlaneView<T>& in, int factor_h, int factor_w,
                          const PlaneView<T>& out) {
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      std::memcpy(out.pixel(y, x), in.pixel(y / factor_h, x / factor_w),
                  static_cast<size_t>(in.channels) * sizeof(T));
    }
  }
}

template <typename T>
void CopyPlane(const ConstPlaneView<T>& in, const PlaneView<T>& out) {
  for (int y = 0; y < out.height; ++y) {
    if (in.stride() == in.channels && out.stride() == out.channels) {
      std::memcpy(out.pixel(y, 0), in.pixel(y, 0),
                  static_cast<size_t>(in.width) * in.channels * sizeof(T));
      continue;
    }
    for (int x = 0; x < out.width; ++x) {
      std::memcpy(out.pixel(y, x), in.pixel(y, x), static_cast<size_t>(in.channels) * sizeof(T));
    }
  }
}

}  // namespace sfrt::ref
