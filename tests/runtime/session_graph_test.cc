// Models that are graphs, not chains (schema 1.5): named inputs, Concat, Add and crops to a
// second input's size. SceneEDNet-U (tests/common/unet_spec.h) on every ISA against the scalar
// reference forward, in float32, int8 and bf16, a hand-computed skip and residual, the arena's
// lifetimes, where fusions still apply, and what the writer and the loader refuse.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "common/bf16_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "common/session_compare.h"
#include "common/unet_spec.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/isa.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"

namespace sfrt {
namespace {

// The acceptance bound of issues 4 and 16: max error at most 1e-4 of the reference's largest
// magnitude.
constexpr double kRelativeTolerance = 1e-4;

int LayerIndex(const Model& model, const std::string& name) {
  const auto layers = model.layers();
  for (size_t i = 0; i < layers.size(); ++i) {
    if (layers[i].name == name) return static_cast<int>(i);
  }
  ADD_FAILURE() << "no layer '" << name << "'";
  return -1;
}

std::vector<float> ReferenceOutput(const Model& model, const std::vector<float>& input, int height,
                                   int width) {
  Result<TensorShape> shape = InferOutputShape(model, height, width);
  EXPECT_TRUE(shape.ok()) << shape.message();
  if (!shape.ok()) return {};
  std::vector<float> out(shape->elements(), NAN);
  const Status s = RunReferenceForward(model, input, height, width, out);
  EXPECT_TRUE(s.ok()) << s.message();
  return out;
}

TEST(GraphModel, LoadsAsAGraphWithItsInputsResolvedToLayerIndices) {
  auto model = testing::LoadOrDie(testing::SceneEdNetUSpec(16));
  ASSERT_NE(model, nullptr);
  EXPECT_FALSE(model->is_chain());
  const LayerDesc& cat1 = model->layers()[static_cast<size_t>(LayerIndex(*model, "cat1"))];
  EXPECT_EQ(cat1.kind, LayerKind::kConcat);
  EXPECT_EQ(cat1.inputs,
            (std::vector<int>{LayerIndex(*model, "crop1"), LayerIndex(*model, "conv2")}));
  EXPECT_EQ(model->layers()[0].inputs, std::vector<int>{kModelInput});
  // conv0 is read by conv1, by crop3 (for its size) and by cat3.
  EXPECT_EQ(model->consumer_count(0), 3);
  // A chain file still loads as one.
  auto chain = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  ASSERT_NE(chain, nullptr);
  EXPECT_TRUE(chain->is_chain());
}

// Every ISA and thread count against the scalar reference forward (which runs the graph layer
// by layer with tensors of its own), at two odd sizes whose skips need the crops.
TEST(GraphSession, SceneEdNetUMatchesTheReferenceForwardOnEveryIsaAtOddSizes) {
  for (bool residual : {false, true}) {
    auto model = testing::LoadOrDie(testing::SceneEdNetUSpec(16, 3, residual));
    ASSERT_NE(model, nullptr);
    for (auto [h, w] : {std::pair{67, 121}, {37, 53}}) {
      const auto input = testing::RandomImage(h, w, 12, 11);
      const auto want = ReferenceOutput(*model, input, h, w);
      for (Isa isa : SupportedIsas()) {
        for (int threads : {1, 2}) {
          SCOPED_TRACE(std::string(IsaName(isa)) + ", " + std::to_string(threads) + " threads, " +
                       std::to_string(h) + "x" + std::to_string(w) +
                       (residual ? ", residual" : ""));
          const auto got = testing::RunSession(model, isa, threads, input, h, w);
          EXPECT_LE(testing::RelativeMaxError(got, want), kRelativeTolerance);
        }
      }
    }
  }
}

TEST(GraphSession, SmallerInputsGiveTheSameResultAsASessionPlannedForThem) {
  auto model = testing::LoadOrDie(testing::SceneEdNetUSpec(16, 4, true));
  ASSERT_NE(model, nullptr);
  for (Isa isa : SupportedIsas()) {
    SCOPED_TRACE(IsaName(isa));
    SessionOptions options;
    options.max_height = 96;
    options.max_width = 128;
    options.isa = isa;
    auto big = Session::Create(model, options);
    ASSERT_TRUE(big.ok()) << big.message();
    const auto input = testing::RandomImage(67, 121, 12, 5);
    std::vector<float> out(67 * 121 * 3, NAN);
    ASSERT_TRUE((*big)->Run(input, 67, 121, out).ok());
    EXPECT_EQ(out, testing::RunSession(model, isa, 1, input, 67, 121));
  }
}

// out = [relu(3 x0 + 1), relu(3 x1 - 1), x0, x1]: a 1x1 convolution (2x + bias), an Add of its
// input (a residual) and a Concat of the input behind it (a skip), computed here by hand.
TEST(GraphSession, ConcatAndAddComputeWhatTheyNameOnEveryIsa) {
  exporter::ModelSpec spec;
  spec.name = "skip-and-residual";
  spec.input.name = "x";
  spec.input.channels = 2;
  spec.input.image_order.clear();
  exporter::SetOutputChannels(spec, 4);
  spec.output.channel_names = {"a", "b", "x0", "x1"};
  exporter::ConvSpec c;
  c.name = "twice";
  c.inputs = {"x"};
  c.in_channels = 2;
  c.out_channels = 2;
  c.kernel_h = c.kernel_w = 1;
  c.weights_hwio = {2, 0, 0, 2};
  c.bias = {1, -1};
  spec.layers.push_back(c);
  spec.layers.push_back(exporter::AddSpec{"sum", {"twice", "x"}, Activation::kRelu, 0.0f});
  spec.layers.push_back(exporter::ConcatSpec{"cat", {"sum", "x"}});
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  const int h = 5, w = 7;
  std::vector<float> input(h * w * 2);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> dist(-1.0f, 1.0f);
  for (float& v : input) v = dist(rng);
  std::vector<float> want;
  for (int p = 0; p < h * w; ++p) {
    const float x0 = input[2 * p], x1 = input[2 * p + 1];
    want.insert(want.end(), {std::max(3 * x0 + 1, 0.0f), std::max(3 * x1 - 1, 0.0f), x0, x1});
  }
  EXPECT_LE(testing::RelativeMaxError(ReferenceOutput(*model, input, h, w), want), 1e-6);
  for (Isa isa : SupportedIsas()) {
    SCOPED_TRACE(IsaName(isa));
    EXPECT_LE(testing::RelativeMaxError(testing::RunSession(model, isa, 2, input, h, w), want),
              1e-6);
  }
}

// A skip tensor stays in the arena until its last reader has run, and no two tensors alive at
// the same time share a byte.
TEST(GraphSession, SkipTensorsLiveUntilTheirLastReaderAndNeverOverlap) {
  auto model = testing::LoadOrDie(testing::SceneEdNetUSpec(16));
  ASSERT_NE(model, nullptr);
  for (Isa isa : SupportedIsas()) {
    SCOPED_TRACE(IsaName(isa));
    SessionOptions options;
    options.max_height = 67;
    options.max_width = 121;
    options.isa = isa;
    auto session = Session::Create(model, options);
    ASSERT_TRUE(session.ok()) << session.message();
    const auto plan = (*session)->plan();
    for (const std::string skip : {"conv0", "conv1", "conv2", "conv3"}) {
      const int producer = LayerIndex(*model, skip);
      const auto found = std::find_if(
          plan.begin(), plan.end(), [&](const PlannedTensor& t) { return t.producer == producer; });
      ASSERT_NE(found, plan.end()) << skip;
      // Its last reader is the Concat of the decoder level it feeds.
      const std::string cat = skip == "conv0"   ? "cat3"
                              : skip == "conv1" ? "cat2"
                              : skip == "conv2" ? "cat1"
                                                : "cat4";
      EXPECT_EQ(found->last_consumer, LayerIndex(*model, cat)) << skip;
    }
    for (size_t i = 0; i < plan.size(); ++i) {
      for (size_t j = i + 1; j < plan.size(); ++j) {
        const PlannedTensor& a = plan[i];
        const PlannedTensor& b = plan[j];
        const bool alive_together = a.producer <= b.last_consumer && b.producer <= a.last_consumer;
        const bool share = a.offset < b.offset + b.bytes && b.offset < a.offset + a.bytes;
        EXPECT_FALSE(alive_together && share) << "tensors " << i << " and " << j;
      }
    }
    EXPECT_GE((*session)->arena_bytes(), plan.back().offset + plan.back().bytes);
  }
}

// Issue 16's bound on SceneEDNet-U's memory: at 540x960, full width, the arena is at most the
// two largest tensors alive at the same time (skips aside) plus the skip tensors (conv0..conv3's
// outputs, alive until their decoder level), on every ISA's plan. The figures are printed.
TEST(GraphSession, SceneEdNetUArenaAt540x960IsAtMostTheTwoLargestLiveTensorsPlusTheSkips) {
  auto model = testing::LoadOrDie(testing::SceneEdNetUSpec(1));
  ASSERT_NE(model, nullptr);
  std::vector<int> skips;
  for (const char* name : {"conv0", "conv1", "conv2", "conv3"}) {
    skips.push_back(LayerIndex(*model, name));
  }
  for (Isa isa : SupportedIsas()) {
    SCOPED_TRACE(IsaName(isa));
    auto session = Session::Create(model, {540, 960, isa});
    ASSERT_TRUE(session.ok()) << session.message();
    const auto plan = (*session)->plan();
    size_t skip_bytes = 0;
    int skips_found = 0;
    for (const PlannedTensor& t : plan) {
      if (std::find(skips.begin(), skips.end(), t.producer) != skips.end()) {
        skip_bytes += t.bytes;
        ++skips_found;
      }
    }
    EXPECT_EQ(skips_found, 4);
    // The two largest other tensors alive together, over every layer's time.
    size_t pair_bytes = 0;
    for (int time = 0; time < static_cast<int>(model->layers().size()); ++time) {
      size_t first = 0, second = 0;
      for (const PlannedTensor& t : plan) {
        const bool skip = std::find(skips.begin(), skips.end(), t.producer) != skips.end();
        if (skip || t.producer > time || t.last_consumer < time) continue;
        if (t.bytes > first) {
          second = first;
          first = t.bytes;
        } else if (t.bytes > second) {
          second = t.bytes;
        }
      }
      pair_bytes = std::max(pair_bytes, first + second);
    }
    std::printf("  %-10s arena %zu bytes; two largest live %zu + skips %zu = %zu\n", IsaName(isa),
                (*session)->arena_bytes(), pair_bytes, skip_bytes, pair_bytes + skip_bytes);
    EXPECT_LE((*session)->arena_bytes(), pair_bytes + skip_bytes);
  }
}

// An upsampling whose output only the crop and convolution after it read still fuses into that
// convolution; one that a Concat reads (through its crop) is computed on its own.
TEST(GraphSession, UpsampleFusesOnlyWhereItsConvolutionIsItsOnlyReader) {
  auto model = testing::LoadOrDie(testing::SceneEdNetUSpec(16));
  ASSERT_NE(model, nullptr);
  for (Isa isa : SupportedIsas()) {
    if (isa == Isa::kRef) continue;  // the reference path fuses nothing
    SCOPED_TRACE(IsaName(isa));
    SessionOptions options;
    options.max_height = 67;
    options.max_width = 121;
    options.isa = isa;
    auto session = Session::Create(model, options);
    ASSERT_TRUE(session.ok()) << session.message();
    const auto steps = (*session)->steps();
    auto step_from = [&](const std::string& name) {
      const int layer = LayerIndex(*model, name);
      return std::find_if(steps.begin(), steps.end(),
                          [&](const PlannedStep& s) { return s.first_layer == layer; });
    };
    const auto up4 = step_from("up4");
    ASSERT_NE(up4, steps.end());
    EXPECT_EQ(up4->last_layer, LayerIndex(*model, "conv9")) << up4->kernel;
    for (const std::string up : {"up1", "up2", "up3"}) {
      const auto step = step_from(up);
      ASSERT_NE(step, steps.end()) << up;
      EXPECT_EQ(step->last_layer, step->first_layer) << up << ": " << step->kernel;
    }
  }
}

// An upsampled (and cropped) tensor that a Concat reads besides the convolution after it must
// exist: that convolution does not fuse the upsampling, and the result still matches.
TEST(GraphSession, UpsampleWithASecondReaderIsNotFused) {
  exporter::ModelSpec spec;
  std::mt19937 rng(5);
  std::normal_distribution<float> dist(0.0f, 0.2f);
  auto conv = [&](const std::string& name, const std::string& input, int in, int out, int k,
                  int stride) {
    exporter::ConvSpec c;
    c.name = name;
    c.inputs = {input};
    c.in_channels = in;
    c.out_channels = out;
    c.kernel_h = c.kernel_w = k;
    c.stride_h = c.stride_w = stride;
    c.padding_rule = PaddingRule::kSameUpper;
    c.weights_hwio.resize(static_cast<size_t>(k) * k * in * out);
    for (float& v : c.weights_hwio) v = dist(rng);
    c.bias.assign(static_cast<size_t>(out), 0.05f);
    spec.layers.push_back(c);
  };
  conv("down", spec.input.name, 12, 8, 3, 2);
  spec.layers.push_back(exporter::UpsampleSpec{"up", 2, 2, {"down"}});
  spec.layers.push_back(exporter::CropSpec{"crop", CropRule::kToInputSize, {}, true, true, {"up"}});
  conv("smooth", "crop", 8, 8, 3, 1);
  spec.layers.push_back(exporter::ConcatSpec{"cat", {"smooth", "crop"}});
  conv("output", "cat", 16, 3, 1, 1);
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  const auto input = testing::RandomImage(21, 31, 12, 6);
  const auto want = ReferenceOutput(*model, input, 21, 31);
  for (Isa isa : SupportedIsas()) {
    SCOPED_TRACE(IsaName(isa));
    EXPECT_LE(testing::RelativeMaxError(testing::RunSession(model, isa, 2, input, 21, 31), want),
              kRelativeTolerance);
    SessionOptions options;
    options.max_height = 21;
    options.max_width = 31;
    options.isa = isa;
    auto session = Session::Create(model, options);
    ASSERT_TRUE(session.ok()) << session.message();
    for (const PlannedStep& step : (*session)->steps()) {
      EXPECT_FALSE(step.first_layer <= LayerIndex(*model, "up") &&
                   step.last_layer >= LayerIndex(*model, "smooth"))
          << step.kernel << " fuses layers " << step.first_layer << ".." << step.last_layer;
    }
  }
}

TEST(GraphSession, OutputShapeOfAGraphFollowsItsLastLayer) {
  auto model = testing::LoadOrDie(testing::SceneEdNetUSpec(16));
  ASSERT_NE(model, nullptr);
  SessionOptions options;
  options.max_height = 96;
  options.max_width = 128;
  auto session = Session::Create(model, options);
  ASSERT_TRUE(session.ok()) << session.message();
  for (auto [h, w] : {std::pair{96, 128}, {37, 53}, {1, 1}}) {
    Result<TensorShape> shape = (*session)->OutputShape(h, w);
    ASSERT_TRUE(shape.ok()) << shape.message();
    EXPECT_EQ(*shape, (TensorShape{h, w, 3}));
  }
}

// Two tensors of different sizes cannot be concatenated: Session::Create (and shape inference)
// name the layer and both shapes.
TEST(GraphSession, ConcatOfDifferentSizesIsRefusedNamingTheLayer) {
  exporter::ModelSpec spec;
  exporter::SetOutputChannels(spec, 8);
  spec.output.channel_names.clear();
  for (int stride : {1, 2}) {
    exporter::ConvSpec c;
    c.name = "s" + std::to_string(stride);
    c.inputs = {spec.input.name};
    c.in_channels = 12;
    c.out_channels = 4;
    c.stride_h = c.stride_w = stride;
    c.padding_rule = PaddingRule::kSameUpper;
    c.weights_hwio.assign(9 * 12 * 4, 0.01f);
    c.bias.assign(4, 0.0f);
    spec.layers.push_back(c);
  }
  spec.layers.push_back(exporter::ConcatSpec{"mixed", {"s1", "s2"}});
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  SessionOptions options;
  options.max_height = 20;
  options.max_width = 30;
  auto session = Session::Create(model, options);
  ASSERT_FALSE(session.ok());
  EXPECT_NE(session.message().find("'mixed': concatenates a 20x30x4 tensor with a 10x15x4 one"),
            std::string::npos)
      << session.message();
}

TEST(GraphWriter, RefusesNamesThatAreNeitherTheInputNorAnEarlierLayer) {
  exporter::ModelSpec spec = testing::SceneEdNetUSpec(16);
  std::get<exporter::ConvSpec>(spec.layers[1]).inputs = {"conv9"};  // conv1 reading a later layer
  auto bytes = exporter::SerializeModel(spec);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("'conv1': reads 'conv9', which is neither the input nor an "
                                 "earlier layer"),
            std::string::npos)
      << bytes.message();
}

TEST(GraphWriter, RefusesAGraphInASchemaBefore15) {
  exporter::SerializeOptions options;
  options.schema_minor = 4;
  auto bytes = exporter::SerializeModel(testing::SceneEdNetUSpec(16), options);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("need schema 1.5; writing 1.4"), std::string::npos)
      << bytes.message();
}

