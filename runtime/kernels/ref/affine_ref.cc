#include "kernels/ref/affine_ref.h"

#include <cassert>

#include "kernels/ref/activation_ref.h"

namespace sfrt::ref {

void ChannelAffineRows(const ConstTensorView& in, const ChannelAffineParams& p,
                       const TensorView& out, int row_begin, int row_end) {
  assert(in.channels == p.channels && out.channels == p.channels);
  for (int y = row_begin; y < row_end; ++y) {
    for (int x = 0; x < out.width; ++x) {
      const float* src = in.pixel(y, x);
      float* dst = out.pixel(y, x);
      for (int c = 0; c < p.channels; ++c) {
        dst[c] = ActivateAffine(src[c] * p.scale[c] + p.shift[c], p);
      }
    }
  }
}

}  // namespace sfrt::ref
