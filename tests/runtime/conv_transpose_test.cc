// Transposed convolutions (schema 1.6): the reference kernel against a scatter oracle written
// here (each input pixel adds its products to the outputs its taps reach, summed in double), a
// small FlowNetS-style graph on every ISA against the reference forward, and what the writer and
// the loader refuse. (PyTorch parity: the flownets cases of tests/runtime/pytorch_parity_test.)
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "common/deconv_spec.h"
#include "common/model_builders.h"
#include "common/session_compare.h"
#include "kernels/ref/conv_transpose_ref.h"
#include "sfrt/isa.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"
#include "sfrt/shapes.h"

namespace sfrt {
namespace {

constexpr double kRelativeTolerance = 1e-4;

std::vector<float> Seeded(size_t n, uint32_t seed, float scale) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(-scale, scale);
  std::vector<float> v(n);
  for (float& x : v) x = dist(rng);
  return v;
}

// The definition, scattered: out starts at bias; in[iy][ix] . w[ky][kx] goes to output pixel
// (iy * s - pad_top + ky, ix * s - pad_left + kx) when that pixel exists.
std::vector<double> ScatterOracle(const std::vector<float>& in, int ih, int iw,
                                  const ConvTransposeParams& p, int oh, int ow) {
  const int ic = p.in_channels, oc = p.out_channels;
  std::vector<double> out(static_cast<size_t>(oh) * ow * oc);
  for (size_t k = 0; k < out.size(); ++k) out[k] = p.bias[k % oc];
  for (int iy = 0; iy < ih; ++iy) {
    for (int ix = 0; ix < iw; ++ix) {
      for (int ky = 0; ky < p.kernel_h; ++ky) {
        for (int kx = 0; kx < p.kernel_w; ++kx) {
          const int y = iy * p.stride_h - p.pads.top + ky;
          const int x = ix * p.stride_w - p.pads.left + kx;
          if (y < 0 || y >= oh || x < 0 || x >= ow) continue;
          for (int i = 0; i < ic; ++i) {
            const double a = in[(static_cast<size_t>(iy) * iw + ix) * ic + i];
            for (int o = 0; o < oc; ++o) {
              out[(static_cast<size_t>(y) * ow + x) * oc + o] +=
                  a * p.weights[((static_cast<size_t>(ky) * p.kernel_w + kx) * ic + i) * oc + o];
            }
          }
        }
      }
    }
  }
  for (double& v : out) {
    if (p.activation == Activation::kLeakyRelu && v < 0) v *= p.leaky_slope;
    if (p.activation == Activation::kRelu && v < 0) v = 0;
  }
  return out;
}

struct DeconvCase {
  int ih, iw, ic, oc, k, s;
  Padding pads;
  int out_pad;
  Activation act;
};

// FlowNetS's 4x4/2 (features and flows), a 3x3/2 with output padding (DispNet-style), an odd
// 5x5/3 with uneven pads, a 2x2/2 without overlap and a 1x1/1.
TEST(ConvTransposeRef, MatchesTheScatterOracleOnDecoderShapes) {
  const DeconvCase cases[] = {
      {5, 8, 32, 16, 4, 2, {1, 1, 1, 1}, 0, Activation::kLeakyRelu},
      {9, 16, 3, 3, 4, 2, {1, 1, 1, 1}, 0, Activation::kNone},
      {7, 11, 8, 12, 3, 2, {1, 1, 1, 1}, 1, Activation::kRelu},
      {6, 5, 4, 5, 5, 3, {0, 2, 4, 1}, 2, Activation::kNone},
      {4, 7, 16, 8, 2, 2, {0, 0, 0, 0}, 0, Activation::kLeakyRelu},
      {3, 3, 5, 7, 1, 1, {0, 0, 0, 0}, 0, Activation::kNone},
  };
  uint32_t seed = 1;
  for (const DeconvCase& c : cases) {
    SCOPED_TRACE(std::to_string(c.k) + "x" + std::to_string(c.k) + "/" + std::to_string(c.s) + " " +
                 std::to_string(c.ic) + "->" + std::to_string(c.oc));
    const auto w = Seeded(static_cast<size_t>(c.k) * c.k * c.ic * c.oc, seed++, 0.5f);
    const auto b = Seeded(static_cast<size_t>(c.oc), seed++, 0.5f);
    const auto in = Seeded(static_cast<size_t>(c.ih) * c.iw * c.ic, seed++, 1.0f);
    ConvTransposeParams p;
    p.in_channels = c.ic;
    p.out_channels = c.oc;
    p.kernel_h = p.kernel_w = c.k;
    p.stride_h = p.stride_w = c.s;
    p.pads = c.pads;
    p.output_padding_h = p.output_padding_w = c.out_pad;
    p.activation = c.act;
    p.leaky_slope = 0.1f;
    p.weights = w.data();
    p.bias = b.data();
    const int oh = (c.ih - 1) * c.s - c.pads.top - c.pads.bottom + c.k + c.out_pad;
    const int ow = (c.iw - 1) * c.s - c.pads.left - c.pads.right + c.k + c.out_pad;
    const auto want = ScatterOracle(in, c.ih, c.iw, p, oh, ow);
    std::vector<float> got(want.size(), NAN);
    const ConstTensorView iv{in.data(), c.ih, c.iw, c.ic, static_cast<ptrdiff_t>(c.iw) * c.ic};
    const TensorView ov = DenseView(got.data(), oh, ow, c.oc);
    // In two row ranges, as a session splits it over threads.
    ref::ConvTranspose2dRows(iv, p, ov, 0, oh / 2);
    ref::ConvTranspose2dRows(iv, p, ov, oh / 2, oh);
    double max_err = 0;
    for (size_t k = 0; k < want.size(); ++k) {
      ASSERT_TRUE(std::isfinite(got[k])) << "element " << k << " not written";
      max_err = std::max(max_err, std::abs(got[k] - want[k]));
    }
    EXPECT_LE(max_err, 1e-5);
  }
}

TEST(ConvTransposeSession, TwoLevelDecoderMatchesTheReferenceForwardOnEveryIsaAtOddSizes) {
  auto model = testing::LoadOrDie(testing::TwoLevelDecoderSpec());
  ASSERT_NE(model, nullptr);
  for (auto [h, w] : {std::pair{67, 121}, {37, 53}, {8, 8}}) {
    auto shape = InferOutputShape(*model, h, w);
    ASSERT_TRUE(shape.ok()) << shape.message();
    EXPECT_EQ(shape->height, h);
    EXPECT_EQ(shape->width, w);
  }
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{67, 121}, {37, 53}, {8, 8}}, 12,
                                                    kRelativeTolerance, 3);
}