TEST(GraphLoading, RefusesAnAddWithOneInputNamingTheLayer) {
  exporter::ModelSpec spec = testing::SceneEdNetUSpec(16, 1, true);
  for (auto& layer : spec.layers) {
    if (auto* add = std::get_if<exporter::AddSpec>(&layer)) add->inputs = {"conv5"};
  }
  // conv4 is still read by conv5, so the only fault is the Add's arity.
  const auto bytes = testing::SerializeOrDie(spec);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy, {}, "g.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("'res5': an Add reads 2 tensors; inputs names 1"),
            std::string::npos)
      << model.message();
}

TEST(GraphLoading, RefusesALayerWhoseOutputNoLayerReads) {
  exporter::ModelSpec spec = testing::SceneEdNetUSpec(16, 1, true);
  for (auto& layer : spec.layers) {
    if (auto* add = std::get_if<exporter::AddSpec>(&layer)) add->inputs = {"conv4", "conv4"};
  }
  const auto bytes = testing::SerializeOrDie(spec);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy, {}, "g.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("'conv5': no layer reads its output"), std::string::npos)
      << model.message();
}

// The range of every value SceneEDNet-U's convolutions and Concats give on `input` (float32), for
// Int8Spec's one activation quantisation.
QuantParams ActivationRange(const Model& model, const std::vector<float>& input, int h, int w) {
  float lo = 0.0f, hi = 0.0f;
  const LayerObserver observe = [&](int, const TensorShape&, std::span<const float> values) {
    for (float v : values) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  };
  Result<TensorShape> shape = InferOutputShape(model, h, w);
  EXPECT_TRUE(shape.ok()) << shape.message();
  std::vector<float> out(shape.ok() ? shape->elements() : 0);
  EXPECT_TRUE(RunReferenceForward(model, input, h, w, out, observe).ok());
  const float scale = (hi - lo) / 255.0f;
  return {scale, static_cast<int>(std::lround(-lo / scale))};
}

