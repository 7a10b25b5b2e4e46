#include "kernels/ref/conv2d_bf16_ref.h"

#include <algorithm>
#include <cassert>

namespace sfrt::ref {

void Conv2dBf16Rows(const Bf16ConvArgs& a, int row_begin, int row_end, int /*blk_begin*/,
                    int /*blk_end*/) {
  const PackedBf16Conv& p = *a.conv;
  assert(a.in.channels == p.in_channels);
  const int cin = p.in_channels;
  const int cout = p.out_channels;
  const int src_h = a.upsampled ? a.c_height : a.in.height;
  const int src_w = a.upsampled ? a.c_width : a.in.width;
  auto source = [&](int y, int x) -> const uint16_t* {
    if (!a.upsampled) return a.in.pixel(y, x);
    return a.in.pixel((y + a.crop_top) / 2, (x + a.crop_left) / 2);
  };
  const int out_w = p.out_float ? a.out_f32.width : a.out_bf16.width;
  // The columns this call computes (Args::col_begin/col_end).
  const int x_begin = std::max(0, a.col_begin);
  const int x_end = std::min(out_w, a.col_end);
  const bool phases = a.upsampled && p.phase_weights_hwio != nullptr;
  const size_t phase_hwio = static_cast<size_t>(4) * cin * cout;
  constexpr int kChunk = 256;  // output channels summed at once (the sums live on the stack)
  double acc[kChunk];
  int c0 = 0, cn = 0;
  // acc += x[ci] * w[ci][c0 + co] over the input channels of one tap.
  auto add_tap = [&](const uint16_t* x, const uint16_t* w) {
    for (int ci = 0; ci < cin; ++ci) {
      const double xv = Bf16ToFloat(x[ci]);
      const uint16_t* w_row = w + static_cast<ptrdiff_t>(ci) * cout + c0;
      for (int co = 0; co < cn; ++co) acc[co] += xv * Bf16ToFloat(w_row[co]);
    }
  };
  for (int oy = row_begin; oy < row_end; ++oy) {
    for (int ox = x_begin; ox < x_end; ++ox) {
      for (c0 = 0; c0 < cout; c0 += kChunk) {
        cn = cout - c0 < kChunk ? cout - c0 : kChunk;
        for (int co = 0; co < cn; ++co) acc[co] = 0.0;
        const int cy0 = oy - a.pads.top, cx0 = ox - a.pads.left;
        const bool inside = cy0 >= 0 && cy0 + 3 <= src_h && cx0 >= 0 && cx0 + 3 <= src_w;
        if (phases && inside) {
          // The 2x2 kernel of this pixel's phase over the low-resolution map.
          const int ay = cy0 + a.crop_top, ax = cx0 + a.crop_left;
          const uint16_t* pw = p.phase_weights_hwio + ((ay & 1) * 2 + (ax & 1)) * phase_hwio;
          for (int t = 0; t < 4; ++t) {
            add_tap(a.in.pixel(ay / 2 + t / 2, ax / 2 + t % 2),
                    pw + static_cast<ptrdiff_t>(t) * cin * cout);
          }
        } else {
          for (int ky = 0; ky < p.kernel_h; ++ky) {
            const int iy = oy * p.stride_h - a.pads.top + ky;
            if (iy < 0 || iy >= src_h) continue;  // padding is real zero: adds nothing
            for (int kx = 0; kx < p.kernel_w; ++kx) {
              const int ix = ox * p.stride_w - a.pads.left + kx;
              if (ix < 0 || ix >= src_w) continue;
              add_tap(source(iy, ix),
                      p.weights_hwio + static_cast<ptrdiff_t>(ky * p.kernel_w + kx) * cin * cout);
            }
          }
        }
        for (int co = 0; co < cn; ++co) {
          const int o = c0 + co;
          const float y =
              Bf16Epilogue(static_cast<float>(acc[co]), p.bias[o], p.activation, p.leaky_slope);
          if (p.out_float) {
            a.out_f32.pixel(oy, ox)[o] = y;
          } else {
            a.out_bf16.pixel(oy, ox)[o] = FloatToBf16(y);
          }
        }
      }
    }
  }
}

void ToBf16Rows(const ConstTensorView& in, const Bf16View& out, int row_begin, int row_end) {
  for (int y = row_begin; y < row_end; ++y) {
    for (int x = 0; x < in.width; ++x) {
      const float* s = in.pixel(y, x);
      uint16_t* d = out.pixel(y, x);
      for (int c = 0; c < in.channels; ++c) d[c] = FloatToBf16(s[c]);
    }
  }
}

}  // namespace sfrt::ref
