// Per-channel scale and shift (schema 1.7, ChannelAffine): the reference kernel on hand-computed
// values, a network with one between convolutions on every ISA against the reference forward,
// and what the writer refuses. (ONNX's BatchNormalization test cases, which become this layer:
// tests/tools/onnx_node_tests.py.)
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "common/model_builders.h"
#include "common/session_compare.h"
#include "kernels/ref/affine_ref.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/isa.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"
#include "sfrt/shapes.h"

namespace sfrt {
namespace {

TEST(ChannelAffineRef, ScalesShiftsAndActivatesEachChannel) {
  const std::vector<float> in = {1, -2, 3, -4, 0.5f, 8};  // 1x2 pixels of 3 channels
  const float scale[3] = {2, -1, 0.5f};
  const float shift[3] = {0, 1, -3};
  ChannelAffineParams p;
  p.channels = 3;
  p.scale = scale;
  p.shift = shift;
  p.activation = Activation::kLeakyRelu;
  p.leaky_slope = 0.1f;
  std::vector<float> out(6, NAN);
  ref::ChannelAffineRows({in.data(), 1, 2, 3, 6}, p, DenseView(out.data(), 1, 2, 3), 0, 1);
  // 1*2+0 = 2; -2*-1+1 = 3; 3*0.5-3 = -1.5 -> -0.15; -4*2 = -8 -> -0.8; 0.5*-1+1 = 0.5; 8*0.5-3
  // = 1.
  const std::vector<float> want = {2, 3, -0.15f, -0.8f, 0.5f, 1};
  for (size_t k = 0; k < want.size(); ++k) EXPECT_FLOAT_EQ(out[k], want[k]) << "element " << k;
}

// conv 3x3 (relu) -> scale+shift (a batch norm after the activation) -> conv 3x3 -> relu alone.
exporter::ModelSpec AffineNetSpec() {
  using namespace sfrt::exporter;
  ModelSpec spec;
  spec.name = "affine-net";
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> dist(-1.0f, 1.0f);
  auto conv = [&](const char* name, int in, int out) {
    ConvSpec c;
    c.name = name;
    c.in_channels = in;
    c.out_channels = out;
    c.kernel_h = c.kernel_w = 3;
    c.pads = {1, 1, 1, 1};
    c.activation = Activation::kRelu;
    c.weights_hwio.resize(static_cast<size_t>(9) * in * out);
    for (float& v : c.weights_hwio) v = dist(rng) / (3 * std::sqrt(float(in)));
    c.bias.assign(static_cast<size_t>(out), 0.05f);
    return c;
  };
  spec.layers.push_back(conv("conv0", 12, 8));
  ChannelAffineSpec bn{"bn", {}, std::vector<float>(8), std::vector<float>(8)};
  for (float& v : bn.scale) v = 0.5f + dist(rng);
  for (float& v : bn.shift) v = dist(rng);
  spec.layers.push_back(bn);
  ConvSpec last = conv("conv1", 8, 3);
  last.activation = Activation::kNone;
  spec.layers.push_back(last);
  spec.layers.push_back(ChannelAffineSpec{"act",
                                          {},
                                          std::vector<float>(3, 1.0f),
                                          std::vector<float>(3, 0.0f),
                                          Activation::kLeakyRelu,
                                          0.2f});
  return spec;
}

TEST(ChannelAffineSession, MatchesTheReferenceForwardOnEveryIsa) {
  auto model = testing::LoadOrDie(AffineNetSpec());
  ASSERT_NE(model, nullptr);
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{67, 121}, {1, 2}}, 12, 1e-5);
}

// The activations only a ChannelAffine takes (schema 1.8), written, loaded and run by a session
// on every ISA, against the textbook formulas in double precision.
TEST(ChannelAffineSession, EluSigmoidTanhAndClipMatchTheirFormulasOnEveryIsa) {
  struct Case {
    Activation activation;
    double (*formula)(double);
  };
  const Case cases[] = {
      {Activation::kElu, [](double v) { return v > 0 ? v : 0.7 * (std::exp(v) - 1); }},
      {Activation::kSigmoid, [](double v) { return 1 / (1 + std::exp(-v)); }},
      {Activation::kTanh, [](double v) { return std::tanh(v); }},
      {Activation::kClip, [](double v) { return std::min(std::max(v, -1.5), 6.0); }},
  };
  const int h = 5, w = 7, c = 12;
  std::vector<float> input(static_cast<size_t>(h) * w * c);
  for (size_t k = 0; k < input.size(); ++k) input[k] = static_cast<float>(k % 97) / 6 - 8;
  for (const Case& test : cases) {
    SCOPED_TRACE(ActivationName(test.activation));
    exporter::ModelSpec spec;
    spec.name = "activation";
    spec.output.channels = c;
    spec.output.channel_names.clear();
    exporter::ChannelAffineSpec a{
        "act", {}, std::vector<float>(c, 0.5f), std::vector<float>(c, 0.25f)};
    a.activation = test.activation;
    a.elu_alpha = 0.7f;
    a.clip_min = -1.5f;
    a.clip_max = 6.0f;
    spec.layers.push_back(a);
    auto model = testing::LoadOrDie(spec);
    ASSERT_NE(model, nullptr);
    EXPECT_EQ(model->layers()[0].affine.activation, test.activation);
    for (Isa isa : SupportedIsas()) {
      SCOPED_TRACE(IsaName(isa));
      const auto got = testing::RunSession(model, isa, 1, input, h, w);
      ASSERT_EQ(got.size(), input.size());
      for (size_t k = 0; k < got.size(); ++k) {
        const double want = test.formula(input[k] * 0.5 + 0.25);
        ASSERT_NEAR(got[k], want, 2e-6 * std::max(1.0, std::abs(want))) << "element " << k;
      }
    }
  }
}

TEST(ChannelAffineLoading, RefusesAClipWhoseMinimumIsAboveItsMaximumNamingTheLayer) {
  exporter::ModelSpec spec = AffineNetSpec();
  auto& act = std::get<exporter::ChannelAffineSpec>(spec.layers.back());
  act.activation = Activation::kClip;
  act.clip_min = 6.0f;
  act.clip_max = 0.0f;
  const auto bytes = testing::SerializeOrDie(spec);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy, {}, "c.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("layer 3 'act': clip range is 6.000000..0.000000; clip_min must "
                                 "be at most clip_max"),
            std::string::npos)
      << model.message();
}

TEST(ChannelAffineWriting, RefusesAScalePerChannelCountThatDiffersFromItsInput) {
  exporter::ModelSpec spec = AffineNetSpec();
  std::get<exporter::ChannelAffineSpec>(spec.layers[1]).scale.pop_back();
  auto bytes = exporter::SerializeModel(spec);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("'bn': holds 7 scales and 8 shifts; its input has 8 channels"),
            std::string::npos)
      << bytes.message();
}

TEST(ChannelAffineWriting, NeedsSchema17) {
  exporter::SerializeOptions options;
  options.schema_minor = 6;
  auto bytes = exporter::SerializeModel(AffineNetSpec(), options);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("'bn': ChannelAffine needs schema 1.7; writing 1.6"),
            std::string::npos)
      << bytes.message();
}

}  // namespace
}  // namespace sfrt