// SceneEDNet-U at 1/width_divisor width in int8 with one quantisation for every activation: the
// range float32 gives on a 67x121 random image (seed `seed`).
exporter::ModelSpec OneRangeInt8SceneEdNetU(int width_divisor, uint32_t seed) {
  const exporter::ModelSpec fp32_spec = testing::SceneEdNetUSpec(width_divisor);
  auto fp32 = testing::LoadOrDie(fp32_spec);
  EXPECT_NE(fp32, nullptr);
  if (fp32 == nullptr) return {};
  const QuantParams range =
      ActivationRange(*fp32, testing::RandomImage(67, 121, 12, seed), 67, 121);
  return testing::Int8Spec(fp32_spec, {}, range.scale, range.zero_point);
}

// What a session planned for `model` at h x w runs: the number of steps of each kernel kind.
struct PlanCounts {
  int quantize = 0, to_bf16 = 0, int8_convs = 0, bf16_convs = 0, fused_upsampling = 0;
  int u8_concats = 0, u8_upsamplings = 0, bf16_concats = 0, bf16_upsamplings = 0;
  int concats_in_place = 0;
  friend bool operator==(const PlanCounts&, const PlanCounts&) = default;
};
void PrintTo(const PlanCounts& c, std::ostream* os) {
  *os << "{quantize " << c.quantize << ", to_bf16 " << c.to_bf16 << ", int8_convs " << c.int8_convs
      << ", bf16_convs " << c.bf16_convs << ", fused_upsampling " << c.fused_upsampling
      << ", u8_concats " << c.u8_concats << ", u8_upsamplings " << c.u8_upsamplings
      << ", bf16_concats " << c.bf16_concats << ", bf16_upsamplings " << c.bf16_upsamplings
      << ", concats_in_place " << c.concats_in_place << "}";
}
PlanCounts CountPlan(const std::shared_ptr<const Model>& model, Isa isa, int h, int w) {
  SessionOptions options;
  options.max_height = h;
  options.max_width = w;
  options.isa = isa;
  auto session = Session::Create(model, options);
  EXPECT_TRUE(session.ok()) << session.message();
  PlanCounts counts;
  if (!session.ok()) return counts;
  const auto layers = model->layers();
  for (const PlannedStep& step : (*session)->steps()) {
    const bool conv = layers[static_cast<size_t>(step.last_layer)].kind == LayerKind::kConv2D;
    if (step.quantize) {
      (step.precision == Precision::kInt8 ? counts.quantize : counts.to_bf16) += 1;
    } else if (conv && step.precision == Precision::kInt8) {
      ++counts.int8_convs;
    } else if (conv && step.precision == Precision::kBFloat16) {
      ++counts.bf16_convs;
    }
    if (conv && !step.quantize &&
        layers[static_cast<size_t>(step.first_layer)].kind == LayerKind::kUpsample) {
      ++counts.fused_upsampling;
    }
    const std::string kernel = step.kernel;
    if (kernel == "ref::ConcatRowsU8") ++counts.u8_concats;
    if (kernel == "in place") ++counts.concats_in_place;
    if (kernel == "ref::UpsampleNearestU8") ++counts.u8_upsamplings;
    if (kernel == "ref::ConcatRowsBf16") ++counts.bf16_concats;
    if (kernel == "ref::UpsampleNearestBf16") ++counts.bf16_upsamplings;
  }
  return counts;
}

