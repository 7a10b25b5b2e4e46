// The vocabularies declared as an enum with its names beside it (sfrt/vocabulary/names.h): every
// name parses back to its value, nothing else parses, and the lists say the names in order.
#include "sfrt/vocabulary/names.h"

#include <gtest/gtest.h>

#include <array>
#include <string>

#include "sfrt/vocabulary/stereo_input.h"

namespace sfrt::vocabulary {
namespace {

enum class Fruit { kApple, kPear, kPlum };
constexpr std::array<const char*, 3> kFruitNames = {"apple", "pear", "plum"};

TEST(VocabularyNames, EveryNameParsesBackToItsValueAndOthersAreRefused) {
  for (size_t i = 0; i < kFruitNames.size(); ++i) {
    const auto fruit = static_cast<Fruit>(i);
    EXPECT_EQ(FromName<Fruit>(kFruitNames, NameOf(kFruitNames, fruit)), fruit);
  }
  EXPECT_FALSE(FromName<Fruit>(kFruitNames, "Apple").has_value());
  EXPECT_FALSE(FromName<Fruit>(kFruitNames, "").has_value());
  EXPECT_STREQ(NameOf(kFruitNames, static_cast<Fruit>(3)), "?");
  static_assert(FromName<Fruit>(kFruitNames, "pear") == Fruit::kPear, "usable at compile time");
}

TEST(VocabularyNames, NameListJoinsTheNamesInTheirOrder) {
  EXPECT_EQ(NameList(kFruitNames), "apple, pear, plum");
  EXPECT_EQ(NameList(kFruitNames, "|"), "apple|pear|plum");
}

TEST(StereoInputWords, ShortAndLongSlotNamesParseInAnyCase) {
  for (int i = 0; i < kImageSlots; ++i) {
    const auto slot = static_cast<ImageSlot>(i);
    const auto at = static_cast<size_t>(i);
    EXPECT_EQ(ImageSlotFromAnyName(kImageSlotNames[at]), slot);
    EXPECT_EQ(ImageSlotFromAnyName(kImageSlotShortNames[at]), slot);
  }
  EXPECT_EQ(ImageSlotFromAnyName("LEFT0"), ImageSlot::kLeft0);
  EXPECT_EQ(ImageSlotFromAnyName("r1"), ImageSlot::kRight1);
  EXPECT_EQ(ImageSlotFromAnyName("Depth1"), ImageSlot::kDepth1);
  EXPECT_FALSE(ImageSlotFromAnyName("L2").has_value());
  EXPECT_FALSE(ImageSlotFromAnyName("left").has_value());
  EXPECT_FALSE(ImageSlotFromAnyName("").has_value());
}

}  // namespace
}  // namespace sfrt::vocabulary
