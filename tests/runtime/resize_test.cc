// General resizing (schema 1.7): the reference kernel against values PyTorch documents for
// bilinear interpolation, a decoder with linear and cubic resizes on every ISA against the
// reference forward, and what the loader and the writer refuse. (ONNX's own Resize test cases,
// every mode and coordinate rule: tests/tools/onnx_node_tests.py.)
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "common/model_builders.h"
#include "common/session_compare.h"
#include "kernels/ref/resize_ref.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/isa.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"
#include "sfrt/shapes.h"

namespace sfrt {
namespace {

std::vector<float> Resize2x2(const ResizeParams& p, int oh, int ow) {
  const std::vector<float> in = {1, 2, 3, 4};  // 2x2, one channel
  std::vector<float> out(static_cast<size_t>(oh) * ow, NAN);
  ref::ResizeRows({in.data(), 2, 2, 1, 2}, p, DenseView(out.data(), oh, ow, 1), 0, oh);
  return out;
}

// torch.nn.functional.interpolate(x, scale_factor=2, mode="bilinear", align_corners=False) of
// [[1, 2], [3, 4]] (ONNX: linear, half_pixel).
TEST(ResizeRef, BilinearHalfPixelMatchesPyTorch) {
  ResizeParams p;
  p.mode = ResizeMode::kLinear;
  p.coordinates = ResizeCoordinates::kHalfPixel;
  p.scale_num_h = p.scale_num_w = 2;
  const std::vector<float> want = {1,   1.25, 1.75, 2,   1.5, 1.75, 2.25, 2.5,
                                   2.5, 2.75, 3.25, 3.5, 3,   3.25, 3.75, 4};
  const auto got = Resize2x2(p, 4, 4);
  for (size_t k = 0; k < want.size(); ++k) EXPECT_FLOAT_EQ(got[k], want[k]) << "element " << k;
}

// The same with align_corners=True: the corners stay, the rest in thirds.
TEST(ResizeRef, BilinearAlignCornersMatchesPyTorch) {
  ResizeParams p;
  p.mode = ResizeMode::kLinear;
  p.coordinates = ResizeCoordinates::kAlignCorners;
  p.scale_num_h = p.scale_num_w = 2;
  const auto got = Resize2x2(p, 4, 4);
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 4; ++x) {
      EXPECT_NEAR(got[y * 4 + x], 1 + 2 * (y / 3.0) + (x / 3.0), 1e-6) << y << "," << x;
    }
  }
}

// Keys' cubic kernel sums to 1 for any a (a constant stays constant), and with a = -0.5 it also
// reproduces a linear ramp exactly away from the borders.
TEST(ResizeRef, CubicKeepsConstantsForAnyAAndARampForAMinusHalf) {
  for (float a : {-0.75f, -0.5f}) {
    ResizeParams p;
    p.mode = ResizeMode::kCubic;
    p.cubic_coeff_a = a;
    p.coordinates = ResizeCoordinates::kAsymmetric;
    p.scale_num_w = 3;
    p.scale_den_w = 2;
    std::vector<float> ramp(12);
    for (int x = 0; x < 12; ++x) ramp[x] = 0.5f * x;
    const std::vector<float> flat(12, 2.5f);
    std::vector<float> out(18, NAN);
    ref::ResizeRows({flat.data(), 1, 12, 1, 12}, p, DenseView(out.data(), 1, 18, 1), 0, 1);
    for (int x = 0; x < 18; ++x) EXPECT_NEAR(out[x], 2.5f, 1e-6) << "a " << a << ", x " << x;
    if (a != -0.5f) continue;
    ref::ResizeRows({ramp.data(), 1, 12, 1, 12}, p, DenseView(out.data(), 1, 18, 1), 0, 1);
    for (int x = 3; x < 14; ++x) EXPECT_NEAR(out[x], 0.5f * x / 1.5f, 1e-5) << "x " << x;
  }
}

// conv 3x3/2 -> linear x2 (half_pixel) -> conv 3x3 -> cubic x3/2 (align_corners) -> conv 1x1.
exporter::ModelSpec ResizingDecoderSpec() {
  using namespace sfrt::exporter;
  ModelSpec spec;
  spec.name = "resizing-decoder";
  std::mt19937 rng(11);
  auto conv = [&](const char* name, int in, int out, int k, int stride) {
    ConvSpec c;
    c.name = name;
    c.in_channels = in;
    c.out_channels = out;
    c.kernel_h = c.kernel_w = k;
    c.stride_h = c.stride_w = stride;
    c.pads = {k / 2, k / 2, k / 2, k / 2};
    c.activation = Activation::kLeakyRelu;
    c.leaky_slope = 0.1f;
    std::uniform_real_distribution<float> dist(-1.0f, 1.0f);
    c.weights_hwio.resize(static_cast<size_t>(k) * k * in * out);
    for (float& v : c.weights_hwio)
      v = dist(rng) / (k * std::sqrt(float(in)) * (in == 12 ? 64 : 1));
    c.bias.assign(static_cast<size_t>(out), 0.05f);
    return c;
  };
  spec.layers.push_back(conv("conv0", 12, 8, 3, 2));
  ResizeParams linear;
  linear.mode = ResizeMode::kLinear;
  linear.scale_num_h = linear.scale_num_w = 2;
  spec.layers.push_back(ResizeSpec{"up0", {}, linear});
  spec.layers.push_back(conv("conv1", 8, 16, 3, 1));
  ResizeParams cubic;
  cubic.mode = ResizeMode::kCubic;
  cubic.coordinates = ResizeCoordinates::kAlignCorners;
  cubic.scale_num_h = cubic.scale_num_w = 3;
  cubic.scale_den_h = cubic.scale_den_w = 2;
  spec.layers.push_back(ResizeSpec{"up1", {}, cubic});
  ConvSpec out = conv("output", 16, 3, 1, 1);
  out.activation = Activation::kNone;
  spec.layers.push_back(out);
  SetOutputChannels(spec, 3);
  return spec;
}

TEST(ResizeSession, ResizingDecoderMatchesTheReferenceForwardOnEveryIsa) {
  auto model = testing::LoadOrDie(ResizingDecoderSpec());
  ASSERT_NE(model, nullptr);
  // 67 -> 34 -> 68 -> 102 rows.
  auto shape = InferOutputShape(*model, 67, 121);
  ASSERT_TRUE(shape.ok()) << shape.message();
  EXPECT_EQ(shape->height, 102);
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{67, 121}, {37, 53}, {2, 3}}, 12, 1e-5,
                                                    9);
}

TEST(ResizeLoading, RefusesAZeroDenominatorNamingTheLayer) {
  exporter::ModelSpec spec = ResizingDecoderSpec();
  std::get<exporter::ResizeSpec>(spec.layers[3]).params.scale_den_w = 0;
  const auto bytes = testing::SerializeOrDie(spec);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy, {}, "r.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("layer 3 'up1': scale_w is 3/0"), std::string::npos)
      << model.message();
}

TEST(ResizeWriting, NeedsSchema17) {
  exporter::SerializeOptions options;
  options.schema_minor = 6;
  auto bytes = exporter::SerializeModel(ResizingDecoderSpec(), options);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("'up0': Resize needs schema 1.7; writing 1.6"), std::string::npos)
      << bytes.message();
}

}  // namespace
}  // namespace sfrt
