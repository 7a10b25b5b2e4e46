#include "kernels/ref/winograd_ref.h"

#include <cassert>
#include <vector>

#include "kernels/winograd_job.h"

namespace sfrt::ref {
namespace {

template <int M>
void Run(const ConstTensorView& in, const ConvParams& p, const Padding& pads,
         const TensorView& out) {
  using T = WinogradTransform<M>;
  constexpr int kA = T::kAlpha;
  constexpr int kP = kA * kA;
  const int cin = p.in_channels, cout = p.out_channels;

  // 1. U[p][ci][co] = (G g GT)[p] for every weight g = w[.][.][ci][co].
  std::vector<float> u(static_cast<size_t>(kP) * cin * cout);
  for (int ci = 0; ci < cin; ++ci) {
    for (int co = 0; co < cout; ++co) {
      double g[3][3];
      for (int ky = 0; ky < 3; ++ky) {
        for (int kx = 0; kx < 3; ++kx) {
          g[ky][kx] = p.weights[((static_cast<size_t>(ky) * 3 + kx) * cin + ci) * cout + co];
        }
      }
      for (int i = 0; i < kA; ++i) {
        for (int j = 0; j < kA; ++j) {
          double sum = 0.0;
          for (int ky = 0; ky < 3; ++ky) {
            for (int kx = 0; kx < 3; ++kx) sum += T::kG[i][ky] * g[ky][kx] * T::kG[j][kx];
          }
          u[(static_cast<size_t>(i * kA + j) * cin + ci) * cout + co] = static_cast<float>(sum);
        }
      }
    }
  }

  std::vector<float> v(static_cast<size_t>(kP) * cin);  // one tile's V[p][ci]
  std::vector<float> mm(static_cast<size_t>(kP));       // one output channel's M[p]
  for (int oy0 = 0; oy0 < out.height; oy0 += M) {
    for (int ox0 = 0; ox0 < out.width; ox0 += M) {
      // 2. V = BT d B for every input channel of the window (zero outside the image).
      for (int ci = 0; ci < cin; ++ci) {
        float d[kA][kA];
        for (int i = 0; i < kA; ++i) {
          for (int j = 0; j < kA; ++j) {
            const int iy = oy0 - pads.top + i, ix = ox0 - pads.left + j;
            const bool inside = iy >= 0 && iy < in.height && ix >= 0 && ix < in.width;
            d[i][j] = inside ? in.pixel(iy, ix)[ci] : 0.0f;
          }
        }
        float t[kA][kA];
        for (int i = 0; i < kA; ++i) {
          for (int j = 0; j < kA; ++j) {
            float s = 0.0f;
            for (int k = 0; k < kA; ++k) s += T::kBt[i][k] * d[k][j];
            t[i][j] = s;
          }
        }
        for (int i = 0; i < kA; ++i) {
          for (int j = 0; j < kA; ++j) {
            float s = 0.0f;
            for (int k = 0; k < kA; ++k) s += t[i][k] * T::kBt[j][k];
            v[static_cast<size_t>(i * kA + j) * cin + ci] = s;
          }
        }
      }
      for (int co = 0; co < cout; ++co) {
        // 3. M[p] = sum over ci of V[p][ci] * U[p][ci][co].
        for (int q = 0; q < kP; ++q) {
          float s = 0.0f;
          for (int ci = 0; ci < cin; ++ci) {
            s += v[static_cast<size_t>(q) * cin + ci] *
                 u[(static_cast<size_t>(q) * cin + ci) * cout + co];
          }
          mm[q] = s;
        }
        // 4. Y = AT M A, plus bias, activation; only the pixels inside the output.
        float t[M][kA];
        for (int i = 0; i < M; ++i) {
          for (int j = 0; j < kA; ++j) {
            float s = 0.0f;
            for (int k = 0; k < kA; ++k) s += T::kAt[i][k] * mm[k * kA + j];
            t[i][j] = s;
          }
        }
        for (int i = 0; i < M && oy0 + i < out.height; ++i) {
          for (int j = 0; j < M && ox0 + j < out.width; ++j) {
            float y = p.bias[co];
            for (int k = 0; k < kA; ++k) y += t[i][k] * T::kAt[j][k];
            if (p.activation == Activation::kLeakyRelu) {
              y = y > 0.0f ? y : y * p.leaky_slope;
            } else if (p.activation == Activation::kRelu) {
              y = y > 0.0f ? y : 0.0f;
            }
            out.pixel(oy0 + i, ox0 + j)[co] = y;
          }
        }
      }
    }
  }
}

}  // namespace

void Conv2dWinograd(const ConstTensorView& in, const ConvParams& params, const Padding& pads, int m,
                    const TensorView& out) {
  assert(params.kernel_h == 3 && params.kernel_w == 3 && params.stride_h == 1 &&
         params.stride_w == 1);
  if (m == 4) {
    Run<4>(in, params, pads, out);
  } else {
    Run<2>(in, params, pads, out);
  }
}

}  // namespace sfrt::ref
