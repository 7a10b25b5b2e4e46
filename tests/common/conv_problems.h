// Single-convolution problems for the kernel tests (conv2d_simd_test, winograd_test): seeded
// input, weights and bias, and the output of the reference kernels (kernels/ref/, the oracle).
// Header-only; its users add runtime/src and runtime/ to their include path.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "kernels/ref/conv2d_ref.h"
#include "kernels/ref/resample_ref.h"
#include "kernels/tensor_view.h"
#include "sfrt/model.h"

namespace sfrt::testing {

// Seeded values uniform in [-scale, scale).
inline std::vector<float> RandomUniform(size_t n, uint32_t seed, float scale) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(-scale, scale);
  std::vector<float> v(n);
  for (float& x : v) x = dist(rng);
  return v;
}

// 64-byte-aligned floats (packed weights, Winograd scratch), 16 spare at the end.
struct AlignedFloats {
  explicit AlignedFloats(size_t n)
      : data(static_cast<float*>(std::aligned_alloc(64, (n + 16) * sizeof(float)))) {}
  ~AlignedFloats() { std::free(data); }
  AlignedFloats(const AlignedFloats&) = delete;
  AlignedFloats& operator=(const AlignedFloats&) = delete;
  float* data;
};

// The problems' views point into their own vectors: they move, never copy.
struct MoveOnly {
  MoveOnly() = default;
  MoveOnly(MoveOnly&&) = default;
  MoveOnly& operator=(MoveOnly&&) = default;
  MoveOnly(const MoveOnly&) = delete;
  MoveOnly& operator=(const MoveOnly&) = delete;
};

// A convolution of an h x w x cin input (rows extra_row_floats apart beyond w * cin, as in a
// cropped view) with a k x k kernel, stride `stride`, to cout channels.
struct ConvShape {
  int h, w, cin, cout, k, stride;
  Padding pads;  // top, left, bottom, right
  int extra_row_floats = 0;
  Activation act = Activation::kLeakyRelu;
};

inline std::string Describe(const ConvShape& c) {
  return std::to_string(c.h) + "x" + std::to_string(c.w) + "x" + std::to_string(c.cin) + "->" +
         std::to_string(c.cout) + " k" + std::to_string(c.k) + " s" + std::to_string(c.stride) +
         " pads " + std::to_string(c.pads.top) + "," + std::to_string(c.pads.left) + "," +
         std::to_string(c.pads.bottom) + "," + std::to_string(c.pads.right) + " rowpad " +
         std::to_string(c.extra_row_floats);
}

struct ConvProblem : MoveOnly {
  std::vector<float> input, weights, bias;
  ConvParams params;  // leaky ReLU slope 0.3 where the activation is leaky
  ConstTensorView in;
  int out_h = 0, out_w = 0;
  std::vector<float> want;  // ref::Conv2d's output, out_h x out_w x cout (empty if either <= 0)
};

// Input in [-1, 1) from `seed`, weights scaled by 1 / sqrt(k * k * cin) from seed + 1 (outputs
// of order 1), bias in [-0.5, 0.5) from seed + 2.
inline ConvProblem MakeConvProblem(const ConvShape& c, uint32_t seed) {
  ConvProblem pr;
  const ptrdiff_t row = static_cast<ptrdiff_t>(c.w) * c.cin + c.extra_row_floats;
  pr.input = RandomUniform(static_cast<size_t>(c.h) * row, seed, 1.0f);
  pr.weights = RandomUniform(static_cast<size_t>(c.k * c.k) * c.cin * c.cout, seed + 1,
                             1.0f / std::sqrt(static_cast<float>(c.k * c.k * c.cin)));
  pr.bias = RandomUniform(c.cout, seed + 2, 0.5f);
  pr.params.in_channels = c.cin;
  pr.params.out_channels = c.cout;
  pr.params.kernel_h = pr.params.kernel_w = c.k;
  pr.params.stride_h = pr.params.stride_w = c.stride;
  pr.params.activation = c.act;
  pr.params.leaky_slope = 0.3f;
  pr.params.weights = pr.weights.data();
  pr.params.bias = pr.bias.data();
  pr.in = ConstTensorView{pr.input.data(), c.h, c.w, c.cin, row};
  pr.out_h = (c.h + c.pads.top + c.pads.bottom - c.k) / c.stride + 1;
  pr.out_w = (c.w + c.pads.left + c.pads.right - c.k) / c.stride + 1;
  if (pr.out_h <= 0 || pr.out_w <= 0) return pr;
  pr.want.resize(static_cast<size_t>(pr.out_h) * pr.out_w * c.cout);
  ref::Conv2d(pr.in, pr.params, c.pads, DenseView(pr.want.data(), pr.out_h, pr.out_w, c.cout));
  return pr;
}

