// Bf16 inference through the Session: every ISA against the reference forward pass
// (sfrt/reference.h), bit for bit where the session runs the reference bf16 kernel (the ISAs
// without bf16 kernels) and within float32 rounding of the sums elsewhere; and the bf16 model
// against the float32 model it was made from, within the accuracy bar (2e-2 of the
// largest output magnitude).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "common/bf16_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "common/session_compare.h"
#include "kernels/bf16_job.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"

namespace sfrt {
namespace {

std::vector<float> Reference(const Model& model, const std::vector<float>& input, int h, int w) {
  auto shape = InferOutputShape(model, h, w);
  EXPECT_TRUE(shape.ok()) << shape.message();
  std::vector<float> out(shape.ok() ? shape->elements() : 0, NAN);
  const Status s = RunReferenceForward(model, input, h, w, out);
  EXPECT_TRUE(s.ok()) << s.message();
  return out;
}

size_t FirstDifference(const std::vector<float>& a, const std::vector<float>& b) {
  for (size_t i = 0; i < a.size(); ++i) {
    if (std::memcmp(&a[i], &b[i], sizeof(float)) != 0) return i;
  }
  return a.size();
}

// The input scaled as the default model's preprocessing does (pixels / 255).
std::vector<float> Input(int h, int w, uint32_t seed) {
  std::vector<float> v = testing::RandomImage(h, w, 12, seed);
  for (float& x : v) x /= 255.0f;
  return v;
}

// A session's output on `isa` against the reference forward's: the same bits where the session
// runs ref::Conv2dBf16Rows (no bf16 kernels), as the reference forward does; elsewhere within
// 1e-2, since the sums run in another order and a value near a bf16 rounding boundary may round
// to its neighbour in one layer and carry the difference on.
void ExpectMatchesReference(Isa isa, const std::vector<float>& got,
                            const std::vector<float>& want) {
  ASSERT_EQ(got.size(), want.size());
  if (!Bf16KernelsAvailable(isa)) {
    const size_t at = FirstDifference(got, want);
    EXPECT_EQ(at, want.size()) << "element " << at << " is " << got[at] << ", reference "
                               << want[at];
  } else {
    EXPECT_LT(testing::RelativeMaxError(got, want), 1e-2);
  }
}

TEST(SessionBf16, EveryIsaMatchesTheReferenceForward) {
  auto model = testing::LoadOrDie(testing::Bf16Spec(exporter::SceneEdNetSpec(16)));
  ASSERT_NE(model, nullptr);
  ASSERT_TRUE(model->metadata().has_bf16);
  // 96x128 as the default model runs; 45x61 odd, so crops and odd padding occur.
  for (auto [h, w] : {std::pair{96, 128}, std::pair{45, 61}}) {
    const std::vector<float> input = Input(h, w, 7);
    const std::vector<float> want = Reference(*model, input, h, w);
    for (Isa isa : SupportedIsas()) {
      for (int threads : {1, 2}) {
        SCOPED_TRACE(std::string(IsaName(isa)) + " x" + std::to_string(threads) + " at " +
                     std::to_string(h) + "x" + std::to_string(w));
        const std::vector<float> got = testing::RunSession(model, isa, threads, input, h, w);
        ExpectMatchesReference(isa, got, want);
      }
    }
  }
}

TEST(SessionBf16, PublishedWidthsMatchTheReferenceOnTheBestIsa) {
  // The real channel counts (12..1024) at a small size, so every kernel tile is exercised.
  auto model = testing::LoadOrDie(testing::Bf16Spec(exporter::SceneEdNetSpec(1)));
  ASSERT_NE(model, nullptr);
  const int h = 33, w = 40;
  const std::vector<float> input = Input(h, w, 11);
  const std::vector<float> want = Reference(*model, input, h, w);
  const std::vector<float> got = testing::RunSession(model, BestIsa(), 2, input, h, w);
  EXPECT_LT(testing::RelativeMaxError(got, want), 1e-2) << IsaName(BestIsa());
}

TEST(SessionBf16, TheOutputLayerRunsOnItsIsasFewOutputKernelAndMatchesTheReference) {
  // 1/4 width: the output convolution reads 16 channels, enough for the few-output kernels;
  // 45x61 has quads of pixels inside the input and single pixels at the borders.
  auto model = testing::LoadOrDie(testing::Bf16Spec(exporter::SceneEdNetSpec(4)));
  ASSERT_NE(model, nullptr);
  const int h = 45, w = 61;
  const std::vector<float> input = Input(h, w, 13);
  const std::vector<float> want = Reference(*model, input, h, w);
  for (Isa isa : SupportedIsas()) {
    auto session = Session::Create(model, {h, w, isa});
    ASSERT_TRUE(session.ok()) << session.message();
    const IsaBf16Kernels* kernels = Bf16KernelsFor(isa);
    if (kernels != nullptr && kernels->few_out_name[0] != '\0') {
      EXPECT_STREQ((*session)->steps().back().kernel, kernels->few_out_name) << IsaName(isa);
    }
    for (int threads : {1, 2}) {
      SCOPED_TRACE(std::string(IsaName(isa)) + " x" + std::to_string(threads));
      ExpectMatchesReference(isa, testing::RunSession(model, isa, threads, input, h, w), want);
    }
  }
}

TEST(SessionBf16, StaysWithinTwoPercentOfTheFloat32Model) {
  // The bar for bf16: within 2e-2 of the float32 output's largest magnitude.
  for (int width_divisor : {16, 1}) {
    SCOPED_TRACE("1/" + std::to_string(width_divisor) + " width");
    auto fp32 = testing::LoadOrDie(exporter::SceneEdNetSpec(width_divisor));
    auto bf16 = testing::LoadOrDie(testing::Bf16Spec(exporter::SceneEdNetSpec(width_divisor)));
    ASSERT_NE(fp32, nullptr);
    ASSERT_NE(bf16, nullptr);
    const int h = width_divisor == 1 ? 33 : 96, w = width_divisor == 1 ? 40 : 128;
    const std::vector<float> input = Input(h, w, 5);
    const std::vector<float> want = testing::RunSession(fp32, BestIsa(), 2, input, h, w);
    const std::vector<float> got = testing::RunSession(bf16, BestIsa(), 2, input, h, w);
    const double error = testing::RelativeMaxError(got, want);
    EXPECT_LT(error, 2e-2);
    EXPECT_GT(error, 0.0) << "bf16 rounds: identical outputs mean the layers ran in float32";
    RecordProperty("relative_max_error_w" + std::to_string(width_divisor), std::to_string(error));
  }
}

TEST(SessionBf16, MixedPrecisionConvertsEachFloatTensorOnceAndMatchesTheReference) {
  // conv0 and the output float32, one float32 layer inside; then bf16 and int8 side by side.
  const std::vector<bool> bf16 = {false, true, true, true, false, true,
                                  true,  true, true, true, false};
  const std::vector<bool> int8 = {false, false, false, false, true, false,
                                  false, false, false, false, false};
  auto model = testing::LoadOrDie(
      testing::Int8Spec(testing::Bf16Spec(exporter::SceneEdNetSpec(16), bf16), int8));
  ASSERT_NE(model, nullptr);
  SessionOptions options;
  options.max_height = 64;
  options.max_width = 80;
  options.isa = Isa::kRef;
  auto session = Session::Create(model, options);
  ASSERT_TRUE(session.ok()) << session.message();
  int to_bf16 = 0, to_u8 = 0;
  for (const PlannedStep& step : (*session)->steps()) {
    if (step.quantize && step.precision == Precision::kBFloat16) ++to_bf16;
    if (step.quantize && step.precision == Precision::kInt8) ++to_u8;
  }
  EXPECT_EQ(to_bf16, 2) << "one after conv0, one after conv4";
  EXPECT_EQ(to_u8, 1) << "one after conv3";
  const std::vector<float> input = Input(64, 80, 5);
  const std::vector<float> want = Reference(*model, input, 64, 80);
  std::vector<float> got(want.size(), NAN);
  ASSERT_TRUE((*session)->Run(input, 64, 80, got).ok());
  EXPECT_EQ(FirstDifference(got, want), want.size()) << "the reference ISA is the reference";
  for (Isa isa : SupportedIsas()) {
    const std::vector<float> other = testing::RunSession(model, isa, 2, input, 64, 80);
    EXPECT_LT(testing::RelativeMaxError(other, want), 2e-2) << IsaName(isa);
  }
}

TEST(SessionBf16, StepsReportBf16PrecisionAndTensorsStayBf16BetweenBf16Layers) {
  auto model = testing::LoadOrDie(testing::Bf16Spec(exporter::SceneEdNetSpec(16)));
  ASSERT_NE(model, nullptr);
  auto session = Session::Create(model, {96, 128, BestIsa()});
  ASSERT_TRUE(session.ok()) << session.message();
  const auto steps = (*session)->steps();
  ASSERT_FALSE(steps.empty());
  EXPECT_TRUE(steps.front().quantize);
  EXPECT_EQ(steps.front().precision, Precision::kBFloat16);
  int bf16_steps = 0;
  for (const PlannedStep& step : steps) {
    if (step.precision == Precision::kBFloat16) ++bf16_steps;
    if (!step.quantize && step.precision == Precision::kBFloat16 &&
        Bf16KernelsAvailable(BestIsa())) {
      EXPECT_NE(std::string(step.kernel).find("bf16__"), std::string::npos) << step.kernel;
    }
  }
  EXPECT_EQ(bf16_steps, 12) << "11 convolutions and the input's conversion";
  // Every planned tensor is bf16: the converted input and conv0..conv9's outputs (the
  // upsamplings are fused); the output convolution writes float32 to the caller's buffer.
  ASSERT_EQ((*session)->plan().size(), 11u);
  for (const PlannedTensor& t : (*session)->plan()) {
    EXPECT_TRUE(t.is_bf16) << t.producer;
    EXPECT_FALSE(t.is_u8) << t.producer;
  }
}

}  // namespace
}  // namespace sfrt