void ExpectPlanOnEveryIsa(const std::shared_ptr<const Model>& model, int h, int w,
                          const PlanCounts& want) {
  for (Isa isa : SupportedIsas()) {
    SCOPED_TRACE(IsaName(isa));
    EXPECT_EQ(CountPlan(model, isa, h, w), want);
  }
}

// With one quantisation for every tensor, every tensor of SceneEDNet-U but the model input and
// output stays uint8: the int8 convolutions write bytes, the upsamplings move bytes, only the
// model input is quantised, and every Concat is in place (its inputs' producers write their
// slices of its tensor; conv0..conv3 read theirs in place). The session on every ISA computes what
// the reference forward (which quantises the float32 tensor each convolution reads) computes, and
// the int8 model stays near the float32 one.
TEST(GraphSession, Int8SceneEdNetURunsOnEveryIsaAsTheReferenceForwardDoes) {
  auto fp32 = testing::LoadOrDie(testing::SceneEdNetUSpec(16));
  auto model = testing::LoadOrDie(OneRangeInt8SceneEdNetU(16, 11));
  ASSERT_NE(fp32, nullptr);
  ASSERT_NE(model, nullptr);
  EXPECT_TRUE(model->float32_between_layers());
  const int h = 67, w = 121;
  const auto input = testing::RandomImage(h, w, 12, 11);
  // 11 convolutions; conv9 fuses up4 and its crop; the other three upsamplings move uint8 (into
  // their Concats' tensors), and the four Concats cost nothing.
  ExpectPlanOnEveryIsa(model, h, w,
                       {.quantize = 1,
                        .int8_convs = 11,
                        .fused_upsampling = 1,
                        .u8_upsamplings = 3,
                        .concats_in_place = 4});
  // Float32 epilogues in SIMD registers may round the last bit otherwise than the scalar one.
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{67, 121}, {37, 53}}, 12, 1e-5, 11);
  // Against the float32 model: one activation range for every tensor, so a coarse bound (the
  // int8 chain's bar is 5e-2 with a range per tensor).
  const auto want = ReferenceOutput(*fp32, input, h, w);
  const auto got = ReferenceOutput(*model, input, h, w);
  EXPECT_LE(testing::RelativeMaxError(got, want), 0.15);
}

