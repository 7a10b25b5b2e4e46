#include "kernels/ref/merge_ref.h"

#include <cassert>
#include <cstring>

namespace sfrt::ref {

void ConcatRows(const ConstTensorView* inputs, int count, const TensorView& out, int row_begin,
                int row_end) {
  for (int y = row_begin; y < row_end; ++y) {
    for (int x = 0; x < out.width; ++x) {
      float* dst = out.pixel(y, x);
      for (int k = 0; k < count; ++k) {
        const ConstTensorView& in = inputs[k];
        assert(in.height == out.height && in.width == out.width);
        std::memcpy(dst, in.pixel(y, x), sizeof(float) * static_cast<size_t>(in.channels));
        dst += in.channels;
      }
    }
  }
}

void AddRows(const ConstTensorView& a, const ConstTensorView& b, const AddParams& params,
             const TensorView& out, int row_begin, int row_end) {
  assert(a.channels == out.channels && b.channels == out.channels);
  const int n = out.width * out.channels;
  for (int y = row_begin; y < row_end; ++y) {
    const float* pa = a.pixel(y, 0);
    const float* pb = b.pixel(y, 0);
    float* po = out.pixel(y, 0);
    for (int i = 0; i < n; ++i) {
      const float v = pa[i] + pb[i];
      switch (params.activation) {
        case Activation::kNone:
          po[i] = v;
          break;
        case Activation::kRelu:
          po[i] = v > 0.0f ? v : 0.0f;
          break;
        case Activation::kLeakyRelu:
          po[i] = v > 0.0f ? v : v * params.leaky_slope;
          break;
      }
    }
  }
}

}  // namespace sfrt::ref
