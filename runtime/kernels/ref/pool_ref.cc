#include "kernels/ref/pool_ref.h"

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <limits>

namespace sfrt::ref {

namespace {

// kArgMax: per window and channel the first tap (row-major) holding the largest input value,
// written as its index c * H * W + iy * W + ix in the input (c * H * W + ix * H + iy with
// indices_column_major).
void ArgMaxPoolRows(const ConstTensorView& in, const PoolParams& p, const Padding& pads,
                    const TensorView& out, int row_begin, int row_end) {
  const int channels = in.channels;
  const int64_t plane = static_cast<int64_t>(in.height) * in.width;
  for (int y = row_begin; y < row_end; ++y) {
    const int top = y * p.stride_h - pads.top;
    for (int x = 0; x < out.width; ++x) {
      const int left = x * p.stride_w - pads.left;
      float* dst = out.pixel(y, x);
      for (int c = 0; c < channels; ++c) {
        float best = -std::numeric_limits<float>::infinity();
        int64_t where = -1;
        for (int ky = 0; ky < p.kernel_h; ++ky) {
          const int iy = top + ky * p.dilation_h;
          if (iy < 0 || iy >= in.height) continue;
          for (int kx = 0; kx < p.kernel_w; ++kx) {
            const int ix = left + kx * p.dilation_w;
            if (ix < 0 || ix >= in.width) continue;
            const float v = in.pixel(iy, ix)[c];
            if (where < 0 || v > best) {
              best = v;
              where =
                  c * plane + (p.indices_column_major ? static_cast<int64_t>(ix) * in.height + iy
                                                      : static_cast<int64_t>(iy) * in.width + ix);
            }
          }
        }
        dst[c] = static_cast<float>(where);
      }
    }
  }
}

}  // namespace

void PoolRows(const ConstTensorView& in, const PoolParams& p, const Padding& pads,
              const TensorView& out, int row_begin, int row_end) {
  assert(in.channels == out.channels);
  if (p.kind == PoolKind::kArgMax) {
    ArgMaxPoolRows(in, p, pads, out, row_begin, row_end);
    return;
  }
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
