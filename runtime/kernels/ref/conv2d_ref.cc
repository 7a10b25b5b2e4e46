#include "kernels/ref/conv2d_ref.h"

#include <cassert>

#include "kernels/ref/activation_ref.h"

namespace sfrt::ref {

void Conv2d(const ConstTensorView& in, const ConvParams& p, const Padding& pads,
            const TensorView& out) {
  assert(in.channels == p.in_channels && out.channels == p.out_channels);
  const int cout = p.out_channels;
  const int group_in = p.in_channels / p.groups;    // input channels per group
  const int group_out = p.out_channels / p.groups;  // output channels per group
  for (int oy = 0; oy < out.height; ++oy) {
    for (int ox = 0; ox < out.width; ++ox) {
      float* acc = out.pixel(oy, ox);
      for (int co = 0; co < cout; ++co) acc[co] = p.bias[co];
      for (int ky = 0; ky < p.kernel_h; ++ky) {
        const int iy = oy * p.stride_h - pads.top + ky * p.dilation_h;
        if (iy < 0 || iy >= in.height) continue;  // zero padding adds nothing
        for (int kx = 0; kx < p.kernel_w; ++kx) {
          const int ix = ox * p.stride_w - pads.left + kx * p.dilation_w;
          if (ix < 0 || ix >= in.width) continue;
          const float* x = in.pixel(iy, ix);
          const float* w =
              p.weights + static_cast<ptrdiff_t>(ky * p.kernel_w + kx) * group_in * cout;
          // Loop over output channels innermost: every co has its own sum, so the (ky, kx, ci)
          // order of each sum is kept while the compiler may still use vector registers.
          for (int g = 0; g < p.groups; ++g) {
            for (int ci = 0; ci < group_in; ++ci) {
              const float xv = x[g * group_in + ci];
              const float* w_row = w + static_cast<ptrdiff_t>(ci) * cout + g * group_out;
              float* acc_g = acc + g * group_out;
              for (int co = 0; co < group_out; ++co) acc_g[co] += xv * w_row[co];
            }
          }
        }
      }
      for (int co = 0; co < cout; ++co) acc[co] = Activate(acc[co], p.activation, p.leaky_slope);
    }
  }
}

}  // namespace sfrt::ref
