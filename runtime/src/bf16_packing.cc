#include "bf16_packing.h"

#include <cassert>
#include <cstdint>
#include <cstring>

namespace sfrt {
namespace {

size_t RoundUp64(size_t n) { return (n + 63) / 64 * 64; }

struct Bf16Sizes {
  int blocks = 1;
  int cin2 = 0;
  size_t bias = 0;        // bytes
  size_t hwio = 0;        // bytes
  size_t weights = 0;     // bytes of the SIMD layout
  size_t phase_hwio = 0;  // bytes, all four phases
  size_t phase_simd = 0;  // bytes of one phase's SIMD layout
  int few_ci_stride = 0;  // > 0: the few-output layout (bf16_job.h)
  size_t few = 0;         // bytes
};

Bf16Sizes SizesOf(const ConvParams& p, int nr, bool with_phases) {
  Bf16Sizes s;
  s.blocks = nr > 0 ? (p.out_channels + nr - 1) / nr : 1;
  s.cin2 = (p.in_channels + 1) / 2 * 2;
  const int lanes = nr > 0 ? s.blocks * nr : p.out_channels;
  const size_t taps = static_cast<size_t>(p.kernel_h) * p.kernel_w;
  s.bias = RoundUp64(static_cast<size_t>(lanes) * sizeof(float));
  s.hwio = RoundUp64(taps * p.in_channels * p.out_channels * sizeof(uint16_t));
  if (nr > 0) s.weights = RoundUp64(s.blocks * taps * s.cin2 * nr * sizeof(uint16_t));
  if (nr > 0 && Bf16FewOutputs(p)) {
    s.few_ci_stride = (p.in_channels + 31) / 32 * 32;
    s.few = RoundUp64(taps * p.out_channels * s.few_ci_stride * sizeof(uint16_t));
  }
  if (with_phases) {
    s.phase_hwio =
        RoundUp64(16 * static_cast<size_t>(p.in_channels) * p.out_channels * sizeof(uint16_t));
    if (nr > 0) s.phase_simd = RoundUp64(s.blocks * 4 * s.cin2 * nr * sizeof(uint16_t));
  }
  return s;
}

// HWIO bf16 weights of `taps` taps into w[block][tap][ci / 2][nr][ci % 2] (zero-filled memory).
void BlockWeights(const uint16_t* hwio, int taps, int cin, int cout, int nr, int blocks, int cin2,
                  uint16_t* w) {
  for (int blk = 0; blk < blocks; ++blk) {
    for (int t = 0; t < taps; ++t) {
      uint16_t* wt = w + (static_cast<size_t>(blk) * taps + t) * cin2 * nr;
      for (int ci = 0; ci < cin; ++ci) {
        for (int j = 0; j < nr; ++j) {
          const int co = blk * nr + j;
          if (co >= cout) continue;
          wt[(static_cast<size_t>(ci / 2) * nr + j) * 2 + ci % 2] =
              hwio[(static_cast<size_t>(t) * cin + ci) * cout + co];
        }
      }
    }
  }
}

}  // namespace

size_t PackedBf16Bytes(const ConvParams& params, int nr, bool with_phases) {
  const Bf16Sizes s = SizesOf(params, nr, with_phases);
  return s.bias + s.hwio + s.weights + s.few + s.phase_hwio + 4 * s.phase_simd;
}

PackedBf16Conv PackBf16Conv(const ConvParams& p, int nr, bool with_phases, bool out_float,
                            void* dst) {
  assert(!with_phases || (p.kernel_h == 3 && p.kernel_w == 3));
  const Bf16Sizes s = SizesOf(p, nr, with_phases);
  uint8_t* base = static_cast<uint8_t*>(dst);
  std::memset(base, 0, PackedBf16Bytes(p, nr, with_phases));
  float* bias = reinterpret_cast<float*>(base);
  for (int o = 0; o < p.out_channels; ++o) bias[o] = p.bias[o];
  uint16_t* hwio = reinterpret_cast<uint16_t*>(base + s.bias);
  const int taps = p.kernel_h * p.kernel_w;
  const size_t n = static_cast<size_t>(taps) * p.in_channels * p.out_channels;
  for (size_t k = 0; k < n; ++k) hwio[k] = FloatToBf16(p.weights[k]);

  PackedBf16Conv out;
  out.in_channels = p.in_channels;
  out.out_channels = p.out_channels;
  out.kernel_h = p.kernel_h;
  out.kernel_w = p.kernel_w;
  out.stride_h = p.stride_h;
  out.stride_w = p.stride_w;
  out.activation = p.activation;
  out.leaky_slope = p.leaky_slope;
  out.out_float = out_float;
  out.bias = bias;
  out.weights_hwio = hwio;
  out.nr = nr;
  out.blocks = s.blocks;
  out.cin2 = s.cin2;
  uint8_t* cursor = base + s.bias + s.hwio;
  if (nr > 0) {
    uint16_t* w = reinterpret_cast<uint16_t*>(cursor);
    BlockWeights(hwio, taps, p.in_channels, p.out_channels, nr, s.blocks, s.cin2, w);
    out.weights = w;
    cursor += s.weights;
  }
  if (s.few_ci_stride > 0) {
    uint16_t* few = reinterpret_cast<uint16_t*>(cursor);
    for (int t = 0; t < taps; ++t) {
      for (int o = 0; o < p.out_channels; ++o) {
        for (int ci = 0; ci < p.in_channels; ++ci) {
          few[(static_cast<size_t>(t) * p.out_channels + o) * s.few_ci_stride + ci] =
              hwio[(static_cast<size_t>(t) * p.in_channels + ci) * p.out_channels + o];
        }
      }
    }
    out.few_weights = few;
    out.few_ci_stride = s.few_ci_stride;
    cursor += s.few;
  }
  if (!with_phases) return out;

  // Along one axis: phase 0 -> taps {w0 + w1, w2}; phase 1 -> {w0, w1 + w2} (conv_packing.cc).
  auto in_group = [](int phase, int tap, int k) {
    if (phase == 0) return tap == 0 ? k <= 1 : k == 2;
    return tap == 0 ? k == 0 : k >= 1;
  };
  uint16_t* ph = reinterpret_cast<uint16_t*>(cursor);
  const int cin = p.in_channels, cout = p.out_channels;
  const size_t phase_elems = static_cast<size_t>(4) * cin * cout;
  for (int py = 0; py < 2; ++py) {
    for (int px = 0; px < 2; ++px) {
      uint16_t* dst_phase = ph + (py * 2 + px) * phase_elems;
      for (int ty = 0; ty < 2; ++ty) {
        for (int tx = 0; tx < 2; ++tx) {
          for (int ci = 0; ci < cin; ++ci) {
            for (int co = 0; co < cout; ++co) {
              float sum = 0.0f;
              for (int ky = 0; ky < 3; ++ky) {
                if (!in_group(py, ty, ky)) continue;
                for (int kx = 0; kx < 3; ++kx) {
                  if (!in_group(px, tx, kx)) continue;
                  sum += p.weights[(static_cast<size_t>(ky * 3 + kx) * cin + ci) * cout + co];
                }
              }
              dst_phase[(static_cast<size_t>(ty * 2 + tx) * cin + ci) * cout + co] =
                  FloatToBf16(sum);
            }
          }
        }
      }
    }
  }
  out.phase_weights_hwio = ph;
  cursor += s.phase_hwio;
  if (nr == 0) return out;
  uint16_t* psimd = reinterpret_cast<uint16_t*>(cursor);
  for (int phase = 0; phase < 4; ++phase) {
    BlockWeights(ph + phase * phase_elems, 4, cin, cout, nr, s.blocks, s.cin2,
                 psimd + phase * (s.phase_simd / sizeof(uint16_t)));
  }
  out.phase_weights = psimd;
  return out;
}

}  // namespace sfrt
