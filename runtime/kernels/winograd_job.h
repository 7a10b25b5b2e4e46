// Winograd convolution F(m x m, 3 x 3) for 3x3 stride-1 convolutions (Lavin and Gray, "Fast
// Algorithms for Convolutional Neural Networks", 2016): what the SIMD tiers are given and the
// transform matrices every tier (and the scalar reference, kernels/ref/winograd_ref.h) uses.
//
// The output is cut into m x m tiles; tile (ty, tx) reads the alpha x alpha input window
// (alpha = m + 2) starting at input row ty * m - pads.top, column tx * m - pads.left (zero
// outside the image). Per input channel, V = BT d B (d: the window); per weight, U = G g GT;
// then for each of the alpha^2 points p, M[p] = V[p] x U[p] is a (tiles x cin) by
// (cin x cout) matrix product; per output channel Y = AT M A (m x m) plus bias, activation.
// F(2x2, 3x3) does 16 multiplies per 4 outputs where direct convolution does 36 (2.25x fewer);
// F(4x4, 3x3) does 36 per 16 (4x fewer) but with larger transform constants, so more rounding.
//
// Run() does it in three passes, each split over the thread pool:
//   1. input transform, by tiles: in -> v[p][tile][k_stride]
//   2. products, by (point, output-channel block): v[p] x weights[p] -> m[p][tile][n_stride]
//   3. output transform, by tiles: m -> out, with bias and activation fused.
// v and m live in the session's arena (scratch of this step only), the transformed weights in
// its packed-weight memory (written at Session::Create).
#pragma once

#include <cstddef>

#include "kernels/tensor_view.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"

