// The words profiles, the pipeline and the command share (sfrt/config/vocabulary.h): each is
// declared once with its names, which parse back, in the spelling profiles use.
#include "sfrt/config/vocabulary.h"

#include <gtest/gtest.h>

#include <string>

namespace sfrt::config {
namespace {

TEST(ConfigVocabulary, StageNamesAreTheProfilesKeysInStageOrder) {
  EXPECT_STREQ(StageName(Stage::kSource), "source");
  EXPECT_STREQ(StageName(Stage::kPreprocess), "preprocess");
  EXPECT_STREQ(StageName(Stage::kInfer), "infer");
  EXPECT_STREQ(StageName(Stage::kOutput), "output");
  EXPECT_EQ(static_cast<int>(kStageNames.size()), kStageCount);
  EXPECT_EQ(StageIndex(Stage::kOutput), kStageCount - 1);
}

TEST(ConfigVocabulary, FlowFormatsAndMissActionsParseBackAndNothingElseDoes) {
  for (FlowFormat f : {FlowFormat::kPfm, FlowFormat::kNpy}) {
    EXPECT_EQ(FlowFormatFromName(FlowFormatName(f)), f);
  }
  EXPECT_FALSE(FlowFormatFromName("none").has_value());
  EXPECT_FALSE(FlowFormatFromName("PFM").has_value());
  for (MissAction a : {MissAction::kDropNext, MissAction::kSmallerInput, MissAction::kCountOnly}) {
    EXPECT_EQ(MissActionFromName(MissActionName(a)), a);
  }
  EXPECT_STREQ(MissActionName(MissAction::kSmallerInput), "smaller-input");
  EXPECT_FALSE(MissActionFromName("drop").has_value());
  EXPECT_STREQ(LogLevelName(LogLevel::kWarn), "warn");
}

}  // namespace
}  // namespace sfrt::config
