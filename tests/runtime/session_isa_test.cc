// Whole-model checks of the optimised paths: every ISA this CPU runs against the reference path
// on SceneEDNet at 1/16 width (540x960 and an odd size), thread counts, ISA selection and its
// errors, the fused upsample-conv plan.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>

#include "common/model_builders.h"
#include "common/scoped_env.h"
#include "common/session_compare.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/isa.h"
#include "sfrt/session.h"

namespace sfrt {
namespace {

// The acceptance bound of issue 4: max error at most 1e-4 of the reference's largest magnitude.
constexpr double kRelativeTolerance = 1e-4;

class SessionIsa : public ::testing::TestWithParam<Isa> {
 protected:
  void SetUp() override {
    if (!IsaSupported(GetParam())) {
      GTEST_SKIP() << "this CPU or build cannot run " << IsaName(GetParam())
                   << " (supported: " << SupportedIsaList() << ")";
    }
  }
};

TEST_P(SessionIsa, SceneEdNetW16MatchesTheReferencePathAt540x960) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  const auto input = testing::RandomImage(540, 960, 12, 3);
  const auto want = testing::RunSession(model, Isa::kRef, 2, input, 540, 960);
  const auto got = testing::RunSession(model, GetParam(), 1, input, 540, 960);
  EXPECT_LE(testing::RelativeMaxError(got, want), kRelativeTolerance);
}

TEST_P(SessionIsa, SceneEdNetW16MatchesTheReferencePathAtAnOddSize) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16, 7));
  const auto input = testing::RandomImage(67, 121, 12, 4);
  const auto want = testing::RunSession(model, Isa::kRef, 1, input, 67, 121);
  const auto got = testing::RunSession(model, GetParam(), 1, input, 67, 121);
  EXPECT_LE(testing::RelativeMaxError(got, want), kRelativeTolerance);
}

TEST_P(SessionIsa, TwoThreadsGiveBitIdenticalResultsToOne) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16, 5));
  const auto input = testing::RandomImage(97, 133, 12, 5);
  EXPECT_EQ(testing::RunSession(model, GetParam(), 2, input, 97, 133),
            testing::RunSession(model, GetParam(), 1, input, 97, 133));
}

TEST_P(SessionIsa, FusesEveryUpsampleIntoTheConvolutionThatReadsIt) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  SessionOptions options;
  options.isa = GetParam();
  auto session = Session::Create(model, options);
  ASSERT_TRUE(session.ok()) << session.message();
  int fused = 0, ref_kernels = 0;
  // avx512amx's float32 kernels are avx512's.
  const std::string isa = GetParam() == Isa::kAvx512Amx ? "avx512" : IsaName(GetParam());
  for (const PlannedStep& step : (*session)->steps()) {
    const std::string kernel = step.kernel;
    EXPECT_NE(kernel.find(isa), std::string::npos) << kernel;
    if (kernel.rfind("upconv2x_conv3x3_f32__", 0) == 0) ++fused;
    if (kernel.rfind("ref::", 0) == 0) ++ref_kernels;
  }
  EXPECT_EQ(fused, 4);
  EXPECT_EQ(ref_kernels, 0);
  // 16 layers in 11 steps: 7 convolutions, 4 fused upsample(+crop)+conv.
  EXPECT_EQ((*session)->steps().size(), 11u);
  // No upsampled tensor: 10 tensors (every step's output but the last).
  EXPECT_EQ((*session)->plan().size(), 10u);
  EXPECT_GT((*session)->packed_weight_bytes(), 0u);
}

INSTANTIATE_TEST_SUITE_P(EveryIsa, SessionIsa,
                         ::testing::Values(Isa::kAvx2, Isa::kAvx512, Isa::kNeon, Isa::kAvx512Amx),
                         [](const ::testing::TestParamInfo<Isa>& param) {
                           return std::string(IsaName(param.param));
                         });

