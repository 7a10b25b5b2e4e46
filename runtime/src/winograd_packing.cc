#include "winograd_packing.h"

#include <cassert>

#include "cpu_features.h"

namespace sfrt {
namespace {

size_t RoundUp16(size_t n) { return (n + 15) / 16 * 16; }

template <int M>
void TransformWeights(const ConvParams& p, int nr, int blocks, float* u) {
  using T = WinogradTransform<M>;
  constexpr int kA = T::kAlpha;
  const int cin = p.in_channels, cout = p.out_channels;
  // HWIO source: g[ky][kx][ci][co].
  auto g = [&](int ky, int kx, int ci, int co) {
    return static_cast<double>(
        p.weights[((static_cast<size_t>(ky) * 3 + kx) * cin + ci) * cout + co]);
  };
  for (int i = 0; i < kA; ++i) {
    for (int j = 0; j < kA; ++j) {
      for (int b = 0; b < blocks; ++b) {
        for (int ci = 0; ci < cin; ++ci) {
          for (int jj = 0; jj < nr; ++jj) {
            const int co = b * nr + jj;
            double sum = 0.0;
            if (co < cout) {
              for (int ky = 0; ky < 3; ++ky) {
                for (int kx = 0; kx < 3; ++kx)
                  sum += T::kG[i][ky] * g(ky, kx, ci, co) * T::kG[j][kx];
              }
            }
            *u++ = static_cast<float>(sum);
          }
        }
      }
    }
  }
}

}  // namespace

bool WinogradUpApplies(const ConvParams& p) {
  return p.kernel_h == 3 && p.kernel_w == 3 && p.stride_h == 1 && p.stride_w == 1 &&
         UndilatedUngrouped(p) && p.in_channels >= kWinogradMinChannels &&
         p.out_channels >= kWinogradMinChannels;
}

size_t PackedWinogradUpFloats(const ConvParams& p, int nr) {
  const size_t phase_stride = static_cast<size_t>((p.out_channels + nr - 1) / nr) * nr;
  const size_t n = 4 * phase_stride;
  return RoundUp16(9 * n * static_cast<size_t>(p.in_channels)) + RoundUp16(n) +
         RoundUp16(static_cast<size_t>(nr));
}

PackedWinograd PackWinogradUp(const ConvParams& p, int nr, float* dst) {
  using T = WinogradPhaseTransform;
  const int cin = p.in_channels, cout = p.out_channels;
  PackedWinograd w;
  w.m = 2;
  w.alpha = 3;
  w.in_channels = cin;
  w.out_channels = cout;
  w.nr = nr;
  w.phase_stride = (cout + nr - 1) / nr * nr;
  w.blocks = 4 * w.phase_stride / nr;
  w.activation = p.activation;
  w.leaky_slope = p.leaky_slope;
  w.k_stride = static_cast<int>(RoundUp16(static_cast<size_t>(cin)));
  w.n_stride = w.blocks * nr;
  auto g = [&](int ky, int kx, int ci, int co) {
    return static_cast<double>(
        p.weights[((static_cast<size_t>(ky) * 3 + kx) * cin + ci) * cout + co]);
  };
  // Along one axis: phase 0 -> taps {w0 + w1, w2}; phase 1 -> {w0, w1 + w2}.
  auto in_group = [](int phase, int tap, int k) {
    if (phase == 0) return tap == 0 ? k <= 1 : k == 2;
    return tap == 0 ? k == 0 : k >= 1;
  };
  float* u = dst;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      for (int b = 0; b < w.blocks; ++b) {
        for (int ci = 0; ci < cin; ++ci) {
          for (int jj = 0; jj < nr; ++jj) {
            const int n = b * nr + jj;
            const int ph = n / w.phase_stride, co = n % w.phase_stride;
            const int py = ph >> 1, px = ph & 1;
            double sum = 0.0;
            if (co < cout) {
              for (int ty = 0; ty < 2; ++ty) {
                for (int tx = 0; tx < 2; ++tx) {
                  double k = 0.0;
                  for (int ky = 0; ky < 3; ++ky) {
                    if (!in_group(py, ty, ky)) continue;
                    for (int kx = 0; kx < 3; ++kx) {
                      if (in_group(px, tx, kx)) k += g(ky, kx, ci, co);
                    }
                  }
                  sum += T::kG[i][ty] * k * T::kG[j][tx];
                }
              }
            }
            *u++ = static_cast<float>(sum);
          }
        }
      }
    }
  }
  const size_t n_total = static_cast<size_t>(w.n_stride);
  float* bias = dst + RoundUp16(9 * n_total * static_cast<size_t>(cin));
  for (size_t n = 0; n < n_total; ++n) {
    const int co = static_cast<int>(n % static_cast<size_t>(w.phase_stride));
    bias[n] = co < cout ? p.bias[co] : 0.0f;
  }
  float* zeros = bias + RoundUp16(n_total);
  for (int i = 0; i < nr; ++i) zeros[i] = 0.0f;
  w.weights = dst;
  w.bias = bias;
  w.zeros = zeros;
  return w;
}

