#include "kernels/ref/conv2d_ref.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "kernels/ref/resample_ref.h"
#include "sfrt/shapes.h"

namespace sfrt {
namespace {

TEST(Conv2dRef, HandComputedOneChannelExample) {
  // 3x3 input 1..9, 3x3 kernel of ones, bias 0.5, pads 1: each output is the sum of its
  // neighbourhood plus 0.5.
  const std::vector<float> in = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  const std::vector<float> w(9, 1.0f);
  const float bias = 0.5f;
  ConvParams p;
  p.in_channels = p.out_channels = 1;
  p.kernel_h = p.kernel_w = 3;
  p.weights = w.data();
  p.bias = &bias;
  std::vector<float> out(9, -1.0f);
  ref::Conv2d({in.data(), 3, 3, 1, 3}, p, {1, 1, 1, 1}, DenseView(out.data(), 3, 3, 1));
  const std::vector<float> expected = {12.5, 21.5, 16.5, 27.5, 45.5, 33.5, 24.5, 39.5, 28.5};
  EXPECT_EQ(out, expected);
}

TEST(Conv2dRef, LeakyReluScalesOnlyNegativeValues) {
  const std::vector<float> in = {1.0f, -2.0f};
  const float w = 1.0f, bias = 0.0f;
  ConvParams p;
  p.in_channels = p.out_channels = 1;
  p.kernel_h = p.kernel_w = 1;
  p.weights = &w;
  p.bias = &bias;
  p.activation = Activation::kLeakyRelu;
  p.leaky_slope = 0.3f;
  std::vector<float> out(2);
  ref::Conv2d({in.data(), 1, 2, 1, 2}, p, {}, DenseView(out.data(), 1, 2, 1));
  EXPECT_FLOAT_EQ(out[0], 1.0f);
  EXPECT_FLOAT_EQ(out[1], -0.6f);
  p.activation = Activation::kRelu;
  ref::Conv2d({in.data(), 1, 2, 1, 2}, p, {}, DenseView(out.data(), 1, 2, 1));
  EXPECT_FLOAT_EQ(out[1], 0.0f);
}

// An independent formulation: materialise the zero-padded input in NCHW, weights in OIHW,
// accumulate in double, loop in a different order.
std::vector<float> DirectConv(const std::vector<float>& in_nhwc, int h, int w, int cin,
                              const std::vector<float>& w_hwio, const std::vector<float>& bias,
                              int cout, int k, int stride, Padding pads, int oh, int ow) {
  const int ph = h + pads.top + pads.bottom + k, pw = w + pads.left + pads.right + k;
  std::vector<double> padded(static_cast<size_t>(cin) * ph * pw, 0.0);
  for (int c = 0; c < cin; ++c)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        padded[(static_cast<size_t>(c) * ph + y + pads.top) * pw + x + pads.left] =
            in_nhwc[(static_cast<size_t>(y) * w + x) * cin + c];
  std::vector<float> out(static_cast<size_t>(oh) * ow * cout);
  for (int co = 0; co < cout; ++co)
    for (int y = 0; y < oh; ++y)
      for (int x = 0; x < ow; ++x) {
        double s = bias[co];
        for (int ci = 0; ci < cin; ++ci)
          for (int ky = 0; ky < k; ++ky)
            for (int kx = 0; kx < k; ++kx)
              s += padded[(static_cast<size_t>(ci) * ph + y * stride + ky) * pw + x * stride + kx] *
                   w_hwio[((static_cast<size_t>(ky) * k + kx) * cin + ci) * cout + co];
        out[(static_cast<size_t>(y) * ow + x) * cout + co] = static_cast<float>(s);
      }
  return out;
}

struct ConvCase {
  int h, w, cin, cout, k, stride;
  PaddingRule rule;
  Padding explicit_pads;
};

class Conv2dRefMatchesDirect : public ::testing::TestWithParam<ConvCase> {};

TEST_P(Conv2dRefMatchesDirect, OnRandomData) {
  const ConvCase c = GetParam();
  std::mt19937 rng(c.h * 131 + c.w * 7 + c.cin);
  std::uniform_real_distribution<float> dist(-1.0f, 1.0f);
  std::vector<float> in(static_cast<size_t>(c.h) * c.w * c.cin),
      w(static_cast<size_t>(c.k) * c.k * c.cin * c.cout), bias(c.cout);
  for (auto* v : {&in, &w, &bias})
    for (float& x : *v) x = dist(rng);
  Padding pads;
  const int oh = ConvOutputSize(c.h, c.k, c.stride, c.rule, c.explicit_pads.top,
                                c.explicit_pads.bottom, &pads.top, &pads.bottom);
  const int ow = ConvOutputSize(c.w, c.k, c.stride, c.rule, c.explicit_pads.left,
                                c.explicit_pads.right, &pads.left, &pads.right);
  ASSERT_GT(oh, 0);
  ASSERT_GT(ow, 0);
  ConvParams p;
  p.in_channels = c.cin;
  p.out_channels = c.cout;
  p.kernel_h = p.kernel_w = c.k;
  p.stride_h = p.stride_w = c.stride;
  p.weights = w.data();
  p.bias = bias.data();
  std::vector<float> out(static_cast<size_t>(oh) * ow * c.cout);
  ref::Conv2d({in.data(), c.h, c.w, c.cin, static_cast<ptrdiff_t>(c.w) * c.cin}, p, pads,
              DenseView(out.data(), oh, ow, c.cout));
  const auto expected =
      DirectConv(in, c.h, c.w, c.cin, w, bias, c.cout, c.k, c.stride, pads, oh, ow);
  ASSERT_EQ(out.size(), expected.size());
  for (size_t i = 0; i < out.size(); ++i) ASSERT_NEAR(out[i], expected[i], 1e-5) << "at " << i;
}

INSTANTIATE_TEST_SUITE_P(
    Shapes, Conv2dRefMatchesDirect,
    ::testing::Values(ConvCase{5, 7, 3, 4, 3, 1, PaddingRule::kSameUpper, {}},
                      ConvCase{6, 8, 12, 5, 3, 2, PaddingRule::kSameUpper, {}},
                      ConvCase{7, 9, 12, 5, 3, 2, PaddingRule::kSameUpper, {}},
                      ConvCase{7, 9, 12, 5, 3, 2, PaddingRule::kExplicit, {1, 1, 1, 1}},
                      ConvCase{8, 5, 2, 3, 3, 2, PaddingRule::kExplicit, {0, 2, 1, 0}},
                      ConvCase{4, 4, 17, 33, 1, 1, PaddingRule::kExplicit, {0, 0, 0, 0}},
                      ConvCase{9, 6, 3, 2, 5, 3, PaddingRule::kSameUpper, {}},
                      ConvCase{1, 1, 4, 3, 3, 1, PaddingRule::kSameUpper, {}},
                      ConvCase{8, 7, 3, 4, 4, 1, PaddingRule::kSameLower, {}},
                      ConvCase{6, 9, 5, 3, 3, 2, PaddingRule::kSameLower, {}}));

// ONNX SAME_LOWER pads the same total as SAME_UPPER, with the odd pixel first.
TEST(ConvOutputSize, SameLowerPadsTheSameTotalWithTheLargerHalfFirst) {
  struct Case {
    int in, kernel, stride, upper_before, upper_after;
  };
  for (const Case c : {Case{540, 3, 2, 0, 1}, Case{135, 3, 2, 1, 1}, Case{8, 4, 1, 1, 2},
                       Case{5, 3, 2, 1, 1}, Case{7, 1, 1, 0, 0}}) {
    int upper_before = -1, upper_after = -1, lower_before = -1, lower_after = -1;
    const int upper_out = ConvOutputSize(c.in, c.kernel, c.stride, PaddingRule::kSameUpper, 9, 9,
                                         &upper_before, &upper_after);
    const int lower_out = ConvOutputSize(c.in, c.kernel, c.stride, PaddingRule::kSameLower, 9, 9,
                                         &lower_before, &lower_after);
    EXPECT_EQ(upper_out, (c.in + c.stride - 1) / c.stride) << c.in;
    EXPECT_EQ(lower_out, upper_out) << c.in;
    EXPECT_EQ(upper_before, c.upper_before) << c.in;
    EXPECT_EQ(upper_after, c.upper_after) << c.in;
    EXPECT_EQ(lower_before, c.upper_after) << c.in;
    EXPECT_EQ(lower_after, c.upper_before) << c.in;
  }
}

TEST(UpsampleNearestRef, RepeatsEachPixelFactorTimes) {
  const std::vector<float> in = {1, 10, 2, 20, 3, 30, 4, 40};  // 2x2, 2 channels
  std::vector<float> out(4 * 6 * 2);
  ref::UpsampleNearest({in.data(), 2, 2, 2, 4}, 2, 3, DenseView(out.data(), 4, 6, 2));
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 6; ++x)
      for (int c = 0; c < 2; ++c)
        EXPECT_EQ(out[(y * 6 + x) * 2 + c], in[((y / 2) * 2 + x / 3) * 2 + c]) << y << "," << x;
}

TEST(CopyRef, CopiesAStridedViewDensely) {
  std::vector<float> in(5 * 4);
  for (size_t i = 0; i < in.size(); ++i) in[i] = static_cast<float>(i);
  // View rows 1..3, columns 1..2 of a 5x4 single-channel image.
  const ConstTensorView view{in.data() + 4 + 1, 3, 2, 1, 4};
  std::vector<float> out(6);
  ref::Copy(view, DenseView(out.data(), 3, 2, 1));
  EXPECT_EQ(out, (std::vector<float>{5, 6, 9, 10, 13, 14}));
}

}  // namespace
}  // namespace sfrt
