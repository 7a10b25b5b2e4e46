// Int8 inference through the Session: every ISA against the reference forward pass
// (sfrt/reference.h), bit for bit wherever both compute in int8, on the SceneEDNet chain.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "common/session_compare.h"
#include "kernels/int8_job.h"
#include "sfrt/crc32c.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"

namespace sfrt {
namespace {

// CRC-32C of OutputIsTheSameBytesOnEveryMachine's output, as first computed on x86-64 (the
// reference and the AVX-512 VNNI kernels agreed); aarch64 must give it too.
constexpr uint32_t kExpectedInt8OutputCrc = 0x7efe1571;

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

TEST(SessionInt8, EveryIsaMatchesTheReferenceForwardBitForBit) {
  auto model = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16)));
  ASSERT_NE(model, nullptr);
  ASSERT_TRUE(model->metadata().has_int8);
  // 96x128 as the default model runs; 45x61 odd, so crops and odd padding occur.
  for (auto [h, w] : {std::pair{96, 128}, std::pair{45, 61}}) {
    const std::vector<float> input = testing::RandomImage(h, w, 12, 7);
    const std::vector<float> want = Reference(*model, input, h, w);
    for (Isa isa : SupportedIsas()) {
      for (int threads : {1, 2}) {
        const std::vector<float> got = testing::RunSession(model, isa, threads, input, h, w);
        ASSERT_EQ(got.size(), want.size());
        const size_t at = FirstDifference(got, want);
        EXPECT_EQ(at, want.size())
            << IsaName(isa) << " x" << threads << " at " << h << "x" << w << ": element " << at
            << " is " << got[at] << ", reference " << want[at];
      }
    }
  }
}

TEST(SessionInt8, PublishedWidthsMatchTheReferenceOnTheBestIsa) {
  // The real channel counts (12..1024) at a small size, so every kernel tile is exercised.
  auto model = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(1)));
  ASSERT_NE(model, nullptr);
  const int h = 33, w = 40;
  const std::vector<float> input = testing::RandomImage(h, w, 12, 11);
  const std::vector<float> want = Reference(*model, input, h, w);
  const std::vector<float> got = testing::RunSession(model, BestIsa(), 2, input, h, w);
  ASSERT_EQ(got.size(), want.size());
  EXPECT_EQ(FirstDifference(got, want), want.size()) << IsaName(BestIsa());
}

// The output layer of SceneEDNet at 1/`width_divisor` width, at 45x61 (blocks of pixels
// inside the input, single pixels or the tiles at the borders), on every ISA: where the ISA's
// table names a kernel for it (`name` of IsaInt8Kernels), the session plans that kernel, and the
// output is the reference's bytes, and the same with KernelTuning::few_out off (the tiles).
void ExpectOutputLayerKernel(int width_divisor, const char* IsaInt8Kernels::*name) {
  auto model = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(width_divisor)));
  ASSERT_NE(model, nullptr);
  const int h = 45, w = 61;
  const std::vector<float> input = testing::RandomImage(h, w, 12, 13);
  const std::vector<float> want = Reference(*model, input, h, w);
  for (Isa isa : SupportedIsas()) {
    const IsaInt8Kernels* kernels = Int8KernelsFor(isa);
    const bool named = kernels != nullptr && (kernels->*name)[0] != '\0';
    for (bool few_out : {true, false}) {
      SCOPED_TRACE(std::string(IsaName(isa)) + (few_out ? "" : ", few_out off"));
      SessionOptions options;
      options.max_height = h;
      options.max_width = w;
      options.isa = isa;
      options.tuning.few_out = few_out;
      auto session = Session::Create(model, options);
      ASSERT_TRUE(session.ok()) << session.message();
      const std::string kernel = (*session)->steps().back().kernel;
      if (named) {
        EXPECT_EQ(kernel == kernels->*name, few_out) << kernel;
      }
      for (int threads : {1, 2}) {
        options.threads = threads;
        const std::vector<float> got = testing::RunSession(model, options, input, h, w);
        ASSERT_EQ(got.size(), want.size());
        EXPECT_EQ(FirstDifference(got, want), want.size()) << " x" << threads;
      }
    }
  }
}

