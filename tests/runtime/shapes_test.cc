#include "sfrt/shapes.h"

#include <gtest/gtest.h>

#include "common/model_builders.h"
#include "sfrt/exporter/sceneednet_spec.h"

namespace sfrt {
namespace {

TEST(ConvOutputSize, SameUpperPadsTheExtraRowAtTheBottom) {
  int before = -1, after = -1;
  // The spec's example: stride 2 over 540 rows pads 0 on top and 1 at the bottom.
  EXPECT_EQ(ConvOutputSize(540, 3, 2, PaddingRule::kSameUpper, 9, 9, &before, &after), 270);
  EXPECT_EQ(before, 0);
  EXPECT_EQ(after, 1);
  // ... and over 135 rows, 1 and 1.
  EXPECT_EQ(ConvOutputSize(135, 3, 2, PaddingRule::kSameUpper, 9, 9, &before, &after), 68);
  EXPECT_EQ(before, 1);
  EXPECT_EQ(after, 1);
  EXPECT_EQ(ConvOutputSize(34, 3, 1, PaddingRule::kSameUpper, 9, 9, &before, &after), 34);
  EXPECT_EQ(before, 1);
  EXPECT_EQ(after, 1);
}

TEST(ConvOutputSize, ExplicitPadsAreUsedAsGiven) {
  int before = -1, after = -1;
  EXPECT_EQ(ConvOutputSize(540, 3, 2, PaddingRule::kExplicit, 1, 1, &before, &after), 270);
  EXPECT_EQ(before, 1);
  EXPECT_EQ(after, 1);
  EXPECT_EQ(ConvOutputSize(7, 3, 1, PaddingRule::kExplicit, 0, 0, &before, &after), 5);
  EXPECT_EQ(ConvOutputSize(2, 3, 1, PaddingRule::kExplicit, 0, 0, &before, &after), 0);
}

TEST(InferGeometry, FullWidthSceneEdNetCostsAbout191Point6GmacAt540x960) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(1));
  ASSERT_NE(model, nullptr);
  auto geometry = InferGeometry(*model, 540, 960);
  ASSERT_TRUE(geometry.ok()) << geometry.message();
  uint64_t macs = 0, params = 0;
  for (const auto& g : *geometry) {
    macs += g.macs;
    params += g.params;
  }
  // The spec's per-layer figures (G MAC), in layer order of the convolutions.
  const double expected_gmac[] = {0.90, 2.39, 2.41, 2.41, 9.62, 19.25,
                                  38.5, 38.5, 38.5, 38.2, 0.90};
  int conv = 0;
  for (size_t i = 0; i < geometry->size(); ++i) {
    if (model->layers()[i].kind != LayerKind::kConv2D) continue;
    EXPECT_NEAR((*geometry)[i].macs / 1e9, expected_gmac[conv], 0.03) << model->layers()[i].name;
    ++conv;
  }
  EXPECT_EQ(conv, 11);
  // Exact sums over the spec's table (out_h*out_w*out_c*9*in_c per conv; weights + biases).
  // The spec rounds them to "about 191.7 GMAC" (its per-layer list sums to that) and quotes
  // "about 21.3 M" parameters; the exact figures are 191.60 G and 21.98 M.
  EXPECT_EQ(macs, 191'602'851'840u);
  EXPECT_EQ(params, 21'983'555u);
  EXPECT_EQ(geometry->back().output, (TensorShape{540, 960, 3}));
}

TEST(InferGeometry, LayerShapesFollowTheSpecTableAt540x960) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  ASSERT_NE(model, nullptr);
  auto geometry = InferGeometry(*model, 540, 960);
  ASSERT_TRUE(geometry.ok()) << geometry.message();
  const std::vector<std::pair<int, int>> sizes = {{270, 480}, {135, 240}, {68, 120},  {34, 60},
                                                  {34, 60},   {34, 60},   {68, 120},  {68, 120},
                                                  {136, 240}, {136, 240}, {272, 480}, {272, 480},
                                                  {544, 960}, {540, 960}, {540, 960}, {540, 960}};
  ASSERT_EQ(geometry->size(), sizes.size());
  for (size_t i = 0; i < sizes.size(); ++i) {
    EXPECT_EQ((*geometry)[i].output.height, sizes[i].first) << model->layers()[i].name;
    EXPECT_EQ((*geometry)[i].output.width, sizes[i].second) << model->layers()[i].name;
  }
  // The crop removes the 4 excess rows from the top, no columns.
  const LayerGeometry& crop = (*geometry)[13];
  EXPECT_EQ(crop.crop.top, 4);
  EXPECT_EQ(crop.crop.left, 0);
  EXPECT_EQ(crop.crop.bottom, 0);
  EXPECT_EQ(crop.crop.right, 0);
  // conv0 over 540 rows: same-upper pads 0 on top, 1 at the bottom.
  EXPECT_EQ((*geometry)[0].pads.top, 0);
  EXPECT_EQ((*geometry)[0].pads.bottom, 1);
}

TEST(InferGeometry, OddSizesCropBackToTheInputSize) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  ASSERT_NE(model, nullptr);
  for (auto [h, w] : {std::pair{67, 121}, {1, 1}, {17, 33}, {35, 61}, {541, 959}}) {
    auto geometry = InferGeometry(*model, h, w);
    ASSERT_TRUE(geometry.ok()) << h << "x" << w << ": " << geometry.message();
    EXPECT_EQ(geometry->back().output, (TensorShape{h, w, 3})) << h << "x" << w;
    const LayerGeometry& crop = (*geometry)[13];
    EXPECT_EQ(crop.crop.top, 16 * ((h + 15) / 16) - h);
    EXPECT_EQ(crop.crop.left, 16 * ((w + 15) / 16) - w);
  }
}

TEST(InferGeometry, RejectsNonPositiveSizes) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  ASSERT_NE(model, nullptr);
  auto geometry = InferGeometry(*model, 0, 10);
  ASSERT_FALSE(geometry.ok());
  EXPECT_NE(geometry.message().find("0x10"), std::string::npos) << geometry.message();
}

TEST(InferGeometry, ExplicitCropThatRemovesEverythingNamesTheLayer) {
  exporter::ModelSpec spec = exporter::SceneEdNetSpec(16);
  std::get<exporter::CropSpec>(spec.layers[13]) = {
      "crop", exporter::CropRule::kExplicit, {40, 0, 0, 0}, true, true, {}};
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  auto geometry = InferGeometry(*model, 20, 20);  // 32 rows reach the crop
  ASSERT_FALSE(geometry.ok());
  EXPECT_NE(geometry.message().find("'crop'"), std::string::npos) << geometry.message();
}

}  // namespace
}  // namespace sfrt
