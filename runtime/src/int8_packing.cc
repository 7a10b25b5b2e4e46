#include "int8_packing.h"

#include <cstdint>
#include <cstring>

namespace sfrt {
namespace {

size_t RoundUp64(size_t n) { return (n + 63) / 64 * 64; }

struct Int8Sizes {
  int blocks = 1;
  int lanes = 0;  // per-channel values: blocks * nr, or out_channels
  int cin4 = 0;
  size_t per_channel = 0;  // bytes of one float array
  size_t weights = 0;      // bytes
  size_t tap_sums = 0;     // bytes
};

Int8Sizes SizesOf(const ConvParams& p, int nr) {
  Int8Sizes s;
  s.blocks = nr > 0 ? (p.out_channels + nr - 1) / nr : 1;
  s.lanes = nr > 0 ? s.blocks * nr : p.out_channels;
  s.cin4 = (p.in_channels + 3) / 4 * 4;
  s.per_channel = RoundUp64(static_cast<size_t>(s.lanes) * sizeof(float));
  if (nr > 0) {
    const size_t taps = static_cast<size_t>(p.kernel_h) * p.kernel_w;
    s.weights = RoundUp64(static_cast<size_t>(s.blocks) * taps * s.cin4 * nr);
    s.tap_sums = RoundUp64(static_cast<size_t>(s.blocks) * taps * nr * sizeof(int32_t));
  }
  return s;
}

}  // namespace

size_t PackedInt8Bytes(const ConvParams& params, int nr) {
  const Int8Sizes s = SizesOf(params, nr);
  return 2 * s.per_channel + s.weights + s.tap_sums;
}

PackedInt8Conv PackInt8Conv(const ConvParams& p, int nr, bool out_float, void* dst) {
  const Int8Sizes s = SizesOf(p, nr);
  uint8_t* base = static_cast<uint8_t*>(dst);
  std::memset(base, 0, PackedInt8Bytes(p, nr));
  float* multiplier = reinterpret_cast<float*>(base);
  float* bias = reinterpret_cast<float*>(base + s.per_channel);
  for (int o = 0; o < p.out_channels; ++o) {
    multiplier[o] = p.input_quant.scale * p.weight_scales[o];
    bias[o] = p.bias[o];
  }

  PackedInt8Conv out;
  out.in_channels = p.in_channels;
  out.out_channels = p.out_channels;
  out.kernel_h = p.kernel_h;
  out.kernel_w = p.kernel_w;
  out.stride_h = p.stride_h;
  out.stride_w = p.stride_w;
  out.activation = p.activation;
  out.leaky_slope = p.leaky_slope;
  out.in_zero_point = p.input_quant.zero_point;
  out.out_float = out_float;
  out.out_inv_scale = out_float ? 1.0f : 1.0f / p.output_quant.scale;
  out.out_zero_point = out_float ? 0 : p.output_quant.zero_point;
  out.multiplier = multiplier;
  out.bias = bias;
  out.weights_hwio = p.weights_q;
  out.nr = nr;
  out.blocks = s.blocks;
  out.cin4 = s.cin4;
  if (nr == 0) return out;

  int8_t* w = reinterpret_cast<int8_t*>(base + 2 * s.per_channel);
  int32_t* sums = reinterpret_cast<int32_t*>(base + 2 * s.per_channel + s.weights);
  const int taps = p.kernel_h * p.kernel_w;
  const int cin = p.in_channels, cout = p.out_channels;
  for (int blk = 0; blk < s.blocks; ++blk) {
    for (int t = 0; t < taps; ++t) {
      int8_t* wt = w + (static_cast<size_t>(blk) * taps + t) * s.cin4 * nr;
      int32_t* st = sums + (static_cast<size_t>(blk) * taps + t) * nr;
      for (int ci = 0; ci < cin; ++ci) {
        for (int j = 0; j < nr; ++j) {
          const int co = blk * nr + j;
          if (co >= cout) continue;
          const int8_t v = p.weights_q[(static_cast<size_t>(t) * cin + ci) * cout + co];
          wt[(static_cast<size_t>(ci / 4) * nr + j) * 4 + ci % 4] = v;
          st[j] += v;
        }
      }
    }
  }
  out.weights = w;
  out.tap_sums = sums;
  return out;
}

}  // namespace sfrt