namespace sfrt {

// Transform matrices of F(m, 3) in one dimension, alpha = m + 2. Points 0, 1, -1 (and 2, -2 for
// m = 4) and infinity.
template <int M>
struct WinogradTransform;

template <>
struct WinogradTransform<2> {
  static constexpr int kM = 2;
  static constexpr int kAlpha = 4;
  static constexpr float kBt[4][4] = {{1, 0, -1, 0}, {0, 1, 1, 0}, {0, -1, 1, 0}, {0, 1, 0, -1}};
  static constexpr double kG[4][3] = {{1, 0, 0}, {0.5, 0.5, 0.5}, {0.5, -0.5, 0.5}, {0, 0, 1}};
  static constexpr float kAt[2][4] = {{1, 1, 1, 0}, {0, 1, -1, -1}};
};

template <>
struct WinogradTransform<4> {
  static constexpr int kM = 4;
  static constexpr int kAlpha = 6;
  static constexpr float kBt[6][6] = {
      {4, 0, -5, 0, 1, 0},  {0, -4, -4, 1, 1, 0}, {0, 4, -4, -1, 1, 0},
      {0, -2, -1, 2, 1, 0}, {0, 2, -1, -2, 1, 0}, {0, 4, 0, -5, 0, 1},
  };
  static constexpr double kG[6][3] = {
      {1.0 / 4, 0, 0},
      {-1.0 / 6, -1.0 / 6, -1.0 / 6},
      {-1.0 / 6, 1.0 / 6, -1.0 / 6},
      {1.0 / 24, 1.0 / 12, 1.0 / 6},
      {1.0 / 24, -1.0 / 12, 1.0 / 6},
      {0, 0, 1},
  };
  static constexpr float kAt[4][6] = {
      {1, 1, 1, 1, 1, 0}, {0, 1, -1, 2, -2, 0}, {0, 1, 1, 4, 4, 0}, {0, 1, -1, 8, -8, 1}};
};

// F(2, 2) for the fused nearest-2x upsample -> 3x3 convolution (conv_job.h): per output phase
// it is a 2x2 convolution over the low-resolution map L, so all four phases together are one
// 2x2 convolution over L with 4 x cout outputs, P[b][c][phase] (the output pixel of phase
// (py, px) whose window starts at upsampled row 2b + py, column 2c + px). F(2x2, 2x2) computes
// a 2x2 tile of P from a 3x3 window of L with 9 products where the phase kernels take 16
// (1.78x fewer); its constants are 0 and +-1, so it rounds like direct summation.
struct WinogradPhaseTransform {
  static constexpr int kM = 2;
  static constexpr int kAlpha = 3;
  static constexpr float kBt[3][3] = {{1, -1, 0}, {0, 1, 0}, {0, -1, 1}};
  static constexpr double kG[3][2] = {{1, 0}, {1, 1}, {0, 1}};
  static constexpr float kAt[2][3] = {{1, 1, 0}, {0, 1, 1}};
};

// Transformed weights of one layer for one tile size and one output-channel block width.
struct PackedWinograd {
  int m = 2;      // output tile side
  int alpha = 4;  // m + 2
  int in_channels = 0;
  int out_channels = 0;
  int nr = 0;      // output channels per block
  int blocks = 0;  // ceil(out_channels / nr)
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  const float* weights = nullptr;  // U: [alpha^2][blocks][in_channels][nr], 64-byte aligned
  const float* bias = nullptr;     // [blocks * nr]
  const float* zeros = nullptr;    // [nr] zeros (the products start from 0, not the bias)
  // Scratch layout (floats between consecutive tiles of one point).
  int k_stride = 0;  // in_channels rounded up to 16
  int n_stride = 0;  // blocks * nr
  // Fused upsample-conv (WinogradPhaseTransform) only: the products' columns are
  // [phase py * 2 + px][phase_stride], phase_stride = out_channels rounded up to nr; bias is
  // repeated per phase. 0 for a plain convolution.
  int phase_stride = 0;
};

// One run of one layer. v and m point into the arena; tiles_h x tiles_w tiles at this size.
struct WinogradArgs {
  const PackedWinograd* conv = nullptr;
  ConstTensorView in;
  TensorView out;
  Padding pads;  // in effect at this size (only top/left are read)
  int tiles_h = 0;
  int tiles_w = 0;
  float* v = nullptr;  // [alpha^2][tiles][k_stride]
  float* m = nullptr;  // [alpha^2][tiles][n_stride]
  // Fused upsample-conv only. `in` is L and the window of tile (ty, tx) starts at L row
  // 2 ty - pads.top (pads are then minus the band's first P row and column); the output pixel of
  // P[b][c][py, px] is (2b + py - crop_top + up_pad_top, 2c + px - crop_left + up_pad_left),
  // stored only inside rows [y_lo, y_hi) and columns [x_lo, x_hi) (the pixels whose 3x3 window
  // lies inside the cropped upsampled map; the direct kernel does the others).
  int up_pad_top = 0, up_pad_left = 0, crop_top = 0, crop_left = 0;
  int y_lo = 0, y_hi = 0, x_lo = 0, x_hi = 0;
};

// Pass 1 and 3 take tile ranges [begin, end) (tile = ty * tiles_w + tx); pass 2 takes items
// [begin, end), item = point * blocks + block. Safe to call concurrently on disjoint ranges of
// one pass; the passes must run in order.
using WinogradFn = void (*)(const WinogradArgs& args, int begin, int end);

struct WinogradKernels {
  int m = 0;   // 2 or 4
  int nr = 0;  // output channels per block of the products
  WinogradFn input = nullptr;
  WinogradFn product = nullptr;
  WinogradFn output = nullptr;
  const char* name = "";  // e.g. "conv2d_winograd_f2x2_3x3__avx512_6x64"
};

inline int WinogradTiles(int size, int m) { return (size + m - 1) / m; }

// Floats of the v and m scratch for an output of out_h x out_w.
inline size_t WinogradScratchFloats(const PackedWinograd& w, int out_h, int out_w) {
  const size_t tiles = static_cast<size_t>(WinogradTiles(out_h, w.m)) * WinogradTiles(out_w, w.m);
  const size_t points = static_cast<size_t>(w.alpha) * w.alpha;
  return points * tiles * (static_cast<size_t>(w.k_stride) + w.n_stride);
}

// The Winograd kernels of `isa` with tile side m (2 or 4), or null where this build has none.
const WinogradKernels* WinogradKernelsFor(Isa isa, int m);
// The fused upsample-conv's F(2x2, 2x2) kernels of `isa` (input pass over L, products, output
// pass scattering the phases), or null.
const WinogradKernels* WinogradUpKernelsFor(Isa isa);

namespace avx2 {
const WinogradKernels& WinogradUpKernels();
const WinogradKernels& WinogradF2Kernels();
const WinogradKernels& WinogradF4Kernels();
}  // namespace avx2
namespace avx512 {
const WinogradKernels& WinogradUpKernels();
const WinogradKernels& WinogradF2Kernels();
const WinogradKernels& WinogradF4Kernels();
}  // namespace avx512
namespace neon {
const WinogradKernels& WinogradUpKernels();
const WinogradKernels& WinogradF2Kernels();
const WinogradKernels& WinogradF4Kernels();
}  // namespace neon

}  // namespace sfrt