// A tensor stays uint8 only where everything that reads it, directly or through upsamplings,
// crops and Concats, reads one quantisation. Here conv6 reads cat1 with its own, so conv3's
// output (read by conv4 with the common quantisation and, through cat4, up1, crop1 and cat1, by
// conv6) is float32, and so are cat4, up1, crop1, cat1 and conv2's and conv5's outputs: the
// converting steps are the model input's, conv3's and conv4's inputs and cat1; cat2 and cat3 and
// their upsamplings stay uint8 (cat2 and cat3 in place). Every ISA still computes what the
// reference forward computes.
TEST(GraphSession, Int8GraphTensorsStayUint8OnlyWhereTheirReadersShareAQuantisation) {
  exporter::ModelSpec spec = OneRangeInt8SceneEdNetU(16, 11);
  for (exporter::LayerSpec& layer : spec.layers) {
    auto* c = std::get_if<exporter::ConvSpec>(&layer);
    if (c != nullptr && c->name == "conv6") {
      c->input_quant = {c->input_quant.scale * 1.25f, c->input_quant.zero_point / 2};
    }
  }
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  ExpectPlanOnEveryIsa(model, 67, 121,
                       {.quantize = 4,
                        .int8_convs = 11,
                        .fused_upsampling = 1,
                        .u8_upsamplings = 2,
                        .concats_in_place = 2});
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{67, 121}, {37, 53}}, 12, 1e-5, 11);
}

