#include "kernels/ref/resample_ref.h"

#include <cassert>
#include <cstring>

namespace sfrt::ref {

void UpsampleNearest(const ConstTensorView& in, int factor_h, int factor_w, const TensorView& out) {
  UpsampleNearestRows(in, factor_h, factor_w, out, 0, out.height);
}

void UpsampleNearestRows(const ConstTensorView& in, int factor_h, int factor_w,
                         const TensorView& out, int row_begin, int row_end) {
  assert(out.height == in.height * factor_h && out.width == in.width * factor_w);
  assert(out.channels == in.channels);
  const size_t pixel_bytes = sizeof(float) * static_cast<size_t>(in.channels);
  for (int y = row_begin; y < row_end; ++y) {
    for (int x = 0; x < out.width; ++x) {
      std::memcpy(out.pixel(y, x), in.pixel(y / factor_h, x / factor_w), pixel_bytes);
    }
  }
}

void Copy(const ConstTensorView& in, const TensorView& out) {
  assert(in.height == out.height && in.width == out.width && in.channels == out.channels);
  const size_t row_bytes = sizeof(float) * static_cast<size_t>(in.width) * in.channels;
  for (int y = 0; y < in.height; ++y) std::memcpy(out.pixel(y, 0), in.pixel(y, 0), row_bytes);
}

}  // namespace sfrt::ref
