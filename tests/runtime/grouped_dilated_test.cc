// Grouped, depthwise and dilated convolutions, dilated transposed convolutions and dilated
// pooling (schema 1.8). The reference kernels against their dense equivalents (a grouped weight
// spread block-diagonally over every input, a dilated kernel spread out with zero taps between):
// the same non-zero terms in the same order, so the outputs are equal. Dilated pooling against
// values worked out by hand; a depthwise-separable, dilated network on every ISA against the
// reference forward; how the writer stores the layers (so that older readers refuse them) and
// what the writer and loader refuse. (ONNX's own dilated MaxPool and ConvTranspose cases run in
// tools.export.onnx_operator_test_cases_match_their_expected_outputs.)
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "common/model_builders.h"
#include "common/session_compare.h"
#include "kernels/ref/conv2d_ref.h"
#include "kernels/ref/conv_transpose_ref.h"
#include "kernels/ref/pool_ref.h"
#include "sfrt/isa.h"
#include "sfrt/session.h"
#include "sfrt/shapes.h"
#include "sfrt_model_generated.h"

namespace sfrt {
namespace {

std::vector<float> Random(size_t n, uint32_t seed, float lo = -1.0f, float hi = 1.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(lo, hi);
  std::vector<float> v(n);
  for (float& x : v) x = dist(rng);
  return v;
}

// The undilated, ungrouped convolution that computes the same as `p`: kernel sides spread to the
// dilated extent with zero taps between, each group's weights placed at its own inputs and zero
// elsewhere (HWIO).
std::vector<float> DenseWeights(const ConvParams& p) {
  const int eh = DilatedExtent(p.kernel_h, p.dilation_h);
  const int ew = DilatedExtent(p.kernel_w, p.dilation_w);
  const int gi = p.in_channels / p.groups;
  const int go = p.out_channels / p.groups;
  std::vector<float> dense(static_cast<size_t>(eh) * ew * p.in_channels * p.out_channels, 0.0f);
  for (int ky = 0; ky < p.kernel_h; ++ky) {
    for (int kx = 0; kx < p.kernel_w; ++kx) {
      for (int ci = 0; ci < gi; ++ci) {
        for (int co = 0; co < p.out_channels; ++co) {
          const int global_ci = (co / go) * gi + ci;
          const size_t from =
              ((static_cast<size_t>(ky) * p.kernel_w + kx) * gi + ci) * p.out_channels + co;
          const size_t to =
              ((static_cast<size_t>(ky * p.dilation_h) * ew + kx * p.dilation_w) * p.in_channels +
               global_ci) *
                  p.out_channels +
              co;
          dense[to] = p.weights[from];
        }
      }
    }
  }
  return dense;
}

struct ConvCase {
  int cin, cout, k, stride, dh, dw, groups;
  Padding pads;
  int h, w;
};

TEST(Conv2dRef, GroupedAndDilatedEqualTheirDenseEquivalent) {
  const ConvCase cases[] = {
      {16, 16, 3, 1, 1, 1, 16, {1, 1, 1, 1}, 13, 17},  // depthwise
      {16, 32, 3, 2, 1, 1, 16, {1, 1, 0, 0}, 15, 12},  // depthwise, 2 outputs per input, stride 2
      {12, 8, 3, 1, 2, 2, 1, {2, 2, 2, 2}, 11, 19},    // dilated
      {12, 8, 3, 1, 3, 1, 4, {3, 1, 3, 1}, 14, 9},     // grouped and dilated, per axis
      {8, 6, 5, 2, 2, 3, 2, {0, 4, 2, 1}, 21, 23},     // 5x5, asymmetric pads
      {6, 6, 3, 1, 4, 4, 6, {0, 0, 0, 0}, 9, 9},       // depthwise, one output pixel per column
  };
  uint32_t seed = 11;
  for (const ConvCase& c : cases) {
    SCOPED_TRACE(std::to_string(c.cin) + "->" + std::to_string(c.cout) + " " + std::to_string(c.k) +
                 "x" + std::to_string(c.k) + "/s" + std::to_string(c.stride) + " dilation " +
                 std::to_string(c.dh) + "x" + std::to_string(c.dw) + " groups " +
                 std::to_string(c.groups));
    ConvParams p;
    p.in_channels = c.cin;
    p.out_channels = c.cout;
    p.kernel_h = p.kernel_w = c.k;
    p.stride_h = p.stride_w = c.stride;
    p.dilation_h = c.dh;
    p.dilation_w = c.dw;
    p.groups = c.groups;
    p.activation = Activation::kLeakyRelu;
    p.leaky_slope = 0.1f;
    const auto weights =
        Random(static_cast<size_t>(c.k) * c.k * (c.cin / c.groups) * c.cout, seed++);
    const auto bias = Random(static_cast<size_t>(c.cout), seed++);
    p.weights = weights.data();
    p.bias = bias.data();
    ConvParams dense = p;
    const auto dense_weights = DenseWeights(p);
    dense.kernel_h = DilatedExtent(c.k, c.dh);
    dense.kernel_w = DilatedExtent(c.k, c.dw);
    dense.dilation_h = dense.dilation_w = dense.groups = 1;
    dense.weights = dense_weights.data();

    Padding used;
    const int oh = ConvOutputSize(c.h, dense.kernel_h, c.stride, PaddingRule::kExplicit, c.pads.top,
                                  c.pads.bottom, &used.top, &used.bottom);
    const int ow = ConvOutputSize(c.w, dense.kernel_w, c.stride, PaddingRule::kExplicit,
                                  c.pads.left, c.pads.right, &used.left, &used.right);
    ASSERT_GT(oh, 0);
    ASSERT_GT(ow, 0);
    const auto in = Random(static_cast<size_t>(c.h) * c.w * c.cin, seed++);
    const ConstTensorView iv{in.data(), c.h, c.w, c.cin, static_cast<ptrdiff_t>(c.w) * c.cin};
    std::vector<float> want(static_cast<size_t>(oh) * ow * c.cout, NAN);
    std::vector<float> got(want.size(), NAN);
    ref::Conv2d(iv, dense, c.pads, DenseView(want.data(), oh, ow, c.cout));
    ref::Conv2d(iv, p, c.pads, DenseView(got.data(), oh, ow, c.cout));
    for (size_t k = 0; k < want.size(); ++k) ASSERT_EQ(got[k], want[k]) << "element " << k;
  }
}

TEST(ConvTranspose2dRef, DilatedEqualsItsZeroSpreadKernel) {
  ConvTransposeParams p;
  p.in_channels = 5;
  p.out_channels = 4;
  p.kernel_h = 3;
  p.kernel_w = 2;
  p.stride_h = 2;
  p.stride_w = 3;
  p.dilation_h = 2;
  p.dilation_w = 3;
  p.pads = {1, 2, 2, 0};
  p.output_padding_h = 1;
  const auto weights = Random(3 * 2 * 5 * 4, 3);
  const auto bias = Random(4, 4);
  p.weights = weights.data();
  p.bias = bias.data();
  ConvTransposeParams dense = p;
  dense.dilation_h = dense.dilation_w = 1;
  dense.kernel_h = DilatedExtent(3, 2);
  dense.kernel_w = DilatedExtent(2, 3);
  std::vector<float> spread(static_cast<size_t>(dense.kernel_h) * dense.kernel_w * 5 * 4, 0.0f);
  for (int ky = 0; ky < 3; ++ky) {
    for (int kx = 0; kx < 2; ++kx) {
      for (int k = 0; k < 20; ++k) {
        spread[(static_cast<size_t>(ky * 2) * dense.kernel_w + kx * 3) * 20 + k] =
            weights[(static_cast<size_t>(ky) * 2 + kx) * 20 + k];
      }
    }
  }
  dense.weights = spread.data();
  const int ih = 7, iw = 6;
  const auto in = Random(static_cast<size_t>(ih) * iw * 5, 5);
  const ConstTensorView iv{in.data(), ih, iw, 5, iw * 5};
  // (in - 1) * stride - pads + dilated extent + output padding.
  const int oh = (ih - 1) * 2 - 3 + 5 + 1;
  const int ow = (iw - 1) * 3 - 2 + 4;
  std::vector<float> want(static_cast<size_t>(oh) * ow * 4, NAN);
  std::vector<float> got(want.size(), NAN);
  ref::ConvTranspose2dRows(iv, dense, DenseView(want.data(), oh, ow, 4), 0, oh);
  ref::ConvTranspose2dRows(iv, p, DenseView(got.data(), oh, ow, 4), 0, oh);
  for (size_t k = 0; k < want.size(); ++k) ASSERT_EQ(got[k], want[k]) << "element " << k;
}

// A 4x4 single-channel input holding 0..15 row by row.
std::vector<float> Ramp4x4() {
  std::vector<float> v(16);
  for (int i = 0; i < 16; ++i) v[static_cast<size_t>(i)] = static_cast<float>(i);
  return v;
}

TEST(PoolRef, DilatedAverageCountsItsTapsAsWorkedOutByHand) {
  const auto in = Ramp4x4();
  const ConstTensorView iv{in.data(), 4, 4, 1, 4};
  PoolParams p;
  p.kind = PoolKind::kAverage;
  p.kernel_h = p.kernel_w = 2;
  p.dilation_h = p.dilation_w = 2;
  // Stride 1, no pads: window (y, x) averages (y, x), (y, x+2), (y+2, x), (y+2, x+2).
  std::vector<float> out(4, NAN);
  ref::PoolRows(iv, p, {}, DenseView(out.data(), 2, 2, 1), 0, 2);
  EXPECT_EQ(out, (std::vector<float>{5, 6, 9, 10}));
  // Stride 2, one pad at the top and left: window (0, 0) has taps at rows and columns -1 and 1,
  // so one tap (value 5) on the input and four counting the pads.
  p.stride_h = p.stride_w = 2;
  const Padding pads{1, 1, 0, 0};
  for (bool count_pads : {false, true}) {
    p.count_include_pad = count_pads;
    ref::PoolRows(iv, p, pads, DenseView(out.data(), 2, 2, 1), 0, 2);
    EXPECT_EQ(out[0], count_pads ? 5.0f / 4 : 5.0f) << "count_include_pad " << count_pads;
    // Window (0, 1): rows -1 and 1, columns 1 and 3: taps 5 and 7 on the input.
    EXPECT_EQ(out[1], count_pads ? 12.0f / 4 : 6.0f) << "count_include_pad " << count_pads;
  }
}

TEST(PoolRef, DilatedMaxSkipsTheRowsBetweenItsTaps) {
  auto in = Ramp4x4();
  in[5] = 100.0f;  // (1, 1): between the taps of window (0, 0) with dilation 2
  const ConstTensorView iv{in.data(), 4, 4, 1, 4};
  PoolParams p;
  p.kernel_h = p.kernel_w = 2;
  p.dilation_h = p.dilation_w = 2;
  std::vector<float> out(4, NAN);
  ref::PoolRows(iv, p, {}, DenseView(out.data(), 2, 2, 1), 0, 2);
  EXPECT_EQ(out, (std::vector<float>{10, 11, 14, 100}));
}

// conv 3x3 12->16 + relu, depthwise 3x3 dilation 2 + relu, pointwise 16->24, grouped (4) 3x3/2
// SAME, maxpool 2x2 dilation 2 (no pads), deconv 4x4/2 dilation 2 -> 3.
exporter::ModelSpec SeparableDilatedSpec() {
  using namespace sfrt::exporter;
  ModelSpec spec;
  spec.name = "separable-dilated";
  uint32_t seed = 21;
  auto conv = [&](const char* name, int in, int out, int k, int groups, int dilation) {
    ConvSpec c;
    c.name = name;
    c.in_channels = in;
    c.out_channels = out;
    c.kernel_h = c.kernel_w = k;
    c.groups = groups;
    c.dilation_h = c.dilation_w = dilation;
    const int pad = (DilatedExtent(k, dilation) - 1) / 2;
    c.pads = {pad, pad, pad, pad};
    c.activation = Activation::kRelu;
    const float range = 1.5f / std::sqrt(static_cast<float>(k * k * in / groups));
    c.weights_hwio =
        Random(static_cast<size_t>(k) * k * (in / groups) * out, seed++, -range, range);
    c.bias = Random(static_cast<size_t>(out), seed++, 0.0f, 0.1f);
    return c;
  };
  ConvSpec first = conv("conv0", 12, 16, 3, 1, 1);
  for (float& v : first.weights_hwio) v /= 128;  // the input is pixels in 0..255
  spec.layers.push_back(first);
  spec.layers.push_back(conv("depthwise", 16, 16, 3, 16, 2));
  spec.layers.push_back(conv("pointwise", 16, 24, 1, 1, 1));
  ConvSpec grouped = conv("grouped", 24, 8, 3, 4, 1);
  grouped.stride_h = grouped.stride_w = 2;
  grouped.padding_rule = PaddingRule::kSameUpper;
  spec.layers.push_back(grouped);
  PoolSpec pool;
  pool.name = "pool";
  pool.kernel_h = pool.kernel_w = 2;
  pool.stride_h = pool.stride_w = 1;
  pool.dilation_h = pool.dilation_w = 2;
  spec.layers.push_back(pool);
  ConvTransposeSpec up;
  up.name = "up";
  up.in_channels = 8;
  up.out_channels = 3;
  up.dilation_h = up.dilation_w = 2;
  up.pads = {2, 2, 2, 2};
  up.weights_hwio = Random(4 * 4 * 8 * 3, seed++, -0.2f, 0.2f);
  up.bias = Random(3, seed++);
  spec.layers.push_back(up);
  spec.output.channels = 3;
  return spec;
}

TEST(GroupedDilatedSession, ASeparableDilatedNetworkMatchesTheReferenceForwardOnEveryIsa) {
  auto model = testing::LoadOrDie(SeparableDilatedSpec());
  ASSERT_NE(model, nullptr);
  EXPECT_EQ(model->layers()[1].conv.groups, 16);
  EXPECT_EQ(model->layers()[1].conv.dilation_h, 2);
  EXPECT_EQ(model->layers()[4].pool.dilation_w, 2);
  EXPECT_EQ(model->layers()[5].deconv.dilation_h, 2);
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{67, 121}, {37, 53}, {5, 6}}, 12, 1e-5);
}