// The fused nearest-2x upsample -> crop -> 3x3 stride-1 convolution of an h x w x cin
// low-resolution input (conv_job.h).
struct UpConvShape {
  int h, w, cin, cout;
  int crop_top, crop_left, crop_bottom, crop_right;  // removed from the upsampled map
  Padding pads;
};

inline std::string Describe(const UpConvShape& c) {
  return std::to_string(c.h) + "x" + std::to_string(c.w) + "x" + std::to_string(c.cin) + "->" +
         std::to_string(c.cout) + " crop " + std::to_string(c.crop_top) + "," +
         std::to_string(c.crop_left) + "," + std::to_string(c.crop_bottom) + "," +
         std::to_string(c.crop_right) + " pads " + std::to_string(c.pads.top) + "," +
         std::to_string(c.pads.left) + "," + std::to_string(c.pads.bottom) + "," +
         std::to_string(c.pads.right);
}

struct UpConvProblem : MoveOnly {
  std::vector<float> low, weights, bias;
  ConvParams params;  // 3x3, stride 1, leaky ReLU 0.3
  ConstTensorView low_view;
  std::vector<float> up;    // the upsampled map, 2h x 2w x cin
  ConstTensorView cropped;  // the view of `up` the convolution reads (C in conv_job.h)
  int out_h = 0, out_w = 0;
  std::vector<float> want;  // reference upsample, crop view, convolution (empty if no output)
};

// Seeds as MakeConvProblem: low-resolution input from `seed`, weights from seed + 1, bias from
// seed + 2.
inline UpConvProblem MakeUpConvProblem(const UpConvShape& c, uint32_t seed) {
  UpConvProblem pr;
  pr.low = RandomUniform(static_cast<size_t>(c.h) * c.w * c.cin, seed, 1.0f);
  pr.weights = RandomUniform(static_cast<size_t>(9) * c.cin * c.cout, seed + 1,
                             1.0f / std::sqrt(9.0f * c.cin));
  pr.bias = RandomUniform(c.cout, seed + 2, 0.5f);
  pr.params.in_channels = c.cin;
  pr.params.out_channels = c.cout;
  pr.params.kernel_h = pr.params.kernel_w = 3;
  pr.params.activation = Activation::kLeakyRelu;
  pr.params.leaky_slope = 0.3f;
  pr.params.weights = pr.weights.data();
  pr.params.bias = pr.bias.data();

  // Reference: upsample into a tensor, crop as a view, convolve.
  pr.up.resize(static_cast<size_t>(4) * c.h * c.w * c.cin);
  pr.low_view = DenseView(pr.low.data(), c.h, c.w, c.cin);
  const TensorView up_view = DenseView(pr.up.data(), 2 * c.h, 2 * c.w, c.cin);
  ref::UpsampleNearest(pr.low_view, 2, 2, up_view);
  pr.cropped = up_view;
  pr.cropped.data = up_view.pixel(c.crop_top, c.crop_left);
  pr.cropped.height = 2 * c.h - c.crop_top - c.crop_bottom;
  pr.cropped.width = 2 * c.w - c.crop_left - c.crop_right;
  pr.out_h = pr.cropped.height + c.pads.top + c.pads.bottom - 2;
  pr.out_w = pr.cropped.width + c.pads.left + c.pads.right - 2;
  if (pr.out_h <= 0 || pr.out_w <= 0) return pr;
  pr.want.resize(static_cast<size_t>(pr.out_h) * pr.out_w * c.cout);
  ref::Conv2d(pr.cropped, pr.params, c.pads, DenseView(pr.want.data(), pr.out_h, pr.out_w, c.cout));
  return pr;
}

}  // namespace sfrt::testing