TEST(ConvTransposeSession, ReportsTheReferenceKernelForItsStep) {
  auto model = testing::LoadOrDie(testing::TwoLevelDecoderSpec());
  ASSERT_NE(model, nullptr);
  SessionOptions options;
  options.max_height = 32;
  options.max_width = 32;
  auto session = Session::Create(model, options);
  ASSERT_TRUE(session.ok()) << session.message();
  int deconv_steps = 0;
  for (const PlannedStep& step : (*session)->steps()) {
    if (model->layers()[static_cast<size_t>(step.first_layer)].kind ==
        LayerKind::kConvTranspose2D) {
      ++deconv_steps;
      EXPECT_STREQ(step.kernel, "ref::ConvTranspose2dRows");
    }
  }
  EXPECT_EQ(deconv_steps, 2);
}

TEST(ConvTransposeWriter, RefusesASchemaBefore16) {
  exporter::SerializeOptions options;
  options.schema_minor = 5;
  auto bytes = exporter::SerializeModel(testing::TwoLevelDecoderSpec(), options);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("'deconv2': ConvTranspose2D needs schema 1.6; writing 1.5"),
            std::string::npos)
      << bytes.message();
}

// Each fault in turn, in a file the writer accepts (it checks counts, not ranges).
TEST(ConvTransposeLoading, RefusesOutputPaddingAndPadsOutOfRangeNamingTheLayer) {
  struct Fault {
    const char* what;
    void (*apply)(exporter::ConvTransposeSpec&);
    const char* message;
  };
  const Fault faults[] = {
      {"output padding = stride", [](exporter::ConvTransposeSpec& d) { d.output_padding_h = 2; },
       "'deconv2': output padding is 2x0; each must be at least 0 and less than its stride (2x2)"},
      {"pad = kernel", [](exporter::ConvTransposeSpec& d) { d.pads.left = 4; },
       "'deconv2': pads.left is 4; must be in 0..3"},
      {"stride 0", [](exporter::ConvTransposeSpec& d) { d.stride_w = 0; },
       "'deconv2': stride is 2x0"},
  };
  for (const Fault& fault : faults) {
    SCOPED_TRACE(fault.what);
    exporter::ModelSpec spec = testing::TwoLevelDecoderSpec();
    fault.apply(std::get<exporter::ConvTransposeSpec>(spec.layers[2]));
    const auto bytes = testing::SerializeOrDie(spec);
    auto model =
        Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy, {}, "d.sfrt");
    ASSERT_FALSE(model.ok());
    EXPECT_NE(model.message().find(fault.message), std::string::npos) << model.message();
  }
}