TEST(SessionInt8, TheOutputLayerRunsOnItsIsasFewOutputKernelAndMatchesTheReference) {
  // 1/4 width: the output convolution reads 16 channels, enough for the few-output kernels.
  ExpectOutputLayerKernel(4, &IsaInt8Kernels::few_out_name);
}

TEST(SessionInt8, TheNarrowOutputLayerRunsOnItsIsasNarrowKernelAndMatchesTheReference) {
  // 1/16 width, the default model's: the output convolution reads 4 channels.
  ExpectOutputLayerKernel(16, &IsaInt8Kernels::narrow_name);
}

TEST(SessionInt8, OutputIsTheSameBytesOnEveryMachine) {
  // Int8 arithmetic is exact up to its epilogue, which is defined op by op (int8_job.h), so the
  // output's checksum is a constant: the same on x86-64 (reference and VNNI) and on aarch64.
  auto model = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16)));
  ASSERT_NE(model, nullptr);
  const int h = 48, w = 64;
  const std::vector<float> input = testing::RandomImage(h, w, 12, 3);
  for (Isa isa : SupportedIsas()) {
    const std::vector<float> got = testing::RunSession(model, isa, 1, input, h, w);
    ASSERT_FALSE(got.empty());
    const uint32_t crc = Crc32c(0, got.data(), got.size() * sizeof(float));
    EXPECT_EQ(crc, kExpectedInt8OutputCrc) << IsaName(isa) << std::hex << " crc 0x" << crc;
  }
}

TEST(SessionInt8, MixedPrecisionQuantisesEachFloatTensorOnceAndMatchesTheReference) {
  // conv0 and output float32 (as `--precision auto` may keep them), one float32 layer inside.
  const std::vector<bool> int8 = {false, true, true, true, false, true,
                                  true,  true, true, true, false};
  auto model = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16), int8));
  ASSERT_NE(model, nullptr);
  SessionOptions options;
  options.max_height = 64;
  options.max_width = 80;
  options.isa = Isa::kRef;
  auto session = Session::Create(model, options);
  ASSERT_TRUE(session.ok()) << session.message();
  int quantise = 0;
  for (const PlannedStep& step : (*session)->steps()) {
    if (step.quantize) ++quantise;
  }
  EXPECT_EQ(quantise, 2) << "one after conv0, one after conv4";
  const std::vector<float> input = testing::RandomImage(64, 80, 12, 5);
  const std::vector<float> want = Reference(*model, input, 64, 80);
  std::vector<float> got(want.size(), NAN);
  ASSERT_TRUE((*session)->Run(input, 64, 80, got).ok());
  EXPECT_EQ(FirstDifference(got, want), want.size()) << "the reference ISA is the reference";
  // Other ISAs: their float32 layers round differently, so a value near a quantisation step
  // may land on the neighbouring one; the outputs stay close.
  for (Isa isa : SupportedIsas()) {
    const std::vector<float> other = testing::RunSession(model, isa, 2, input, 64, 80);
    EXPECT_LT(testing::RelativeMaxError(other, want), 2e-2) << IsaName(isa);
  }
}

TEST(SessionInt8, StepsReportInt8PrecisionAndTensorsStayUint8BetweenInt8Layers) {
  auto model = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16)));
  ASSERT_NE(model, nullptr);
  auto session = Session::Create(model, {96, 128, BestIsa()});
  ASSERT_TRUE(session.ok()) << session.message();
  const auto steps = (*session)->steps();
  ASSERT_FALSE(steps.empty());
  EXPECT_TRUE(steps.front().quantize);
  int int8_convs = 0;
  for (const PlannedStep& step : steps) {
    if (step.precision == Precision::kInt8) ++int8_convs;
  }
  EXPECT_EQ(int8_convs, 12) << "11 convolutions and the input's quantisation";
  // Every planned tensor is uint8: the quantised input and conv0..conv9's outputs (the
  // upsamplings are fused); the output convolution writes float32 to the caller's buffer.
  ASSERT_EQ((*session)->plan().size(), 11u);
  for (const PlannedTensor& t : (*session)->plan()) EXPECT_TRUE(t.is_u8) << t.producer;
}

}  // namespace
}  // namespace sfrt