// The same for bf16: every tensor but the model input and output stays bf16 (no scale to agree
// on), every Concat in place, within the bf16 bar (2e-2) of the float32 model, and on every ISA
// within 1e-2 of the reference forward (sums in another order), the same where bf16 runs on the
// reference kernel.
TEST(GraphSession, Bf16SceneEdNetURunsOnEveryIsaNearTheReferenceForward) {
  const exporter::ModelSpec fp32_spec = testing::SceneEdNetUSpec(16, 2);
  auto fp32 = testing::LoadOrDie(fp32_spec);
  auto model = testing::LoadOrDie(testing::Bf16Spec(fp32_spec));
  ASSERT_NE(fp32, nullptr);
  ASSERT_NE(model, nullptr);
  ExpectPlanOnEveryIsa(model, 37, 53,
                       {.to_bf16 = 1,
                        .bf16_convs = 11,
                        .fused_upsampling = 1,
                        .bf16_upsamplings = 3,
                        .concats_in_place = 4});
  for (auto [h, w] : {std::pair{67, 121}, {37, 53}}) {
    const auto input = testing::RandomImage(h, w, 12, 5);
    const auto want = ReferenceOutput(*model, input, h, w);
    EXPECT_LE(testing::RelativeMaxError(want, ReferenceOutput(*fp32, input, h, w)), 2e-2);
    for (Isa isa : SupportedIsas()) {
      SCOPED_TRACE(std::string(IsaName(isa)) + ", " + std::to_string(h) + "x" + std::to_string(w));
      const auto got = testing::RunSession(model, isa, 2, input, h, w);
      if (Bf16KernelsAvailable(isa)) {
        EXPECT_LE(testing::RelativeMaxError(got, want), 1e-2);
      } else {
        EXPECT_EQ(got, want);
      }
    }
  }
}

