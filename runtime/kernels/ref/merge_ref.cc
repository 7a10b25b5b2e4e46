#include "kernels/ref/merge_ref.h"

#include <cassert>
#include <cstring>

#include "kernels/ref/activation_ref.h"

namespace sfrt::ref {

namespace {

// Either element type: the views' pixel() gives typed pointers.
template <typename InView, typename OutView>
void ConcatViews(const InView* inputs, int count, const OutView& out, int row_begin, int row_end) {
  for (int y = row_begin; y < row_end; ++y) {
    for (int x = 0; x < out.width; ++x) {
      auto* dst = out.pixel(y, x);
      for (int k = 0; k < count; ++k) {
        const InView& in = inputs[k];
        assert(in.height == out.height && in.width == out.width);
        std::memcpy(dst, in.pixel(y, x), sizeof(*dst) * static_cast<size_t>(in.channels));
        dst += in.channels;
      }
    }
  }
}

}  // namespace

void ConcatRows(const ConstTensorView* inputs, int count, const TensorView& out, int row_begin,
                int row_end) {
  ConcatViews(inputs, count, out, row_begin, row_end);
}

void ConcatRows(const ConstByteView* inputs, int count, const ByteView& out, int row_begin,
                int row_end) {
  ConcatViews(inputs, count, out, row_begin, row_end);
}

void ConcatRows(const ConstBf16View* inputs, int count, const Bf16View& out, int row_begin,
                int row_end) {
  ConcatViews(inputs, count, out, row_begin, row_end);
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
      po[i] = Activate(pa[i] + pb[i], params.activation, params.leaky_slope);
    }
  }
}

}  // namespace sfrt::ref