TEST(GroupedDilatedSession, RunsGroupedAndDilatedConvolutionsOnTheReferenceKernelOnly) {
  auto model = testing::LoadOrDie(SeparableDilatedSpec());
  ASSERT_NE(model, nullptr);
  for (Isa isa : SupportedIsas()) {
    SCOPED_TRACE(IsaName(isa));
    SessionOptions options;
    options.max_height = 32;
    options.max_width = 32;
    options.isa = isa;
    auto session = Session::Create(model, options);
    ASSERT_TRUE(session.ok()) << session.message();
    for (const PlannedStep& step : (*session)->steps()) {
      const LayerDesc& layer = model->layers()[static_cast<size_t>(step.last_layer)];
      if (layer.kind == LayerKind::kConv2D && !UndilatedUngrouped(layer.conv)) {
        EXPECT_STREQ(step.kernel, "ref::Conv2d") << layer.name;
      }
    }
  }
}

TEST(GroupedDilatedWriting, StoresLayersWithDilationOrGroupsUnderTheV2MembersOnly) {
  const auto bytes = testing::SerializeOrDie(SeparableDilatedSpec());
  ASSERT_FALSE(bytes.empty());
  const auto* file = schema::GetModel(bytes.data());
  ASSERT_NE(file->version(), nullptr);
  EXPECT_EQ(file->version()->minor(), kSchemaVersionMinor);
  const auto* layers = file->layers();
  ASSERT_EQ(layers->size(), 6u);
  // A reader before 1.8 does not know the V2 members, so it refuses these layers rather than
  // running them undilated.
  const schema::LayerOp want[] = {schema::LayerOp::Conv2D,   schema::LayerOp::Conv2DV2,
                                  schema::LayerOp::Conv2D,   schema::LayerOp::Conv2DV2,
                                  schema::LayerOp::Pool2DV2, schema::LayerOp::ConvTranspose2DV2};
  for (unsigned i = 0; i < layers->size(); ++i) {
    EXPECT_EQ(layers->Get(i)->op_type(), want[i]) << "layer " << i;
  }
}

