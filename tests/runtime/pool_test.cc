// Max and average pooling (schema 1.6): the reference kernel and the output size against an
// oracle written here from PyTorch's documented rules (window start y * stride - pad, the
// divisor counting pads up to the padded input's end, a ceil-mode window that would start past
// the input and its leading pad dropped), a pooling encoder on every ISA against the reference
// forward, and what the loader refuses. (PyTorch parity: the poolnet cases of
// tests/runtime/pytorch_parity_test.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "common/model_builders.h"
#include "common/session_compare.h"
#include "kernels/ref/pool_ref.h"
#include "sfrt/isa.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"
#include "sfrt/shapes.h"

namespace sfrt {
namespace {

struct PoolCase {
  PoolKind kind;
  int k, s;
  Padding pads;
  bool ceil, count_pads;
  int ih, iw, c;
};

// Output size along one axis: floor or ceil of (in + pads - k) / s, plus one; in ceil mode a
// last window starting at or past in + pad_before is dropped.
int OracleSize(int in, int k, int s, int before, int after, bool ceil) {
  const double span = static_cast<double>(in + before + after - k) / s;
  int out = static_cast<int>(ceil ? std::ceil(span) : std::floor(span)) + 1;
  if (ceil && (out - 1) * s >= in + before) --out;
  return out;
}

std::vector<double> Oracle(const std::vector<float>& in, const PoolCase& p, int oh, int ow) {
  std::vector<double> out(static_cast<size_t>(oh) * ow * p.c);
  for (int y = 0; y < oh; ++y) {
    for (int x = 0; x < ow; ++x) {
      int hs = y * p.s - p.pads.top, ws = x * p.s - p.pads.left;
      int he = std::min(hs + p.k, p.ih + p.pads.bottom),
          we = std::min(ws + p.k, p.iw + p.pads.right);
      const int padded = (he - hs) * (we - ws);
      hs = std::max(hs, 0);
      ws = std::max(ws, 0);
      he = std::min(he, p.ih);
      we = std::min(we, p.iw);
      for (int ch = 0; ch < p.c; ++ch) {
        double acc = p.kind == PoolKind::kMax ? -INFINITY : 0.0;
        for (int iy = hs; iy < he; ++iy) {
          for (int ix = ws; ix < we; ++ix) {
            const double v = in[(static_cast<size_t>(iy) * p.iw + ix) * p.c + ch];
            acc = p.kind == PoolKind::kMax ? std::max(acc, v) : acc + v;
          }
        }
        if (p.kind == PoolKind::kAverage) acc /= p.count_pads ? padded : (he - hs) * (we - ws);
        out[(static_cast<size_t>(y) * ow + x) * p.c + ch] = acc;
      }
    }
  }
  return out;
}

TEST(PoolRef, MatchesTheOracleInSizeAndValues) {
  const PoolCase cases[] = {
      {PoolKind::kMax, 3, 2, {1, 1, 1, 1}, false, false, 67, 121, 4},
      {PoolKind::kAverage, 2, 2, {0, 0, 0, 0}, true, false, 19, 31, 8},
      {PoolKind::kAverage, 3, 2, {1, 1, 1, 1}, true, true, 17, 16, 16},
      {PoolKind::kMax, 2, 1, {0, 0, 0, 0}, true, false, 9, 15, 3},
      {PoolKind::kAverage, 3, 3, {0, 1, 2, 0}, true, true, 10, 11, 5},
      {PoolKind::kAverage, 3, 3, {0, 1, 2, 0}, false, false, 10, 11, 5},
      {PoolKind::kMax, 5, 2, {2, 2, 2, 2}, true, false, 7, 6, 2},
      {PoolKind::kAverage, 2, 2, {0, 0, 0, 0}, true, true, 1, 3, 2},  // wider than the input
  };
  uint32_t seed = 1;
  for (const PoolCase& p : cases) {
    SCOPED_TRACE(std::string(p.kind == PoolKind::kMax ? "max " : "avg ") + std::to_string(p.k) +
                 "/" + std::to_string(p.s) + (p.ceil ? " ceil" : "") +
                 (p.count_pads ? " count-pads" : "") + " on " + std::to_string(p.ih) + "x" +
                 std::to_string(p.iw));
    PoolParams params;
    params.kind = p.kind;
    params.kernel_h = params.kernel_w = p.k;
    params.stride_h = params.stride_w = p.s;
    params.pads = p.pads;
    params.ceil_mode = p.ceil;
    params.count_include_pad = p.count_pads;
    Padding used;
    const int oh = PoolOutputSize(p.ih, p.k, p.s, PaddingRule::kExplicit, p.pads.top, p.pads.bottom,
                                  p.ceil, &used.top, &used.bottom);
    const int ow = PoolOutputSize(p.iw, p.k, p.s, PaddingRule::kExplicit, p.pads.left, p.pads.right,
                                  p.ceil, &used.left, &used.right);
    ASSERT_EQ(oh, OracleSize(p.ih, p.k, p.s, p.pads.top, p.pads.bottom, p.ceil));
    ASSERT_EQ(ow, OracleSize(p.iw, p.k, p.s, p.pads.left, p.pads.right, p.ceil));
    EXPECT_EQ(used, p.pads);
    std::mt19937 rng(seed++);
    std::uniform_real_distribution<float> dist(-2.0f, 1.0f);  // mostly negative: pads must lose
    std::vector<float> in(static_cast<size_t>(p.ih) * p.iw * p.c);
    for (float& v : in) v = dist(rng);
    const auto want = Oracle(in, p, oh, ow);
    std::vector<float> got(want.size(), NAN);
    const ConstTensorView iv{in.data(), p.ih, p.iw, p.c, static_cast<ptrdiff_t>(p.iw) * p.c};
    const TensorView ov = DenseView(got.data(), oh, ow, p.c);
    ref::PoolRows(iv, params, p.pads, ov, 0, oh / 2);
    ref::PoolRows(iv, params, p.pads, ov, oh / 2, oh);
    for (size_t k = 0; k < want.size(); ++k) {
      ASSERT_NEAR(got[k], want[k], 1e-6) << "element " << k;
    }
  }
}

// conv 3x3 -> maxpool 3x3/2 pad 1 -> conv 3x3 -> avgpool 2x2/2 ceil -> conv 1x1.
exporter::ModelSpec PoolingEncoderSpec() {
  using namespace sfrt::exporter;
  ModelSpec spec;
  spec.name = "pooling-encoder";
  std::mt19937 rng(5);
  auto conv = [&](const char* name, int in, int out, int k) {
    ConvSpec c;
    c.name = name;
    c.in_channels = in;
    c.out_channels = out;
    c.kernel_h = c.kernel_w = k;
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
  spec.layers.push_back(conv("conv0", 12, 8, 3));
  spec.layers.push_back(PoolSpec{"pool0",
                                 {},
                                 PoolKind::kMax,
                                 3,
                                 3,
                                 2,
                                 2,
                                 1,
                                 1,
                                 PaddingRule::kExplicit,
                                 {1, 1, 1, 1},
                                 false,
                                 false});
  spec.layers.push_back(conv("conv1", 8, 16, 3));
  spec.layers.push_back(PoolSpec{
      "pool1", {}, PoolKind::kAverage, 2, 2, 2, 2, 1, 1, PaddingRule::kExplicit, {}, true, false});
  ConvSpec out = conv("output", 16, 3, 1);
  out.activation = Activation::kNone;
  spec.layers.push_back(out);
  return spec;
}

// The argmax pool (schema 1.10, ONNX MaxPool's Indices output): per window and channel the
// first largest tap in row-major window order, as its index c * H * W + y * W + x in the input
// (c * H * W + x * H + y column-major). Worked out by hand on 2 channels of 2x3, with a tie.
TEST(PoolRef, ArgMaxGivesTheFirstLargestTapAsAnIndexOfTheInput) {
  // Channel 0 (rows): 1 5 5 / 2 0 7; channel 1 is its negation. NHWC.
  std::vector<float> in = {1, -1, 5, -5, 5, -5, 2, -2, 0, 0, 7, -7};
  PoolParams p;
  p.kind = PoolKind::kArgMax;
  p.kernel_h = p.kernel_w = 2;
  p.stride_h = p.stride_w = 1;
  const ConstTensorView view{in.data(), 2, 3, 2, 6};
  std::vector<float> out(4, NAN);
  ref::PoolRows(view, p, {}, DenseView(out.data(), 1, 2, 2), 0, 1);
  // Window 0: 5 at (0, 1); channel 1: 0 at (1, 1), plane offset 6. Window 1: 7 at (1, 2).
  EXPECT_EQ(out, (std::vector<float>{1, 10, 5, 10}));
  p.indices_column_major = true;
  ref::PoolRows(view, p, {}, DenseView(out.data(), 1, 2, 2), 0, 1);
  EXPECT_EQ(out, (std::vector<float>{2, 9, 5, 9}));
  // A tie: 7 becomes 5, and window 1's first 5 in row-major order is at (0, 1).
  in[10] = 5;
  p.indices_column_major = false;
  ref::PoolRows(view, p, {}, DenseView(out.data(), 1, 2, 2), 0, 1);
  EXPECT_EQ(out, (std::vector<float>{1, 10, 1, 10}));
  // Padding never wins, even over negative values: a 3x3 window padded by 1 on a 1x1 input.
  const std::vector<float> one = {-4.0f};
  p.kernel_h = p.kernel_w = 3;
  std::vector<float> single(1, NAN);
  ref::PoolRows(ConstTensorView{one.data(), 1, 1, 1, 1}, p, {1, 1, 1, 1},
                DenseView(single.data(), 1, 1, 1), 0, 1);
  EXPECT_EQ(single[0], 0.0f);
}

// Shape inference (so every session) refuses an argmax pool whose input has more than 2^24
// values, whose indices float32 cannot hold exactly; the writer refuses it below schema 1.10.
TEST(PoolShapes, AnArgMaxPoolOverMoreThan2To24ValuesIsRefusedAndNeedsSchema110) {
  exporter::ModelSpec spec;
  spec.name = "argmax";
  spec.input.name = "x";
  spec.input.channels = 64;
  spec.input.image_order.clear();
  exporter::SetOutputChannels(spec, 64);
  exporter::PoolSpec pool;
  pool.name = "where";
  pool.inputs = {"x"};
  pool.kind = PoolKind::kArgMax;
  spec.layers.push_back(pool);
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  EXPECT_TRUE(InferGeometry(*model, 512, 512).ok());  // exactly 2^24
  auto big = InferGeometry(*model, 512, 514);
  ASSERT_FALSE(big.ok());
  EXPECT_NE(big.message().find("'where'"), std::string::npos) << big.message();
  EXPECT_NE(big.message().find("exactly up to 2^24"), std::string::npos) << big.message();
  // The kind is new in schema 1.10: a 1.9 file cannot say it.
  exporter::SerializeOptions options;
  options.schema_minor = 9;
  auto bytes = exporter::SerializeModel(spec, options);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("Pool2D kind argmax needs schema 1.10; writing 1.9"),
            std::string::npos)
      << bytes.message();
}

TEST(PoolSession, PoolingEncoderMatchesTheReferenceForwardOnEveryIsa) {
  auto model = testing::LoadOrDie(PoolingEncoderSpec());
  ASSERT_NE(model, nullptr);
  EXPECT_TRUE(model->is_chain());
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{67, 121}, {37, 53}, {3, 2}}, 12, 1e-5,
                                                    9);
}

