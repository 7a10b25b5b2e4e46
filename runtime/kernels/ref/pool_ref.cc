#include "kernels/ref/pool_ref.h"

#include <algorithm>
#include <cassert>
#include <limits>

namespace sfrt::ref {

void PoolRows(const ConstTensorView& in, const PoolParams& p, const Padding& pads,
              const TensorView& out, int row_begin, int row_end) {
  assert(in.channels == out.channels);
  const int channels = in.channels;
  const bool max = p.kind == PoolKind::kMax;
  for (int y = row_begin; y < row_end; ++y) {
    const int top = y * p.stride_h - pads.top;
    const int y0 = std::max(top, 0);
    const int y1 = std::min(top + p.kernel_h, in.height);
    // The window's extent inside the padded input, which count_include_pad divides by.
    const int padded_rows = std::min(top + p.kernel_h, in.height + pads.bottom) - top;
    for (int x = 0; x < out.width; ++x) {
      const int left = x * p.stride_w - pads.left;
      const int x0 = std::max(left, 0);
      const int x1 = std::min(left + p.kernel_w, in.width);
      const int padded_cols = std::min(left + p.kernel_w, in.width + pads.right) - left;
      float* dst = out.pixel(y, x);
      std::fill(dst, dst + channels, max ? -std::numeric_limits<float>::infinity() : 0.0f);
      for (int iy = y0; iy < y1; ++iy) {
        for (int ix = x0; ix < x1; ++ix) {
          const float* src = in.pixel(iy, ix);
          for (int c = 0; c < channels; ++c) {
            dst[c] = max ? std::max(dst[c], src[c]) : dst[c] + src[c];
          }
        }
      }
      if (!max) {
        const int count = p.count_include_pad ? padded_rows * padded_cols : (y1 - y0) * (x1 - x0);
        const float inv = 1.0f / static_cast<float>(count);
        for (int c = 0; c < channels; ++c) dst[c] *= inv;
      }
    }
  }
}

}  // namespace sfrt::ref