// KernelTuning::concat_in_place off: every uint8 Concat copies, the arena holds each Concat's
// tensor only from the Concat on (so it is no larger), and the output is the same, bit for bit.
TEST(GraphSession, Int8ConcatsCopyWhenInPlaceIsOffWithTheSameOutput) {
  auto model = testing::LoadOrDie(OneRangeInt8SceneEdNetU(16, 11));
  ASSERT_NE(model, nullptr);
  const int h = 67, w = 121;
  const auto input = testing::RandomImage(h, w, 12, 11);
  auto output = [&](bool in_place, size_t* arena) {
    SessionOptions options;
    options.max_height = h;
    options.max_width = w;
    options.threads = 2;
    options.tuning.concat_in_place = in_place;
    auto session = Session::Create(model, options);
    EXPECT_TRUE(session.ok()) << session.message();
    std::vector<float> out(static_cast<size_t>(h) * w * 3);
    if (!session.ok()) return out;
    *arena = (*session)->arena_bytes();
    int copies = 0, in_place_steps = 0;
    for (const PlannedStep& step : (*session)->steps()) {
      copies += std::string(step.kernel) == "ref::ConcatRowsU8" ? 1 : 0;
      in_place_steps += std::string(step.kernel) == "in place" ? 1 : 0;
    }
    EXPECT_EQ(copies, in_place ? 0 : 4);
    EXPECT_EQ(in_place_steps, in_place ? 4 : 0);
    EXPECT_TRUE((*session)->Run(input, h, w, out).ok());
    return out;
  };
  size_t arena_in_place = 0, arena_copying = 0;
  EXPECT_EQ(output(true, &arena_in_place), output(false, &arena_copying));
  EXPECT_LE(arena_copying, arena_in_place);
}