TEST(SessionIsaSelection, FusedPlanHalvesTheFullWidthArena) {
  if (BestIsa() == Isa::kRef) GTEST_SKIP() << "no SIMD ISA on this CPU or build";
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(1));
  SessionOptions options;
  options.isa = BestIsa();
  auto session = Session::Create(model, options);
  ASSERT_TRUE(session.ok()) << session.message();
  // The two largest neighbours are now conv8's output (272x480x128) and conv9's (540x960x64),
  // plus, while conv9 runs on the Winograd phase path, its band scratch (at most 16 MiB:
  // runtime/src/winograd_run.h; at 540x960 five rows of 240 tiles x 9 x (128 + 256) floats).
  const size_t conv8 = 272ull * 480 * 128 * 4;
  const size_t conv9 = 540ull * 960 * 64 * 4;
  const size_t conv9_scratch = 5ull * 240 * 9 * (128 + 256) * 4;
  EXPECT_EQ((*session)->arena_bytes(), conv8 + conv9 + conv9_scratch);
}

TEST(SessionIsaSelection, RefIsAlwaysSupportedAndListedFirst) {
  EXPECT_TRUE(IsaSupported(Isa::kRef));
  EXPECT_FALSE(IsaSupported(Isa::kAuto));
  ASSERT_FALSE(SupportedIsas().empty());
  EXPECT_EQ(SupportedIsas().front(), Isa::kRef);
  EXPECT_EQ(SupportedIsas().back(), BestIsa());
}

TEST(SessionIsaSelection, ParsesEveryNameAndRejectsOthers) {
  for (Isa isa : {Isa::kAuto, Isa::kRef, Isa::kAvx2, Isa::kAvx512, Isa::kNeon, Isa::kAvx512Amx}) {
    Isa parsed = Isa::kRef;
    EXPECT_TRUE(ParseIsa(IsaName(isa), &parsed)) << IsaName(isa);
    EXPECT_EQ(parsed, isa);
  }
  Isa parsed = Isa::kRef;
  EXPECT_FALSE(ParseIsa("sse2", &parsed));
  EXPECT_FALSE(ParseIsa("AVX2", &parsed));
}

TEST(SessionIsaSelection, AnUnsupportedRequestFailsNamingTheIsaAndWhatIsSupported) {
  Isa missing = Isa::kAuto;
  for (Isa isa : {Isa::kNeon, Isa::kAvx512Amx, Isa::kAvx512, Isa::kAvx2}) {
    if (!IsaSupported(isa)) missing = isa;
  }
  if (missing == Isa::kAuto) GTEST_SKIP() << "this CPU runs every ISA this runtime knows";
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  SessionOptions options;
  options.isa = missing;
  auto session = Session::Create(model, options);
  ASSERT_FALSE(session.ok());
  EXPECT_NE(session.message().find(std::string("'") + IsaName(missing) + "'"), std::string::npos)
      << session.message();
  EXPECT_NE(session.message().find(SupportedIsaList()), std::string::npos) << session.message();
}

using testing::ScopedEnv;

// The library takes options and reads no environment: SFRT_ISA is the `sfrt` tool's to map
// (tests/tools/session_environment_test.cc), and kAuto means BestIsa() whatever it says.
TEST(SessionIsaSelection, AutoMeansTheBestIsaWhateverTheEnvironmentSays) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  for (const char* value : {"ref", "mmx"}) {
    ScopedEnv env("SFRT_ISA", value);
    auto session = Session::Create(model, {32, 32});
    ASSERT_TRUE(session.ok()) << session.message();
    EXPECT_EQ((*session)->isa(), BestIsa()) << "SFRT_ISA=" << value;
  }
}

TEST(SessionIsaSelection, RejectsAWinogradTileOtherThanZeroTwoOrFour) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  SessionOptions options;
  options.max_height = options.max_width = 32;
  options.tuning.winograd_tile = 3;
  auto session = Session::Create(model, options);
  ASSERT_FALSE(session.ok());
  EXPECT_NE(session.message().find("winograd_tile is 3"), std::string::npos) << session.message();
}

TEST(SessionIsaSelection, RejectsANegativeThreadCount) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  SessionOptions options;
  options.threads = -1;
  auto session = Session::Create(model, options);
  ASSERT_FALSE(session.ok());
  EXPECT_NE(session.message().find("threads"), std::string::npos) << session.message();
}

}  // namespace
}  // namespace sfrt
