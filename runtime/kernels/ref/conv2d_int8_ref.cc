#include "kernels/ref/conv2d_int8_ref.h"

#include <algorithm>
#include <cassert>

namespace sfrt::ref {

namespace {

// The epilogue of output channels [c0, c0 + cn) of pixel (oy, ox).
void Finish(const PackedInt8Conv& p, const int32_t* acc, const float* multiplier,
            const Int8ConvArgs& a, int oy, int ox, int c0, int cn) {
  for (int co = 0; co < cn; ++co) {
    const int o = c0 + co;
    const float y = Int8Dequantize(acc[co], multiplier[o], p.bias[o], p.activation, p.leaky_slope);
    if (p.out_float) {
      a.out_f32.pixel(oy, ox)[o] = y;
    } else {
      a.out_u8.pixel(oy, ox)[o] = Int8Quantize(y, p.out_inv_scale, p.out_zero_point);
    }
  }
}

}  // namespace

void Conv2dInt8Rows(const Int8ConvArgs& a, int row_begin, int row_end, int /*blk_begin*/,
                    int /*blk_end*/) {
  const PackedInt8Conv& p = *a.conv;
  assert(a.in.channels == p.in_channels);
  const int cin = p.in_channels;
  const int cout = p.out_channels;
  const int zp = p.in_zero_point;
  // The map the convolution reads: the input itself, or C.
  const int src_h = a.upsampled ? a.c_height : a.in.height;
  const int src_w = a.upsampled ? a.c_width : a.in.width;
  auto source = [&](int y, int x) -> const uint8_t* {
    if (!a.upsampled) return a.in.pixel(y, x);
    return a.in.pixel((y + a.crop_top) / 2, (x + a.crop_left) / 2);
  };
  const int out_w = p.out_float ? a.out_f32.width : a.out_u8.width;
  // The columns this call computes (Args::col_begin/col_end).
  const int x_begin = std::max(0, a.col_begin);
  const int x_end = std::min(out_w, a.col_end);
  const bool phases = a.upsampled && p.phase_weights_hwio != nullptr;
  const size_t phase_hwio = static_cast<size_t>(4) * cin * cout;
  constexpr int kChunk = 256;  // output channels summed at once (the sums live on the stack)
  int32_t acc[kChunk];
  for (int oy = row_begin; oy < row_end; ++oy) {
    for (int ox = x_begin; ox < x_end; ++ox) {
      for (int c0 = 0; c0 < cout; c0 += kChunk) {
        const int cn = cout - c0 < kChunk ? cout - c0 : kChunk;
        for (int co = 0; co < cn; ++co) acc[co] = 0;
        const int cy0 = oy - a.pads.top, cx0 = ox - a.pads.left;
        const bool inside = cy0 >= 0 && cy0 + 3 <= src_h && cx0 >= 0 && cx0 + 3 <= src_w;
        if (phases && inside) {
          // The 2x2 kernel of this pixel's phase over the low-resolution map.
          const int ay = cy0 + a.crop_top, ax = cx0 + a.crop_left;
          const int phase = (ay & 1) * 2 + (ax & 1);
          const int8_t* pw = p.phase_weights_hwio + phase * phase_hwio;
          for (int t = 0; t < 4; ++t) {
            const uint8_t* x = a.in.pixel(ay / 2 + t / 2, ax / 2 + t % 2);
            const int8_t* w = pw + static_cast<ptrdiff_t>(t) * cin * cout + c0;
            for (int ci = 0; ci < cin; ++ci) {
              const int32_t xv = static_cast<int32_t>(x[ci]) - zp;
              const int8_t* w_row = w + static_cast<ptrdiff_t>(ci) * cout;
              for (int co = 0; co < cn; ++co) acc[co] += xv * static_cast<int32_t>(w_row[co]);
            }
          }
          const float* multiplier =
              p.phase_multiplier + phase * (p.nr > 0 ? p.blocks * p.nr : cout);
          Finish(p, acc, multiplier, a, oy, ox, c0, cn);
          continue;
        }
        for (int ky = 0; ky < p.kernel_h; ++ky) {
          const int iy = oy * p.stride_h - a.pads.top + ky;
          if (iy < 0 || iy >= src_h) continue;  // padding is real zero: adds nothing
          for (int kx = 0; kx < p.kernel_w; ++kx) {
            const int ix = ox * p.stride_w - a.pads.left + kx;
            if (ix < 0 || ix >= src_w) continue;
            const uint8_t* x = source(iy, ix);
            const int8_t* w =
                p.weights_hwio + static_cast<ptrdiff_t>(ky * p.kernel_w + kx) * cin * cout + c0;
            for (int ci = 0; ci < cin; ++ci) {
              const int32_t xv = static_cast<int32_t>(x[ci]) - zp;
              const int8_t* w_row = w + static_cast<ptrdiff_t>(ci) * cout;
              for (int co = 0; co < cn; ++co) acc[co] += xv * static_cast<int32_t>(w_row[co]);
            }
          }
        }
        Finish(p, acc, p.multiplier, a, oy, ox, c0, cn);
      }
    }
  }
}

void QuantizeRows(const ConstTensorView& in, float inv_scale, int zero_point, const ByteView& out,
                  int row_begin, int row_end) {
  for (int y = row_begin; y < row_end; ++y) {
    for (int x = 0; x < in.width; ++x) {
      const float* s = in.pixel(y, x);
      uint8_t* d = out.pixel(y, x);
      for (int c = 0; c < in.channels; ++c) d[c] = Int8Quantize(s[c], inv_scale, zero_point);
    }
  }
}

}  // namespace sfrt::ref
