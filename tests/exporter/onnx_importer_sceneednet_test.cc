// ImportOnnx on the SceneEDNet suite that tests/fixtures/gen_sceneednet.py exports from PyTorch
// (FIXTURES sceneednet_models). Fails, never skips, when the suite is missing.
#include <gtest/gtest.h>
#include <onnx/onnx_pb.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include "sfrt/exporter/onnx_importer.h"

namespace sfrt::exporter {
namespace {

struct FixtureCase {
  std::string name;
  int height = 0;
  int width = 0;
};

// Hidden widths conv0..conv9 of the full network (docs/sceneednet.md), and their strides.
constexpr std::array<int, 10> kFullWidths = {64, 128, 256, 512, 1024, 1024, 512, 256, 128, 64};
constexpr std::array<int, 10> kStrides = {2, 2, 2, 2, 1, 1, 1, 1, 1, 1};

std::string FixtureDir() { return SFRT_FIXTURE_DIR; }

std::vector<FixtureCase> ReadCases() {
  std::vector<FixtureCase> cases;
  std::ifstream f(FixtureDir() + "/cases.txt");
  std::string line;
  while (std::getline(f, line)) {
    if (line.empty()) continue;
    std::istringstream fields(line);
    FixtureCase c;
    fields >> c.name >> c.height >> c.width;
    EXPECT_TRUE(fields && !c.name.empty() && c.height > 0 && c.width > 0)
        << "bad line in cases.txt: " << line;
    if (fields) cases.push_back(c);
  }
  return cases;
}

int CeilDiv(int a, int b) { return (a + b - 1) / b; }

Pads SameUpper(int in_h, int in_w, int stride) {
  auto axis = [stride](int in, int* before, int* after) {
    const int total = std::max((CeilDiv(in, stride) - 1) * stride + 3 - in, 0);
    *before = total / 2;
    *after = total - total / 2;
  };
  Pads p;
  axis(in_h, &p.top, &p.bottom);
  axis(in_w, &p.left, &p.right);
  return p;
}

// The OIHW weights of initialiser `name` in the ONNX file.
std::vector<float> OnnxWeights(const onnx::ModelProto& model, const std::string& name) {
  for (const auto& t : model.graph().initializer()) {
    if (t.name() != name) continue;
    std::vector<float> w(t.raw_data().size() / 4);
    std::memcpy(w.data(), t.raw_data().data(), w.size() * 4);  // little-endian host
    if (w.empty()) w.assign(t.float_data().begin(), t.float_data().end());
    return w;
  }
  ADD_FAILURE() << "initializer " << name << " not found";
  return {};
}

void CheckHwioMatchesOihw(const ConvSpec& conv, const std::vector<float>& oihw) {
  ASSERT_EQ(conv.weights_hwio.size(), oihw.size()) << conv.name;
  const int kh = conv.kernel_h, kw = conv.kernel_w;
  const int cin = conv.in_channels, cout = conv.out_channels;
  for (int co = 0; co < cout; ++co) {
    for (int ci = 0; ci < cin; ++ci) {
      for (int ky = 0; ky < kh; ++ky) {
        for (int kx = 0; kx < kw; ++kx) {
          ASSERT_EQ(conv.weights_hwio[((ky * kw + kx) * cin + ci) * cout + co],
                    oihw[((co * cin + ci) * kh + ky) * kw + kx])
              << conv.name << " co " << co << " ci " << ci << " ky " << ky << " kx " << kx;
        }
      }
    }
  }
}

void CheckCase(const FixtureCase& fc) {
  // Case names: w{width_div}_{tf|torch}_{H}x{W}[...] (gen_sceneednet.py default_name).
  int width_div = 0;
  ASSERT_EQ(std::sscanf(fc.name.c_str(), "w%d_", &width_div), 1) << fc.name;
  ASSERT_GT(width_div, 0);
  const bool tf = fc.name.find("_tf_") != std::string::npos;
  const bool torch = fc.name.find("_torch_") != std::string::npos;
  ASSERT_NE(tf, torch) << "case name names neither or both paddings: " << fc.name;

  const std::string path = FixtureDir() + "/" + fc.name + ".onnx";
  const Result<ModelSpec> spec = ImportOnnx(path);
  ASSERT_TRUE(spec.ok()) << spec.message();

  EXPECT_EQ(spec->input.channels, 12);
  EXPECT_EQ(spec->input.traced_height, fc.height);
  EXPECT_EQ(spec->input.traced_width, fc.width);
  EXPECT_EQ(spec->output.channels, 3);
  EXPECT_EQ(spec->producer.source_format, "onnx");
  EXPECT_EQ(spec->producer.source_file, fc.name + ".onnx");
  EXPECT_EQ(spec->producer.source_sha256.size(), 64u);

  // conv0..conv5, up, conv6, up, conv7, up, conv8, up, crop, conv9, output.
  const std::string kinds = "CCCCCCUCUCUCUXCC";
  ASSERT_EQ(spec->layers.size(), kinds.size());
  int convs = 0, ups = 0, crops = 0;
  int h = fc.height, w = fc.width, channels = 12;
  onnx::ModelProto model;
  {
    std::ifstream f(path, std::ios::binary);
    ASSERT_TRUE(model.ParseFromIstream(&f)) << path;
  }
  for (size_t i = 0; i < kinds.size(); ++i) {
    SCOPED_TRACE("layer " + std::to_string(i));
    const LayerSpec& layer = spec->layers[i];
    switch (kinds[i]) {
      case 'C': {
        ASSERT_TRUE(std::holds_alternative<ConvSpec>(layer));
        const auto& c = std::get<ConvSpec>(layer);
        const bool is_output = convs == 10;
        const int stride = is_output ? 1 : kStrides[convs];
        const int out_channels = is_output ? 3 : kFullWidths[convs] / width_div;
        const std::string torch_name = is_output ? "output" : "conv" + std::to_string(convs);
        EXPECT_NE(c.name.find(torch_name), std::string::npos) << c.name;
        EXPECT_EQ(c.in_channels, channels);
        EXPECT_EQ(c.out_channels, out_channels);
        EXPECT_EQ(c.kernel_h, 3);
        EXPECT_EQ(c.kernel_w, 3);
        EXPECT_EQ(c.stride_h, stride);
        EXPECT_EQ(c.stride_w, stride);
        if (is_output) {
          EXPECT_EQ(c.activation, Activation::kNone);
        } else {
          EXPECT_EQ(c.activation, Activation::kLeakyRelu);
          EXPECT_FLOAT_EQ(c.leaky_slope, 0.3f);
        }
        if (tf) {
          EXPECT_EQ(c.padding_rule, PaddingRule::kSameUpper);
          EXPECT_EQ(c.pads, SameUpper(h, w, stride));
        } else {
          EXPECT_EQ(c.padding_rule, PaddingRule::kExplicit);
          EXPECT_EQ(c.pads, (Pads{1, 1, 1, 1}));
        }
        EXPECT_EQ(c.bias.size(), static_cast<size_t>(out_channels));
        if (convs == 0 || is_output)
          CheckHwioMatchesOihw(c, OnnxWeights(model, torch_name + ".weight"));
        channels = out_channels;
        h = CeilDiv(h, stride);
        w = CeilDiv(w, stride);
        ++convs;
        break;
      }
      case 'U': {
        ASSERT_TRUE(std::holds_alternative<UpsampleSpec>(layer));
        const auto& u = std::get<UpsampleSpec>(layer);
        EXPECT_EQ(u.factor_h, 2);
        EXPECT_EQ(u.factor_w, 2);
        h *= 2;
        w *= 2;
        ++ups;
        break;
      }
      default: {
        ASSERT_TRUE(std::holds_alternative<CropSpec>(layer));
        const auto& c = std::get<CropSpec>(layer);
        EXPECT_EQ(c.rule, CropRule::kToInputSize);
        EXPECT_TRUE(c.excess_rows_from_top);
        EXPECT_TRUE(c.excess_cols_from_left);
        EXPECT_EQ(c.amounts, (Pads{h - fc.height, w - fc.width, 0, 0}));
        h = fc.height;
        w = fc.width;
        ++crops;
        break;
      }
    }
  }
  EXPECT_EQ(convs, 11);
  EXPECT_EQ(ups, 4);
  EXPECT_EQ(crops, 1);
}

TEST(OnnxImporterSceneEDNet, ImportsEveryFixtureCaseAsTheDocumentedLayerChain) {
  const std::vector<FixtureCase> cases = ReadCases();
  ASSERT_FALSE(cases.empty()) << FixtureDir() << "/cases.txt is missing or empty: run the "
                              << "fixtures.generate_sceneednet test first (ctest -L fixtures)";
  bool saw_tf = false, saw_torch = false;
  for (const FixtureCase& fc : cases) {
    if (fc.name[0] != 'w') continue;  // SceneEDNet-U and FlowNetS: the tests below
    SCOPED_TRACE(fc.name);
    CheckCase(fc);
    saw_tf = saw_tf || fc.name.find("_tf_") != std::string::npos;
    saw_torch = saw_torch || fc.name.find("_torch_") != std::string::npos;
  }
  EXPECT_TRUE(saw_tf) << "the suite has no tf-padding case";
  EXPECT_TRUE(saw_torch) << "the suite has no torch-padding case";
}

// SceneEDNet-U (gen_sceneednet.py --arch sceneednet-u, u* cases): a graph of eleven
// convolutions (batch norms folded into them), four Concats (conv3's skip and three decoder
// levels), four upsamplings, three crops to the skip tensor's size and one to the input's.
TEST(OnnxImporterSceneEDNet, ImportsEverySceneEdNetUCaseAsAGraphWithSkipsAndFoldedNorms) {
  int u_cases = 0;
  for (const FixtureCase& fc : ReadCases()) {
    if (fc.name[0] != 'u') continue;
    SCOPED_TRACE(fc.name);
    ++u_cases;
    const Result<ModelSpec> spec = ImportOnnx(FixtureDir() + "/" + fc.name + ".onnx");
    ASSERT_TRUE(spec.ok()) << spec.message();
    EXPECT_TRUE(IsGraph(*spec));
    int convs = 0, cats = 0, ups = 0, skip_crops = 0, input_crops = 0;
    for (const LayerSpec& layer : spec->layers) {
      if (const auto* conv = std::get_if<ConvSpec>(&layer)) {
        ++convs;
        EXPECT_EQ(conv->activation,
                  conv->name == "output" ? Activation::kNone : Activation::kLeakyRelu)
            << conv->name;
      }
      cats += std::holds_alternative<ConcatSpec>(layer);
      ups += std::holds_alternative<UpsampleSpec>(layer);
      if (const auto* crop = std::get_if<CropSpec>(&layer)) {
        skip_crops += crop->rule == CropRule::kToSecondInput;
        input_crops += crop->rule == CropRule::kToInputSize;
      }
    }
    EXPECT_EQ(spec->layers.size(), 23u);
    EXPECT_EQ(convs, 11);
    EXPECT_EQ(cats, 4);
    EXPECT_EQ(ups, 4);
    EXPECT_EQ(skip_crops, 3);
    EXPECT_EQ(input_crops, 1);
  }
  EXPECT_GE(u_cases, 3) << "the suite has no SceneEDNet-U cases";
}

// The FlowNetS-style network (gen_sceneednet.py --arch flownets, f* cases): fifteen
// convolutions and eight transposed convolutions (batch norms folded into both: no layer
// normalises), four Concats of three tensors, and the crops odd sizes need.
TEST(OnnxImporterSceneEDNet, ImportsEveryFlowNetSCaseWithTransposedConvolutionsAndFoldedNorms) {
  int f_cases = 0;
  for (const FixtureCase& fc : ReadCases()) {
    if (fc.name[0] != 'f') continue;
    SCOPED_TRACE(fc.name);
    ++f_cases;
    const Result<ModelSpec> spec = ImportOnnx(FixtureDir() + "/" + fc.name + ".onnx");
    ASSERT_TRUE(spec.ok()) << spec.message();
    int convs = 0, deconvs = 0, cats = 0, leaky = 0;
    for (const LayerSpec& layer : spec->layers) {
      if (const auto* conv = std::get_if<ConvSpec>(&layer)) {
        ++convs;
        leaky += conv->activation == Activation::kLeakyRelu;
      }
      if (const auto* deconv = std::get_if<ConvTransposeSpec>(&layer)) {
        ++deconvs;
        EXPECT_EQ(deconv->kernel_h, 4);
        EXPECT_EQ(deconv->stride_h, 2);
        EXPECT_EQ(deconv->pads, (Pads{1, 1, 1, 1}));
        // Feature deconvolutions carry the leaky ReLU, the flow upsamplings none.
        EXPECT_EQ(deconv->activation,
                  deconv->name.rfind("deconv", 0) == 0 ? Activation::kLeakyRelu : Activation::kNone)
            << deconv->name;
      }
      if (const auto* cat = std::get_if<ConcatSpec>(&layer)) {
        ++cats;
        EXPECT_EQ(cat->inputs.size(), 3u);
      }
    }
    EXPECT_EQ(convs, 15);
    EXPECT_EQ(leaky, 10);  // the encoder; predictions are linear
    EXPECT_EQ(deconvs, 8);
    EXPECT_EQ(cats, 4);
    EXPECT_TRUE(IsGraph(*spec));
  }
  EXPECT_GE(f_cases, 3) << "the suite has no FlowNetS cases";
}

// The DispNetS-style network (gen_sceneednet.py --arch dispnets, d* cases): FlowNetS's encoder,
// and at each of five decoder levels an upconvolution, an upsampled prediction, a Concat of three
// tensors and an iconv (batch norms folded: only convolutions, transposed convolutions, crops and
// Concats remain).
TEST(OnnxImporterSceneEDNet, ImportsEveryDispNetSCaseWithIconvsAfterEachConcat) {
  int d_cases = 0;
  for (const FixtureCase& fc : ReadCases()) {
    if (fc.name[0] != 'd') continue;
    SCOPED_TRACE(fc.name);
    ++d_cases;
    const Result<ModelSpec> spec = ImportOnnx(FixtureDir() + "/" + fc.name + ".onnx");
    ASSERT_TRUE(spec.ok()) << spec.message();
    int convs = 0, deconvs = 0, cats = 0, others = 0;
    for (size_t i = 0; i < spec->layers.size(); ++i) {
      const LayerSpec& layer = spec->layers[i];
      convs += std::holds_alternative<ConvSpec>(layer);
      deconvs += std::holds_alternative<ConvTransposeSpec>(layer);
      others += std::holds_alternative<UpsampleSpec>(layer) ||
                std::holds_alternative<PoolSpec>(layer) || std::holds_alternative<AddSpec>(layer);
      if (std::holds_alternative<ConcatSpec>(layer)) {
        ++cats;
        // The iconv reads the Concat.
        ASSERT_LT(i + 1, spec->layers.size());
        const auto* iconv = std::get_if<ConvSpec>(&spec->layers[i + 1]);
        ASSERT_NE(iconv, nullptr);
        EXPECT_EQ(iconv->activation, Activation::kLeakyRelu);
      }
    }
    EXPECT_EQ(convs, 21);  // 10 encoder, pr6, and an iconv and a prediction per level
    EXPECT_EQ(deconvs, 10);
    EXPECT_EQ(cats, 5);
    EXPECT_EQ(others, 0);
  }
  EXPECT_GE(d_cases, 3) << "the suite has no DispNetS cases";
}

// The pooling encoder (gen_sceneednet.py --arch poolnet, p* cases): five convolutions (batch
// norms folded) and four poolings with the attributes PyTorch gave them.
TEST(OnnxImporterSceneEDNet, ImportsEveryPoolNetCaseWithItsPoolingAttributes) {
  int p_cases = 0;
  for (const FixtureCase& fc : ReadCases()) {
    if (fc.name[0] != 'p') continue;
    SCOPED_TRACE(fc.name);
    ++p_cases;
    const Result<ModelSpec> spec = ImportOnnx(FixtureDir() + "/" + fc.name + ".onnx");
    ASSERT_TRUE(spec.ok()) << spec.message();
    std::vector<PoolSpec> pools;
    int convs = 0;
    for (const LayerSpec& layer : spec->layers) {
      convs += std::holds_alternative<ConvSpec>(layer);
      if (const auto* pool = std::get_if<PoolSpec>(&layer)) pools.push_back(*pool);
    }
    EXPECT_EQ(convs, 5);
    ASSERT_EQ(pools.size(), 4u);
    // reference_nets.PoolNet: MaxPool2d(3, 2, 1), AvgPool2d(2, 2, ceil), AvgPool2d(3, 2, 1,
    // ceil, counting pads), MaxPool2d(2, 1, ceil).
    EXPECT_EQ(pools[0].kind, PoolKind::kMax);
    EXPECT_EQ(pools[0].pads, (Pads{1, 1, 1, 1}));
    EXPECT_FALSE(pools[0].ceil_mode);
    EXPECT_EQ(pools[1].kind, PoolKind::kAverage);
    EXPECT_TRUE(pools[1].ceil_mode);
    EXPECT_FALSE(pools[1].count_include_pad);
    EXPECT_EQ(pools[2].kind, PoolKind::kAverage);
    EXPECT_TRUE(pools[2].count_include_pad);
    EXPECT_EQ(pools[2].kernel_h, 3);
    EXPECT_EQ(pools[3].kind, PoolKind::kMax);
    EXPECT_EQ(pools[3].stride_h, 1);
  }
  EXPECT_GE(p_cases, 2) << "the suite has no poolnet cases";
}

// The depthwise-separable network (gen_sceneednet.py --arch separable, s* cases): eight
// convolutions, three of them depthwise (the second dilated by 2, the third with stride 2 and
// two outputs per input), batch norms folded into them (every scale and shift but the last is
// the identity), each ReLU6 a clip of its own after the ReLU PyTorch exports, and
// sigmoid(x) * 2 - 1 as a sigmoid and one scale and shift.
TEST(OnnxImporterSceneEDNet, ImportsEverySeparableCaseWithDepthwiseDilatedConvolutions) {
  int s_cases = 0;
  for (const FixtureCase& fc : ReadCases()) {
    if (fc.name[0] != 's') continue;
    SCOPED_TRACE(fc.name);
    ++s_cases;
    const Result<ModelSpec> spec = ImportOnnx(FixtureDir() + "/" + fc.name + ".onnx");
    ASSERT_TRUE(spec.ok()) << spec.message();
    std::vector<ConvSpec> convs;
    std::vector<ChannelAffineSpec> affines;
    for (const LayerSpec& layer : spec->layers) {
      if (const auto* c = std::get_if<ConvSpec>(&layer)) convs.push_back(*c);
      if (const auto* a = std::get_if<ChannelAffineSpec>(&layer)) affines.push_back(*a);
    }
    ASSERT_EQ(convs.size(), 8u);
    // SeparableNet at width / 16: conv0 12->4, dw1 (4 groups), pw1 4->8, dw2 (8 groups,
    // dilation 2), pw2, dw3 (8 groups, 8->16, stride 2), pw3 16->16, output 16->3.
    EXPECT_EQ(convs[1].groups, 4);
    EXPECT_EQ(convs[3].groups, 8);
    EXPECT_EQ(convs[3].dilation_h, 2);
    EXPECT_EQ(convs[3].dilation_w, 2);
    EXPECT_EQ(convs[3].pads, (Pads{2, 2, 2, 2}));
    EXPECT_EQ(convs[5].groups, 8);
    EXPECT_EQ(convs[5].out_channels, 16);
    EXPECT_EQ(convs[5].stride_h, 2);
    for (size_t k : {size_t{0}, size_t{2}, size_t{4}, size_t{6}, size_t{7}}) {
      EXPECT_EQ(convs[k].groups, 1) << convs[k].name;
    }
    ASSERT_EQ(affines.size(), 9u);
    for (size_t k = 0; k + 1 < affines.size(); ++k) {
      SCOPED_TRACE(affines[k].name);
      EXPECT_EQ(affines[k].activation, k < 7 ? Activation::kClip : Activation::kSigmoid);
      EXPECT_EQ(affines[k].scale, std::vector<float>(affines[k].scale.size(), 1.0f));
      EXPECT_EQ(affines[k].shift, std::vector<float>(affines[k].shift.size(), 0.0f));
      if (k < 7) {
        EXPECT_EQ(affines[k].clip_min, 0.0f);
        EXPECT_EQ(affines[k].clip_max, 6.0f);
      }
    }
    EXPECT_EQ(affines.back().activation, Activation::kNone);
    EXPECT_EQ(affines.back().scale, std::vector<float>(3, 2.0f));
    EXPECT_EQ(affines.back().shift, std::vector<float>(3, -1.0f));
  }
  EXPECT_GE(s_cases, 3) << "the suite has no separable cases";
}

}  // namespace
}  // namespace sfrt::exporter
