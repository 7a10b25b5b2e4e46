// Full-width SceneEDNet (the published channel widths; 191.6 GMAC at 540x960) on every ISA this
// CPU runs against the reference path, at 540x960 and at an odd size, within issue 4's bound.
// (session_isa_test covers the same sizes at 1/16 width, plus threads and the fused plan.)
//
// At 540x960 the reference path alone takes about 30 s natively and far longer under qemu or
// sanitizers, so in those builds (SFRT_TEST_EMULATED / SFRT_TEST_SANITIZED) that case is
// compiled as DISABLED_ (GoogleTest and ctest list it as disabled, not passed) and is run by
// hand, e.g. for NEON:
//   qemu-aarch64 -L /usr/aarch64-linux-gnu build/aarch64/bin/session_isa_full_width_test
//     --gtest_also_run_disabled_tests --gtest_filter='*540x960*'   (one command line)
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "common/model_builders.h"
#include "common/session_compare.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/isa.h"
#include "sfrt/session.h"

#if SFRT_TEST_EMULATED || SFRT_TEST_SANITIZED
#define MAYBE_MatchesTheReferencePathAt540x960 DISABLED_MatchesTheReferencePathAt540x960
#else
#define MAYBE_MatchesTheReferencePathAt540x960 MatchesTheReferencePathAt540x960
#endif

namespace sfrt {
namespace {

// The acceptance bound of issue 4: max error at most 1e-4 of the reference's largest magnitude.
constexpr double kRelativeTolerance = 1e-4;

std::shared_ptr<const Model> FullWidthModel() {
  static const std::shared_ptr<const Model> model = testing::LoadOrDie(exporter::SceneEdNetSpec(1));
  return model;
}

// The reference path's output at each size, computed once for all ISAs (seeded input).
const std::vector<float>& ReferenceOutput(int height, int width, const std::vector<float>& input) {
  static std::map<std::pair<int, int>, std::vector<float>> cache;
  auto [it, inserted] = cache.try_emplace({height, width});
  if (inserted)
    it->second = testing::RunSession(FullWidthModel(), Isa::kRef, 2, input, height, width);
  return it->second;
}

class SessionIsaFullWidth : public ::testing::TestWithParam<Isa> {
 protected:
  void SetUp() override {
    if (!IsaSupported(GetParam())) {
      GTEST_SKIP() << "this CPU or build cannot run " << IsaName(GetParam())
                   << " (supported: " << SupportedIsaList() << ")";
    }
  }

  void ExpectMatchesReference(int height, int width) {
    ASSERT_NE(FullWidthModel(), nullptr);
    const auto input = testing::RandomImage(height, width, 12, 11);
    const auto& want = ReferenceOutput(height, width, input);
    ASSERT_FALSE(want.empty());
    const auto got = testing::RunSession(FullWidthModel(), GetParam(), 2, input, height, width);
    const double error = testing::RelativeMaxError(got, want);
    RecordProperty("relative_max_error", std::to_string(error));
    std::printf("%s at %dx%d: max error / max |reference| = %.3g\n", IsaName(GetParam()), height,
                width, error);
    EXPECT_LE(error, kRelativeTolerance);
  }
};

TEST_P(SessionIsaFullWidth, MatchesTheReferencePathAtAnOddSize) { ExpectMatchesReference(35, 61); }

TEST_P(SessionIsaFullWidth, MAYBE_MatchesTheReferencePathAt540x960) {
  ExpectMatchesReference(540, 960);
}

INSTANTIATE_TEST_SUITE_P(EveryIsa, SessionIsaFullWidth,
                         ::testing::Values(Isa::kAvx2, Isa::kAvx512, Isa::kNeon),
                         [](const ::testing::TestParamInfo<Isa>& param) {
                           return std::string(IsaName(param.param));
                         });

}  // namespace
}  // namespace sfrt