bool WinogradApplies(const ConvParams& p) {
  return p.kernel_h == 3 && p.kernel_w == 3 && p.stride_h == 1 && p.stride_w == 1 &&
         UndilatedUngrouped(p) && p.in_channels >= kWinogradMinChannels &&
         p.out_channels >= kWinogradMinChannels;
}

size_t PackedWinogradFloats(const ConvParams& p, int m, int nr) {
  const size_t alpha = static_cast<size_t>(m) + 2;
  const size_t blocks = static_cast<size_t>((p.out_channels + nr - 1) / nr);
  return RoundUp16(alpha * alpha * blocks * static_cast<size_t>(p.in_channels) * nr) +
         RoundUp16(blocks * nr) + RoundUp16(static_cast<size_t>(nr));
}

PackedWinograd PackWinograd(const ConvParams& p, int m, int nr, float* dst) {
  assert(m == 2 || m == 4);
  PackedWinograd w;
  w.m = m;
  w.alpha = m + 2;
  w.in_channels = p.in_channels;
  w.out_channels = p.out_channels;
  w.nr = nr;
  w.blocks = (p.out_channels + nr - 1) / nr;
  w.activation = p.activation;
  w.leaky_slope = p.leaky_slope;
  w.k_stride = static_cast<int>(RoundUp16(static_cast<size_t>(p.in_channels)));
  w.n_stride = w.blocks * nr;
  const size_t u_floats = RoundUp16(static_cast<size_t>(w.alpha) * w.alpha * w.blocks *
                                    static_cast<size_t>(p.in_channels) * nr);
  if (m == 2) {
    TransformWeights<2>(p, nr, w.blocks, dst);
  } else {
    TransformWeights<4>(p, nr, w.blocks, dst);
  }
  float* bias = dst + u_floats;
  for (int i = 0; i < w.blocks * nr; ++i) bias[i] = i < p.out_channels ? p.bias[i] : 0.0f;
  float* zeros = bias + RoundUp16(static_cast<size_t>(w.blocks) * nr);
  for (int i = 0; i < nr; ++i) zeros[i] = 0.0f;
  w.weights = dst;
  w.bias = bias;
  w.zeros = zeros;
  return w;
}

}  // namespace sfrt

namespace sfrt {

const WinogradKernels* WinogradUpKernelsFor(Isa isa) {
  switch (VectorIsa(isa)) {
#if SFRT_HAVE_AVX2
    case Isa::kAvx2:
      return &avx2::WinogradUpKernels();
#endif
#if SFRT_HAVE_AVX512
    case Isa::kAvx512:
      return &avx512::WinogradUpKernels();
#endif
#if SFRT_HAVE_NEON
    case Isa::kNeon:
      return &neon::WinogradUpKernels();
#endif
    default:
      return nullptr;
  }
}

const WinogradKernels* WinogradKernelsFor(Isa isa, int m) {
  switch (VectorIsa(isa)) {
#if SFRT_HAVE_AVX2
    case Isa::kAvx2:
      return m == 4 ? &avx2::WinogradF4Kernels() : &avx2::WinogradF2Kernels();
#endif
#if SFRT_HAVE_AVX512
    case Isa::kAvx512:
      return m == 4 ? &avx512::WinogradF4Kernels() : &avx512::WinogradF2Kernels();
#endif
#if SFRT_HAVE_NEON
    case Isa::kNeon:
      return m == 4 ? &neon::WinogradF4Kernels() : &neon::WinogradF2Kernels();
#endif
    default:
      (void)m;
      return nullptr;
  }
}

}  // namespace sfrt