// A Concat is in place only where every input's channel count is a multiple of 4 (kernels read
// input channels in groups of 4, which must not reach into a neighbouring slice). At 1/64 width
// conv0 and conv1 have 1 and 2 channels, so cat3 and cat2 copy their uint8 inputs, while cat4
// (conv5 and conv3: 16 and 8 channels) and cat1 (24 and 4) are in place. Every ISA computes what
// the reference forward computes, whichever way each Concat goes.
TEST(GraphSession, Int8ConcatsOfChannelCountsNotMultiplesOf4CopyTheirInputs) {
  auto model = testing::LoadOrDie(OneRangeInt8SceneEdNetU(64, 4));
  ASSERT_NE(model, nullptr);
  ExpectPlanOnEveryIsa(model, 67, 121,
                       {.quantize = 1,
                        .int8_convs = 11,
                        .fused_upsampling = 1,
                        .u8_concats = 2,
                        .u8_upsamplings = 3,
                        .concats_in_place = 2});
  testing::ExpectEveryIsaMatchesTheReferenceForward(model, {{67, 121}, {37, 53}}, 12, 1e-5, 4);
}

// An Add is float32 arithmetic: with the residual bottleneck (res5 = conv4 + conv5), conv4's and
// conv5's outputs, res5, and everything that res5 reaches through cat4, up1, crop1 and cat1 (and
// conv2's and conv3's outputs, which cat4 and cat1 also read) stay float32, so the model input
// and conv3's, conv4's, conv5's and conv6's inputs are converted; cat2, cat3 (in place) and
// their upsamplings stay bf16. Every ISA stays near the reference forward.
TEST(GraphSession, Bf16TensorsStayFloat32WhereAnAddReadsThem) {
  auto model = testing::LoadOrDie(testing::Bf16Spec(testing::SceneEdNetUSpec(16, 3, true)));
  ASSERT_NE(model, nullptr);
  ExpectPlanOnEveryIsa(model, 37, 53,
                       {.to_bf16 = 5,
                        .bf16_convs = 11,
                        .fused_upsampling = 1,
                        .bf16_upsamplings = 2,
                        .concats_in_place = 2});
  const auto input = testing::RandomImage(37, 53, 12, 8);
  const auto want = ReferenceOutput(*model, input, 37, 53);
  for (Isa isa : SupportedIsas()) {
    SCOPED_TRACE(IsaName(isa));
    const auto got = testing::RunSession(model, isa, 2, input, 37, 53);
    if (Bf16KernelsAvailable(isa)) {
      EXPECT_LE(testing::RelativeMaxError(got, want), 1e-2);
    } else {
      EXPECT_EQ(got, want);
    }
  }
}

}  // namespace
}  // namespace sfrt
