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
    for (int x = 0; x < out.width; ++x) {
      const int left = x * p.stride_w - pads.left;
      float* dst = out.pixel(y, x);
      std::fill(dst, dst + channels, max ? -std::numeric_limits<float>::infinity() : 0.0f);
      int inside = 0;  // taps on the input
      int padded = 0;  // taps on the input or its padding (count_include_pad divides by these)
      for (int ky = 0; ky < p.kernel_h; ++ky) {
        const int iy = top + ky * p.dilation_h;
        if (iy >= in.height + pads.bottom) continue;
        for (int kx = 0; kx < p.kernel_w; ++kx) {
          const int ix = left + kx * p.dilation_w;
          if (ix >= in.width + pads.right) continue;
          ++padded;
          if (iy < 0 || iy >= in.height || ix < 0 || ix >= in.width) continue;
          ++inside;
          const float* src = in.pixel(iy, ix);
          for (int c = 0; c < channels; ++c) {
            dst[c] = max ? std::max(dst[c], src[c]) : dst[c] + src[c];
          }
        }
      }
      if (!max) {
        const float inv = 1.0f / static_cast<float>(p.count_include_pad ? padded : inside);
        for (int c = 0; c < channels; ++c) dst[c] *= inv;
      }
    }
  }
}

}  // namespace sfrt::ref
