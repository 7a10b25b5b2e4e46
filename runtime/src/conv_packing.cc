#include "conv_packing.h"

#include <cassert>

namespace sfrt {
namespace {

size_t RoundUp16(size_t n) { return (n + 15) / 16 * 16; }

struct Sizes {
  size_t weights = 0;
  size_t bias = 0;
  size_t phases = 0;
};

Sizes SizesOf(const ConvParams& p, int nr, bool with_phases) {
  const size_t blocks = static_cast<size_t>((p.out_channels + nr - 1) / nr);
  const size_t per_tap = static_cast<size_t>(p.in_channels) * static_cast<size_t>(nr);
  Sizes s;
  s.weights = RoundUp16(blocks * static_cast<size_t>(p.kernel_h * p.kernel_w) * per_tap);
  s.bias = RoundUp16(blocks * static_cast<size_t>(nr));
  if (with_phases) s.phases = RoundUp16(4 * blocks * 4 * per_tap);
  return s;
}

}  // namespace

int DefaultCinBlock(const ConvParams& p, int nr, bool with_phases) {
  const size_t taps = with_phases ? 4 : static_cast<size_t>(p.kernel_h * p.kernel_w);
  const size_t per_channel = taps * static_cast<size_t>(nr) * sizeof(float);
  int kc = static_cast<int>(kConvWeightBlockBytes / per_channel);
  if (kc < 16) kc = 16;
  if (kc >= p.in_channels) return p.in_channels;
  const int passes = (p.in_channels + kc - 1) / kc;
  return (p.in_channels + passes - 1) / passes;
}

size_t PackedConvFloats(const ConvParams& params, int nr, bool with_phases) {
  const Sizes s = SizesOf(params, nr, with_phases);
  return s.weights + s.bias + s.phases;
}

size_t PackedConvFewOutFloats(const ConvParams& p) {
  const size_t taps = static_cast<size_t>(p.kernel_h * p.kernel_w);
  return RoundUp16(taps * static_cast<size_t>(p.out_channels) * RoundUp16(p.in_channels)) +
         RoundUp16(static_cast<size_t>(p.out_channels));
}

PackedConv PackConvFewOut(const ConvParams& p, float* dst) {
  const int cin = p.in_channels, cout = p.out_channels, taps = p.kernel_h * p.kernel_w;
  const int cs = static_cast<int>(RoundUp16(static_cast<size_t>(cin)));
  PackedConv out;
  out.in_channels = cin;
  out.out_channels = cout;
  out.kernel_h = p.kernel_h;
  out.kernel_w = p.kernel_w;
  out.stride_h = p.stride_h;
  out.stride_w = p.stride_w;
  out.nr = cout;
  out.blocks = 1;
  out.cin_block = cin;
  out.activation = p.activation;
  out.leaky_slope = p.leaky_slope;
  out.few_ci_stride = cs;
  float* w = dst;
  for (int t = 0; t < taps; ++t) {
    for (int co = 0; co < cout; ++co) {
      for (int ci = 0; ci < cs; ++ci) {
        *w++ = ci < cin ? p.weights[(static_cast<size_t>(t) * cin + ci) * cout + co] : 0.0f;
      }
    }
  }
  float* bias = dst + RoundUp16(static_cast<size_t>(taps) * cout * cs);
  for (int co = 0; co < cout; ++co) bias[co] = p.bias[co];
  out.few_weights = dst;
  out.bias = bias;
  return out;
}

PackedConv PackConv(const ConvParams& p, int nr, bool with_phases, float* dst) {
  assert(!with_phases || (p.kernel_h == 3 && p.kernel_w == 3));
  const Sizes s = SizesOf(p, nr, with_phases);
  const int cin = p.in_channels, cout = p.out_channels, taps = p.kernel_h * p.kernel_w;
  PackedConv out;
  out.in_channels = cin;
  out.out_channels = cout;
  out.kernel_h = p.kernel_h;
  out.kernel_w = p.kernel_w;
  out.stride_h = p.stride_h;
  out.stride_w = p.stride_w;
  out.nr = nr;
  out.blocks = (cout + nr - 1) / nr;
  out.cin_block = DefaultCinBlock(p, nr, with_phases);
  out.activation = p.activation;
  out.leaky_slope = p.leaky_slope;

  // HWIO source: w[tap][ci][co].
  auto src = [&](int tap, int ci, int co) {
    return p.weights[(static_cast<size_t>(tap) * cin + ci) * cout + co];
  };
  float* w = dst;
  for (int b = 0; b < out.blocks; ++b) {
    for (int t = 0; t < taps; ++t) {
      for (int ci = 0; ci < cin; ++ci) {
        for (int j = 0; j < nr; ++j) {
          const int co = b * nr + j;
          *w++ = co < cout ? src(t, ci, co) : 0.0f;
        }
      }
    }
  }
  float* bias = dst + s.weights;
  for (int i = 0; i < out.blocks * nr; ++i) bias[i] = i < cout ? p.bias[i] : 0.0f;
  out.weights = dst;
  out.bias = bias;

  if (with_phases) {
    // Along one axis: phase 0 -> taps {w0 + w1, w2}; phase 1 -> {w0, w1 + w2}.
    auto in_group = [](int phase, int tap, int k) {
      if (phase == 0) return tap == 0 ? k <= 1 : k == 2;
      return tap == 0 ? k == 0 : k >= 1;
    };
    float* ph = dst + s.weights + s.bias;
    out.phase_weights = ph;
    for (int py = 0; py < 2; ++py) {
      for (int px = 0; px < 2; ++px) {
        for (int b = 0; b < out.blocks; ++b) {
          for (int ty = 0; ty < 2; ++ty) {
            for (int tx = 0; tx < 2; ++tx) {
              for (int ci = 0; ci < cin; ++ci) {
                for (int j = 0; j < nr; ++j) {
                  const int co = b * nr + j;
                  float sum = 0.0f;
                  if (co < cout) {
                    for (int ky = 0; ky < 3; ++ky) {
                      if (!in_group(py, ty, ky)) continue;
                      for (int kx = 0; kx < 3; ++kx) {
                        if (in_group(px, tx, kx)) sum += src(ky * 3 + kx, ci, co);
                      }
                    }
                  }
                  *ph++ = sum;
                }
              }
            }
          }
        }
      }
    }
  }
  return out;
}

bool ConvRowsFirst(const PackedConv& p, const ConstTensorView& in, int out_rows) {
  if (p.blocks < 2) return false;
  const double input = static_cast<double>(in.height) * in.width * in.channels * sizeof(float);
  const double weights = static_cast<double>(p.blocks) * p.nr * p.kernel_h * p.kernel_w *
                         p.in_channels * sizeof(float);
  const double weight_reads = weights <= kRowsFirstWeightBytes ? weights : weights * out_rows;
  return input + weight_reads < input * p.blocks + weights;
}

}  // namespace sfrt
