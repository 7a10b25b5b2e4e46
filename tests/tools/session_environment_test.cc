// The `sfrt` tool's mapping of SFRT_ISA, SFRT_WINOGRAD, SFRT_WINOGRAD_UPCONV, SFRT_FEWOUT,
// SFRT_CONCAT_IN_PLACE and SFRT_AMX_PAIRS onto SessionOptions, and of `sfrt bench --tuning`'s
// variants onto KernelTuning (tools/sfrt/session_environment.h); the runtime itself reads none
// of them.
#include "sfrt/session_environment.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <string>
#include <string_view>
#include <vector>

#include "common/scoped_env.h"
#include "sfrt/isa.h"
#include "sfrt/session.h"

namespace sfrt::tools {
namespace {

using testing::ScopedEnv;

TEST(SessionEnvironment, NoVariablesLeaveTheDefaults) {
  ScopedEnv a("SFRT_ISA", nullptr), b("SFRT_WINOGRAD", nullptr), c("SFRT_WINOGRAD_UPCONV", nullptr),
      d("SFRT_FEWOUT", nullptr), e("SFRT_CONCAT_IN_PLACE", nullptr), f("SFRT_AMX_PAIRS", nullptr);
  SessionOptions options;
  ASSERT_TRUE(ApplySessionEnvironment(options).ok());
  EXPECT_EQ(options.isa, Isa::kAuto);
  EXPECT_EQ(options.tuning.winograd_tile, KernelTuning{}.winograd_tile);
  EXPECT_TRUE(options.tuning.winograd_upconv);
  EXPECT_TRUE(options.tuning.few_out);
  EXPECT_TRUE(options.tuning.concat_in_place);
  EXPECT_TRUE(options.tuning.amx_pairs);
}

TEST(SessionEnvironment, SfrtIsaChoosesThePathWhenOptionsSayAutoAndAFlagWins) {
  ScopedEnv env("SFRT_ISA", "ref");
  SessionOptions automatic;
  ASSERT_TRUE(ApplySessionEnvironment(automatic).ok());
  EXPECT_EQ(automatic.isa, Isa::kRef);
  SessionOptions flagged;
  flagged.isa = BestIsa();
  ASSERT_TRUE(ApplySessionEnvironment(flagged).ok());
  EXPECT_EQ(flagged.isa, BestIsa());
}

TEST(SessionEnvironment, KernelSwitchesMapOntoTheTuningFields) {
  ScopedEnv a("SFRT_WINOGRAD", "f2"), b("SFRT_WINOGRAD_UPCONV", "off"), c("SFRT_FEWOUT", "off"),
      d("SFRT_CONCAT_IN_PLACE", "off"), e("SFRT_AMX_PAIRS", "off");
  SessionOptions options;
  ASSERT_TRUE(ApplySessionEnvironment(options).ok());
  EXPECT_EQ(options.tuning.winograd_tile, 2);
  EXPECT_FALSE(options.tuning.winograd_upconv);
  EXPECT_FALSE(options.tuning.few_out);
  EXPECT_FALSE(options.tuning.concat_in_place);
  EXPECT_FALSE(options.tuning.amx_pairs);
  ScopedEnv off("SFRT_WINOGRAD", "off");
  ASSERT_TRUE(ApplySessionEnvironment(options).ok());
  EXPECT_EQ(options.tuning.winograd_tile, 0);
}

TEST(SessionEnvironment, AnUnknownValueIsAnErrorNamingTheVariableAndTheAcceptedValues) {
  const struct {
    const char* name;
    const char* value;
    const char* accepted;
  } cases[] = {{"SFRT_ISA", "mmx", "auto, ref, avx2, avx512, avx512amx, neon"},
               {"SFRT_WINOGRAD", "f3", "auto, off, f2, f4"},
               {"SFRT_WINOGRAD_UPCONV", "no", "off, on"},
               {"SFRT_FEWOUT", "0", "off, on"},
               {"SFRT_CONCAT_IN_PLACE", "yes", "off, on"},
               {"SFRT_AMX_PAIRS", "1x4", "off, on"}};
  for (const auto& c : cases) {
    ScopedEnv env(c.name, c.value);
    SessionOptions options;
    const Status s = ApplySessionEnvironment(options);
    ASSERT_FALSE(s.ok()) << c.name;
    EXPECT_EQ(s.message(), std::string(c.name) + "='" + c.value + "' is not one of " + c.accepted);
  }
}

// sfrt bench --tuning: the same switches by their names, on top of whatever the tuning holds.
TEST(TuningVariant, DefaultChangesNothingAndSwitchesApplyInOrder) {
  KernelTuning tuning;
  tuning.few_out = false;  // as an SFRT_FEWOUT=off before it would leave it
  ASSERT_TRUE(ApplyTuningVariant("default", tuning).ok());
  EXPECT_FALSE(tuning.few_out);
  EXPECT_TRUE(tuning.amx_pairs);
  ASSERT_TRUE(ApplyTuningVariant("amx_pairs=off,winograd=f4,fewout=on,winograd=off", tuning).ok());
  EXPECT_FALSE(tuning.amx_pairs);
  EXPECT_TRUE(tuning.few_out);
  EXPECT_EQ(tuning.winograd_tile, 0);
  ASSERT_TRUE(ApplyTuningVariant("winograd_upconv=off,concat_in_place=off", tuning).ok());
  EXPECT_FALSE(tuning.winograd_upconv);
  EXPECT_FALSE(tuning.concat_in_place);
}

TEST(TuningVariant, ErrorsNameTheAssignmentAndWhatIsAccepted) {
  const std::string names = "winograd, winograd_upconv, fewout, concat_in_place, amx_pairs";
  const struct {
    const char* variant;
    std::string message;
  } cases[] = {
      {"fewout=maybe", "fewout='maybe' is not one of off, on"},
      {"amx_pairs=off,winograd=f3", "winograd='f3' is not one of auto, off, f2, f4"},
      {"speed=fast", "'speed' is not a tuning switch (names: " + names + ")"},
      {"fewout", "'fewout' is not NAME=VALUE (names: " + names + ")"},
      {"fewout=off,", "'' is not NAME=VALUE (names: " + names + ")"},
      {"", "a tuning variant is 'default' or NAME=VALUE[,NAME=VALUE...], not empty"},
  };
  for (const auto& c : cases) {
    KernelTuning tuning;
    const Status s = ApplyTuningVariant(c.variant, tuning);
    ASSERT_FALSE(s.ok()) << c.variant;
    EXPECT_EQ(s.message(), c.message) << c.variant;
  }
}

// One vocabulary: each switch's variable is SFRT_ and its name in upper case.
TEST(TuningVariant, EachSwitchsVariableIsItsNameInUpperCase) {
  std::string variables;
  for (const TuningSwitch& s : TuningSwitches()) variables += TuningVariable(s) + " ";
  EXPECT_EQ(variables,
            "SFRT_WINOGRAD SFRT_WINOGRAD_UPCONV SFRT_FEWOUT SFRT_CONCAT_IN_PLACE SFRT_AMX_PAIRS ");
}

// Each switch's declared default is KernelTuning's: its other values each change the tuning, and
// the default value brings it back to KernelTuning{}.
TEST(TuningVariant, EachSwitchsDefaultValueIsKernelTuningsDefault) {
  for (const TuningSwitch& s : TuningSwitches()) {
    for (std::string_view value : TuningValues(s)) {
      KernelTuning tuning;
      ASSERT_TRUE(s.apply(value, tuning)) << s.name << "=" << value;
      if (value == s.default_value) {
        EXPECT_TRUE(tuning == KernelTuning{}) << s.name << "=" << value;
        continue;
      }
      EXPECT_FALSE(tuning == KernelTuning{}) << s.name << "=" << value;
      ASSERT_TRUE(s.apply(s.default_value, tuning));
      EXPECT_TRUE(tuning == KernelTuning{}) << s.name << "=" << s.default_value;
    }
  }
}

// --tuning each: the default, then every other value of every switch, one at a time.
TEST(TuningVariant, EachIsTheDefaultAndEveryOtherValueOfEverySwitch) {
  const std::vector<std::string> expected = {
      "default",    "winograd=off",        "winograd=f2",  "winograd=f4", "winograd_upconv=off",
      "fewout=off", "concat_in_place=off", "amx_pairs=off"};
  EXPECT_EQ(EachTuningVariant(), expected);
  for (const std::string& variant : EachTuningVariant()) {
    KernelTuning tuning;
    EXPECT_TRUE(ApplyTuningVariant(variant, tuning).ok()) << variant;
  }
}

}  // namespace
}  // namespace sfrt::tools
