#include "kernels/ref/conv_transpose_ref.h"

#include <cassert>
#include <cstring>

#include "kernels/ref/activation_ref.h"

namespace sfrt::ref {
namespace {

// The input index that the tap at offset `reach` (tap index times dilation) of an output
// coordinate reads along one axis, or -1: it reaches output `o` from input `i` where
// o = i * stride - pad + reach.
int SourceOf(int o, int reach, int stride, int pad, int in_size) {
  const int t = o + pad - reach;
  if (t < 0 || t % stride != 0) return -1;
  const int i = t / stride;
  return i < in_size ? i : -1;
}

}  // namespace

void ConvTranspose2dRows(const ConstTensorView& in, const ConvTransposeParams& p,
                         const TensorView& out, int row_begin, int row_end) {
  assert(in.channels == p.in_channels && out.channels == p.out_channels);
  const int oc = p.out_channels;
  const size_t tap_floats = static_cast<size_t>(p.in_channels) * oc;
  for (int y = row_begin; y < row_end; ++y) {
    for (int x = 0; x < out.width; ++x) {
      float* dst = out.pixel(y, x);
      std::memcpy(dst, p.bias, sizeof(float) * static_cast<size_t>(oc));
      for (int ky = 0; ky < p.kernel_h; ++ky) {
        const int iy = SourceOf(y, ky * p.dilation_h, p.stride_h, p.pads.top, in.height);
        if (iy < 0) continue;
        for (int kx = 0; kx < p.kernel_w; ++kx) {
          const int ix = SourceOf(x, kx * p.dilation_w, p.stride_w, p.pads.left, in.width);
          if (ix < 0) continue;
          const float* src = in.pixel(iy, ix);
          const float* w = p.weights + (static_cast<size_t>(ky) * p.kernel_w + kx) * tap_floats;
          for (int i = 0; i < p.in_channels; ++i, w += oc) {
            const float a = src[i];
            for (int o = 0; o < oc; ++o) dst[o] += a * w[o];
          }
        }
      }
      for (int o = 0; o < oc; ++o) dst[o] = Activate(dst[o], p.activation, p.leaky_slope);
    }
  }
}

}  // namespace sfrt::ref
