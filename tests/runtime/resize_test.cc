// General resizing (schema 1.7): the reference kernel against values PyTorch documents for
// bilinear interpolation, a decoder with linear and cubic resizes on every ISA against the
// reference forward, tf_crop_and_resize (schema 1.9) against values worked out by hand, and
// what the loader and the writer refuse. (ONNX's own Resize test cases,
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

// ONNX's tf_crop_and_resize example (its Resize test case): the 4x4 input 1..16, roi H 0.4..1.2
// and W 0.6..1.7, sizes 3x3 (scale 3/4), extrapolation 10. Output row y reads source row
// 0.4 * 3 + y * 0.8 * 3 / 2 = 1.2, 2.4, 3.6 and column 1.8, 3.45, 5.1; a source beyond 3 is
// outside the input, so that pixel is 10. Inside: linear 1 + 4 * row + col.
ResizeParams CropAndResizeExample(ResizeMode mode) {
  ResizeParams p;
  p.mode = mode;
  p.coordinates = ResizeCoordinates::kTfCropAndResize;
  p.scale_num_h = p.scale_num_w = 3;
  p.scale_den_h = p.scale_den_w = 4;
  p.roi_start_h = 0.4f;
  p.roi_start_w = 0.6f;
  p.roi_end_h = 1.2f;
  p.roi_end_w = 1.7f;
  p.extrapolation_value = 10.0f;
  return p;
}

std::vector<float> Resize4x4To3x3(const ResizeParams& p) {
  std::vector<float> in(16);
  for (int k = 0; k < 16; ++k) in[static_cast<size_t>(k)] = static_cast<float>(k + 1);
  std::vector<float> out(9, NAN);
  ref::ResizeRows({in.data(), 4, 4, 1, 4}, p, DenseView(out.data(), 3, 3, 1), 0, 3);
  return out;
}

TEST(ResizeRef, CropAndResizeSamplesTheRegionAndExtrapolatesOutsideTheInput) {
  const auto linear = Resize4x4To3x3(CropAndResizeExample(ResizeMode::kLinear));
  const std::vector<float> want = {
      1 + 4 * 1.2f + 1.8f, 10, 10, 1 + 4 * 2.4f + 1.8f, 10, 10, 10, 10, 10};
  for (size_t k = 0; k < want.size(); ++k) EXPECT_NEAR(linear[k], want[k], 1e-5) << "element " << k;
  // Nearest (round_prefer_floor): rows 1.2 -> 1, 2.4 -> 2; column 1.8 -> 2.
  const auto nearest = Resize4x4To3x3(CropAndResizeExample(ResizeMode::kNearest));
  EXPECT_EQ(nearest[0], 1 + 4 * 1 + 2);
  EXPECT_EQ(nearest[3], 1 + 4 * 2 + 2);
  EXPECT_EQ(nearest[1], 10);
  EXPECT_EQ(nearest[8], 10);
}

TEST(ResizeRef, CropAndResizeToOnePixelSamplesTheRegionsCentre) {
  ResizeParams p = CropAndResizeExample(ResizeMode::kLinear);
  p.scale_num_h = p.scale_num_w = 1;  // 4 -> 1: source (start + end) / 2 * 3
  std::vector<float> in(16);
  for (int k = 0; k < 16; ++k) in[static_cast<size_t>(k)] = static_cast<float>(k + 1);
  float out = NAN;
  ref::ResizeRows({in.data(), 4, 4, 1, 4}, p, DenseView(&out, 1, 1, 1), 0, 1);
  // Row 0.8 * 3 = 2.4, column 1.15 * 3 = 3.45 > 3: outside.
  EXPECT_EQ(out, 10.0f);
  p.roi_end_w = 1.0f;  // column 0.8 * 3 = 2.4
  ref::ResizeRows({in.data(), 4, 4, 1, 4}, p, DenseView(&out, 1, 1, 1), 0, 1);
  EXPECT_NEAR(out, 1 + 4 * 2.4f + 2.4f, 1e-5);
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

// A decoder whose first resize crops and resizes: written, loaded (the region and the value
// kept) and run on every ISA.
exporter::ModelSpec CropAndResizeDecoderSpec() {
  exporter::ModelSpec spec = ResizingDecoderSpec();
  ResizeParams& r = std::get<exporter::ResizeSpec>(spec.layers[1]).params;
  r.coordinates = ResizeCoordinates::kTfCropAndResize;
  r.roi_start_h = 0.25f;
  r.roi_start_w = -0.1f;
  r.roi_end_h = 0.75f;
  r.roi_end_w = 1.2f;
  r.extrapolation_value = -0.5f;
  return spec;
}

TEST(ResizeSession, CropAndResizeKeepsItsRegionThroughTheFileOnEveryIsa) {
  auto model = testing::LoadOrDie(CropAndResizeDecoderSpec());
  ASSERT_NE(model, nullptr);
  const ResizeParams& r = model->layers()[1].resize;
  EXPECT_EQ(r.coordinates, ResizeCoordinates::kTfCropAndResize);
  EXPECT_EQ(r.roi_start_h, 0.25f);
  EXPECT_EQ(r.roi_start_w, -0.1f);
  EXPECT_EQ(r.roi_end_h, 0.75f);
  EXPECT_EQ(r.roi_end_w, 1.2f);
  EXPECT_EQ(r.extrapolation_value, -0.5f);
  EXPECT_EQ(model->metadata().schema_minor, kSchemaVersionMinor);
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{67, 121}, {37, 53}}, 12, 1e-5, 10);
}

TEST(ResizeLoading, RefusesANonFiniteRegionOfInterestNamingTheField) {
  exporter::ModelSpec spec = CropAndResizeDecoderSpec();
  std::get<exporter::ResizeSpec>(spec.layers[1]).params.roi_end_w = INFINITY;
  const auto bytes = testing::SerializeOrDie(spec);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy, {}, "r.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("layer 1 'up0': roi_end_w is inf; must be finite and within "
                                 "-64..64"),
            std::string::npos)
      << model.message();
}

TEST(ResizeWriting, CropAndResizeNeedsSchema19) {
  exporter::SerializeOptions options;
  options.schema_minor = 8;
  auto bytes = exporter::SerializeModel(CropAndResizeDecoderSpec(), options);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find(
                "'up0': Resize coordinates tf_crop_and_resize need schema 1.9; writing 1.8"),
            std::string::npos)
      << bytes.message();
}

}  // namespace
}  // namespace sfrt
