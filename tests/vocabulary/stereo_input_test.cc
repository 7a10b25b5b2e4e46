// The stereo-input words (vocabulary/stereo_input.h): names and parsers agree, and a model file
// written with an image order and colour order reads back spelled with the same words.
#include "sfrt/vocabulary/stereo_input.h"

#include <gtest/gtest.h>

#include "common/model_builders.h"
#include "sfrt/exporter/sceneednet_spec.h"

namespace sfrt::vocabulary {
namespace {

TEST(StereoInputWords, EveryNameParsesBackToItsWordAndOthersAreRefused) {
  for (int i = 0; i < kImageSlots; ++i) {
    const auto slot = static_cast<ImageSlot>(i);
    EXPECT_EQ(ImageSlotFromName(ImageSlotName(slot)), slot);
  }
  for (ColorOrder c : {ColorOrder::kBGR, ColorOrder::kRGB}) {
    EXPECT_EQ(ColorOrderFromName(ColorOrderName(c)), c);
  }
  EXPECT_FALSE(ImageSlotFromName("Left0"));
  EXPECT_FALSE(ImageSlotFromName("left2"));
  EXPECT_FALSE(ImageSlotFromName(""));
  EXPECT_FALSE(ColorOrderFromName("bgr"));
  EXPECT_EQ(ImageSlotName(static_cast<ImageSlot>(8)), "?");
  // Stereo images fill 3 channels each; of the RGB-D frames, colour 3 and depth 1.
  int stereo = 0, rgbd = 0;
  for (ImageSlot s : kDefaultImageOrder) stereo += IsRgbdSlot(s) ? 100 : SlotChannels(s);
  for (ImageSlot s : kDefaultRgbdOrder) rgbd += IsRgbdSlot(s) ? SlotChannels(s) : 100;
  EXPECT_EQ(stereo, 12);
  EXPECT_EQ(rgbd, 8);
  EXPECT_EQ(ImageSlotName(ImageSlot::kDepth1), "depth1");
}

TEST(StereoInputWords, ModelFileMetadataIsSpelledWithTheVocabulary) {
  exporter::ModelSpec spec = sfrt::exporter::SceneEdNetSpec(16);
  spec.input.image_order = {ImageSlot::kRight1, ImageSlot::kLeft0, ImageSlot::kRight0,
                            ImageSlot::kLeft1};
  spec.input.color_order = ColorOrder::kRGB;
  std::shared_ptr<const Model> model = sfrt::testing::LoadOrDie(spec);
  ASSERT_TRUE(model);
  const InputDesc& in = model->metadata().input;
  ASSERT_EQ(in.image_order.size(), 4u);
  for (size_t g = 0; g < 4; ++g) {
    EXPECT_EQ(in.image_order[g], ImageSlotName(spec.input.image_order[g])) << g;
  }
  EXPECT_EQ(in.color_order, ColorOrderName(ColorOrder::kRGB));
}

}  // namespace
}  // namespace sfrt::vocabulary
