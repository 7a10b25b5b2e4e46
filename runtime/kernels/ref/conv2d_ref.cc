#include "kernels/ref/conv2d_ref.h"

#include <cassert>

namespace sfrt::ref {
namespace {

float Activate(float v, const ConvParams& p) {
  switch (p.activation) {
    case Activation::kNone:
      return v;
    case Activation::kRelu:
      return v > 0.0f ? v : 0.0f;
    case Activation::kLeakyRelu:
      return v > 0.0f ? v : v * p.leaky_slope;
  }
  return v;
}

}  // namespace

void Conv2d(const ConstTensorView& in, const ConvParams& p, const Padding& pads,
            const TensorView& out) {
  assert(in.channels == p.in_channels && out.channels == p.out_channels);
  const int cin = p.in_channels;
  const int cout = p.out_channels;
  for (int oy = 0; oy < out.height; ++oy) {
    for (int ox = 0; ox < out.width; ++ox) {
      float* acc = out.pixel(oy, ox);
      for (int co = 0; co < cout; ++co) acc[co] = p.bias[co];
      for (int ky = 0; ky < p.kernel_h; ++ky) {
        const int iy = oy * p.stride_h - pads.top + ky;
        if (iy < 0 || iy >= in.height) continue;  // zero padding adds nothing
        for (int kx = 0; kx < p.kernel_w; ++kx) {
          const int ix = ox * p.stride_w - pads.left + kx;
          if (ix < 0 || ix >= in.width) continue;
          const float* x = in.pixel(iy, ix);
          const float* w = p.weights + static_cast<ptrdiff_t>(ky * p.kernel_w + kx) * cin * cout;
          // Loop over output channels innermost: every co has its own sum, so the (ky, kx, ci)
          // order of each sum is kept while the compiler may still use vector registers.
          for (int ci = 0; ci < cin; ++ci) {
            const float xv = x[ci];
            const float* w_row = w + static_cast<ptrdiff_t>(ci) * cout;
            for (int co = 0; co < cout; ++co) acc[co] += xv * w_row[co];
          }
        }
      }
      for (int co = 0; co < cout; ++co) acc[co] = Activate(acc[co], p);
    }
  }
}

}  // namespace sfrt::ref
