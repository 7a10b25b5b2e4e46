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
  bool phases = false;
  size_t phase_weights = 0;  // bytes of one phase's SIMD weights
  size_t phase_sums = 0;     // bytes of one phase's tap sums
  int few_ci_stride = 0;     // > 0: the few-output layout (int8_job.h)
  size_t few_weights = 0;    // bytes
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
  if (nr > 0 && Int8FewOutputs(p)) {
    s.few_ci_stride = (p.in_channels + 63) / 64 * 64;
    s.few_weights =
        RoundUp64(static_cast<size_t>(p.kernel_h) * p.kernel_w * p.out_channels * s.few_ci_stride);
  }
  s.phases = p.phase_weights_q != nullptr;
  if (s.phases && nr > 0) {
    s.phase_weights = RoundUp64(static_cast<size_t>(s.blocks) * 4 * s.cin4 * nr);
    s.phase_sums = RoundUp64(static_cast<size_t>(s.blocks) * 4 * nr * sizeof(int32_t));
  }
  return s;
}

// HWIO int8 weights of `taps` taps into w[block][tap][ci / 4][nr][ci % 4] (zero-filled memory)
// and their sums over ci into sums[block][tap][nr].
void BlockWeights(const int8_t* hwio, int taps, int cin, int cout, int nr, int blocks, int cin4,
                  int8_t* w, int32_t* sums) {
  for (int blk = 0; blk < blocks; ++blk) {
    for (int t = 0; t < taps; ++t) {
      int8_t* wt = w + (static_cast<size_t>(blk) * taps + t) * cin4 * nr;
      int32_t* st = sums + (static_cast<size_t>(blk) * taps + t) * nr;
      for (int ci = 0; ci < cin; ++ci) {
        for (int j = 0; j < nr; ++j) {
          const int co = blk * nr + j;
          if (co >= cout) continue;
          const int8_t v = hwio[(static_cast<size_t>(t) * cin + ci) * cout + co];
          wt[(static_cast<size_t>(ci / 4) * nr + j) * 4 + ci % 4] = v;
          st[j] += v;
        }
      }
    }
  }
}

}  // namespace

size_t PackedInt8Bytes(const ConvParams& params, int nr) {
  const Int8Sizes s = SizesOf(params, nr);
  const size_t phases = s.phases ? 4 * (s.per_channel + s.phase_weights + s.phase_sums) : 0;
  return 2 * s.per_channel + s.weights + s.tap_sums + s.few_weights + phases;
}

PackedInt8Conv PackInt8Conv(const ConvParams& p, int nr, const QuantParams* out_quant, void* dst) {
  const bool out_float = out_quant == nullptr;
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
  out.out_inv_scale = out_float ? 1.0f : 1.0f / out_quant->scale;
  out.out_zero_point = out_float ? 0 : out_quant->zero_point;
  out.multiplier = multiplier;
  out.bias = bias;
  out.weights_hwio = p.weights_q;
  out.nr = nr;
  out.blocks = s.blocks;
  out.cin4 = s.cin4;
  uint8_t* cursor = base + 2 * s.per_channel;
  if (nr > 0) {
    int8_t* w = reinterpret_cast<int8_t*>(cursor);
    int32_t* sums = reinterpret_cast<int32_t*>(cursor + s.weights);
    BlockWeights(p.weights_q, p.kernel_h * p.kernel_w, p.in_channels, p.out_channels, nr, s.blocks,
                 s.cin4, w, sums);
    out.weights = w;
    out.tap_sums = sums;
    cursor += s.weights + s.tap_sums;
  }
  if (s.few_ci_stride > 0) {
    int8_t* few = reinterpret_cast<int8_t*>(cursor);
    const int taps = p.kernel_h * p.kernel_w;
    for (int t = 0; t < taps; ++t) {
      for (int o = 0; o < p.out_channels; ++o) {
        for (int ci = 0; ci < p.in_channels; ++ci) {
          few[(static_cast<size_t>(t) * p.out_channels + o) * s.few_ci_stride + ci] =
              p.weights_q[(static_cast<size_t>(t) * p.in_channels + ci) * p.out_channels + o];
        }
      }
    }
    out.few_weights = few;
    out.few_ci_stride = s.few_ci_stride;
    cursor += s.few_weights;
  }
  if (!s.phases) return out;

  // The phases: multipliers, then (SIMD) each phase's blocked weights and tap sums.
  float* phase_multiplier = reinterpret_cast<float*>(cursor);
  for (int ph = 0; ph < 4; ++ph) {
    for (int o = 0; o < p.out_channels; ++o) {
      phase_multiplier[static_cast<size_t>(ph) * s.lanes + o] =
          p.input_quant.scale * p.phase_scales[ph * p.out_channels + o];
    }
  }
  cursor += 4 * s.per_channel;
  out.phase_weights_hwio = p.phase_weights_q;
  out.phase_multiplier = phase_multiplier;
  if (nr == 0) return out;
  int8_t* pw = reinterpret_cast<int8_t*>(cursor);
  int32_t* ps = reinterpret_cast<int32_t*>(cursor + 4 * s.phase_weights);
  const size_t phase_hwio = static_cast<size_t>(4) * p.in_channels * p.out_channels;
  for (int ph = 0; ph < 4; ++ph) {
    BlockWeights(p.phase_weights_q + ph * phase_hwio, 4, p.in_channels, p.out_channels, nr,
                 s.blocks, s.cin4, pw + ph * s.phase_weights,
                 reinterpret_cast<int32_t*>(reinterpret_cast<uint8_t*>(ps) + ph * s.phase_sums));
  }
  out.phase_weights = pw;
  out.phase_tap_sums = ps;
  return out;
}

}  // namespace sfrt