TEST(GroupedDilatedWriting, RefusesGroupsThatDoNotDivideTheChannelsNamingTheLayer) {
  exporter::ModelSpec spec = SeparableDilatedSpec();
  std::get<exporter::ConvSpec>(spec.layers[3]).groups = 5;
  auto bytes = exporter::SerializeModel(spec);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("'grouped': groups is 5; must divide in_channels (24) and "
                                 "out_channels (8)"),
            std::string::npos)
      << bytes.message();
}

TEST(GroupedDilatedWriting, RefusesDilationInAnOlderSchemaNamingTheVersion) {
  exporter::SerializeOptions options;
  options.schema_minor = 7;
  auto bytes = exporter::SerializeModel(SeparableDilatedSpec(), options);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("'depthwise': dilation or groups other than 1 need schema 1.8; "
                                 "writing 1.7"),
            std::string::npos)
      << bytes.message();
}

TEST(GroupedDilatedLoading, RefusesADilationAboveTheLimitNamingTheLayer) {
  exporter::ModelSpec spec = SeparableDilatedSpec();
  auto& depthwise = std::get<exporter::ConvSpec>(spec.layers[1]);
  depthwise.dilation_h = 65;
  depthwise.pads = {};
  const auto bytes = testing::SerializeOrDie(spec);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy, {}, "d.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("layer 1 'depthwise': dilation is 65x2; each must be in 1..64"),
            std::string::npos)
      << model.message();
}

TEST(GroupedDilatedShapes, ADilatedWindowLargerThanThePaddedInputIsRefusedNamingTheLayer) {
  auto model = testing::LoadOrDie(SeparableDilatedSpec());
  ASSERT_NE(model, nullptr);
  // 2x2 -> ... -> grouped (stride 2): 1x1, which the pool's 3x3 dilated window does not fit.
  auto shape = InferOutputShape(*model, 2, 2);
  ASSERT_FALSE(shape.ok());
  EXPECT_NE(shape.message().find("'pool'"), std::string::npos) << shape.message();
}

}  // namespace
}  // namespace sfrt