TEST(PoolLoading, RefusesAPadAsLargeAsTheWindowNamingTheLayer) {
  exporter::ModelSpec spec = PoolingEncoderSpec();
  std::get<exporter::PoolSpec>(spec.layers[1]).pads.bottom = 3;
  const auto bytes = testing::SerializeOrDie(spec);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy, {}, "p.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("layer 1 'pool0': pads.bottom is 3; must be in 0..2"),
            std::string::npos)
      << model.message();
}

// Without ceil mode; with it, a window wider than the padded input still gives one output, as in
// PyTorch (PoolRef's last case).
TEST(PoolShapes, AWindowLargerThanThePaddedInputIsRefusedNamingTheLayer) {
  exporter::ModelSpec spec = PoolingEncoderSpec();
  std::get<exporter::PoolSpec>(spec.layers[3]).ceil_mode = false;
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  // 1x1 -> pool0 1x1 -> pool1 (2x2, no pads) on a 1x1 input: the window does not fit.
  auto shape = InferOutputShape(*model, 1, 1);
  ASSERT_FALSE(shape.ok());
  EXPECT_NE(shape.message().find("'pool1': input 1x1 is smaller than its 2x2 window"),
            std::string::npos)
      << shape.message();
}

}  // namespace
}  // namespace sfrt