// An int8 convolution before a transposed one (a float32-only layer): it quantises its input and
// writes float32 for the transposed convolution, on every ISA as in the reference forward, and
// (every weight 0.01, the input quantised to whole numbers) near the same model in float32.
TEST(ConvTransposeSession, RunsAnInt8ConvolutionBeforeItBetweenFloat32Tensors) {
  exporter::ModelSpec spec;
  spec.name = "int8-before-deconv";
  spec.input.channels = 12;
  exporter::ConvSpec c;
  c.name = "conv";
  c.in_channels = 12;
  c.out_channels = 4;
  c.pads = {1, 1, 1, 1};
  c.precision = Precision::kInt8;
  c.weights_q.assign(9 * 12 * 4, 1);
  c.weight_scales.assign(4, 0.01f);
  c.bias.assign(4, 0.0f);
  c.input_quant = {1.0f, 0};
  c.output_quant = {1.0f, 0};
  spec.layers.push_back(c);
  exporter::ConvTransposeSpec d;
  d.name = "deconv";
  d.in_channels = 4;
  d.out_channels = 3;
  d.pads = {1, 1, 1, 1};
  d.weights_hwio.assign(16 * 4 * 3, 0.1f);
  d.bias.assign(3, 0.0f);
  spec.layers.push_back(d);
  spec.output.channels = 3;
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  EXPECT_TRUE(model->float32_between_layers());
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{9, 13}, {16, 16}}, 12, 1e-6);
  exporter::ConvSpec& conv = std::get<exporter::ConvSpec>(spec.layers[0]);
  conv.precision = Precision::kFloat32;
  conv.weights_q.clear();
  conv.weight_scales.clear();
  conv.weights_hwio.assign(9 * 12 * 4, 0.01f);
  auto fp32 = testing::LoadOrDie(spec);
  ASSERT_NE(fp32, nullptr);
  const auto input = testing::RandomImage(9, 13, 12, 3);
  Result<TensorShape> shape = InferOutputShape(*model, 9, 13);
  ASSERT_TRUE(shape.ok()) << shape.message();
  std::vector<float> got(shape->elements()), want(shape->elements());
  ASSERT_TRUE(RunReferenceForward(*model, input, 9, 13, got).ok());
  ASSERT_TRUE(RunReferenceForward(*fp32, input, 9, 13, want).ok());
  // Rounding 108 inputs of 0..255 to whole numbers moves a convolution output of about 137 (at
  // most 275) by at most 0.54.
  EXPECT_LE(testing::RelativeMaxError(got, want), 1e-2);
}

}  // namespace
}  // namespace sfrt
