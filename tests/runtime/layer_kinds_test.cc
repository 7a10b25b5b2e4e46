// The table of layer kinds (runtime/src/ops/registry.cc): every kind has a whole unit under its
// own enumerator, every op the schema can store finds one, and each unit answers for its kind (its
// name, its descriptions, its padding text, its parameter count).
#include "sfrt/layer_kinds.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

#include "ops/layer_op.h"
#include "sfrt_model_generated.h"

namespace sfrt {
namespace {

TEST(LayerKinds, EveryKindHasAWholeUnitFiledUnderItsOwnEnumerator) {
  std::set<std::string> names;
  for (int k = 0; k < kLayerKindCount; ++k) {
    const auto kind = static_cast<LayerKind>(k);
    const ops::LayerOp& op = ops::OpOf(kind);
    SCOPED_TRACE(op.name);
    EXPECT_EQ(op.kind, kind);
    EXPECT_TRUE(names.insert(op.name).second) << "two kinds share the name " << op.name;
    EXPECT_NE(op.parse, nullptr);
    EXPECT_NE(op.geometry, nullptr);
    EXPECT_NE(op.parameters, nullptr);
    EXPECT_NE(op.rows, nullptr);
    EXPECT_NE(std::string(op.rows_kernel), "");
    EXPECT_NE(op.describe, nullptr);
    EXPECT_NE(op.padding, nullptr);
    EXPECT_NE(op.stored[0], schema::LayerOp::NONE);
    for (schema::LayerOp stored : op.stored) {
      if (stored != schema::LayerOp::NONE) {
        EXPECT_EQ(ops::OpStoredAs(stored), &op);
      }
    }
    EXPECT_STREQ(LayerKindName(kind), op.name);
  }
}

// A union member added to the schema without a unit, or a unit the table leaves out, fails here.
TEST(LayerKinds, EveryOpTheSchemaCanStoreFindsTheUnitOfTheSameName) {
  for (schema::LayerOp stored : schema::EnumValuesLayerOp()) {
    const std::string name = schema::EnumNameLayerOp(stored);
    SCOPED_TRACE(name);
    const ops::LayerOp* op = ops::OpStoredAs(stored);
    if (stored == schema::LayerOp::NONE) {
      EXPECT_EQ(op, nullptr);
      continue;
    }
    ASSERT_NE(op, nullptr);
    const bool v2 = name.size() > 2 && name.compare(name.size() - 2, 2, "V2") == 0;
    EXPECT_EQ(std::string(op->name), v2 ? name.substr(0, name.size() - 2) : name);
  }
}

TEST(LayerKinds, OnlyTheConvolutionUpsamplingAndCropRunInReducedPrecision) {
  for (int k = 0; k < kLayerKindCount; ++k) {
    const auto kind = static_cast<LayerKind>(k);
    const bool reduced =
        kind == LayerKind::kConv2D || kind == LayerKind::kUpsample || kind == LayerKind::kCrop;
    EXPECT_EQ(Float32OnlyKind(kind), !reduced) << LayerKindName(kind);
  }
}

LayerDesc Conv() {
  LayerDesc l;
  l.kind = LayerKind::kConv2D;
  l.conv.in_channels = 8;
  l.conv.out_channels = 8;
  l.conv.kernel_h = l.conv.kernel_w = 3;
  l.conv.stride_h = 2;
  l.conv.stride_w = 1;
  l.conv.dilation_h = l.conv.dilation_w = 2;
  l.conv.groups = 8;
  l.conv.padding_rule = PaddingRule::kSameUpper;
  l.conv.activation = Activation::kLeakyRelu;
  l.conv.leaky_slope = 0.1f;
  return l;
}

TEST(LayerKinds, AConvolutionDescribesItsWindowGroupsAndActivation) {
  const LayerDesc l = Conv();
  EXPECT_EQ(DescribeLayer(l, LayerText::kBrief), "conv 3x3/s2x1 dil2 dw");
  EXPECT_EQ(DescribeLayer(l, LayerText::kFull), "conv 3x3/s2x1 dilation 2 depthwise + leaky(0.1)");
  LayerGeometry g;
  g.pads = {1, 2, 3, 4};
  EXPECT_EQ(DescribePadding(l, g), "1,2,3,4 same-upper");
  EXPECT_EQ(LayerParameterCount(l), 3u * 3u * 1u * 8u + 8u);
}

TEST(LayerKinds, EveryOtherKindDescribesItselfAsInspectAndProfilesShowIt) {
  LayerDesc up;
  up.kind = LayerKind::kUpsample;
  up.upsample = {2, 3};
  EXPECT_EQ(DescribeLayer(up, LayerText::kBrief), "upsample 2x3");
  EXPECT_EQ(DescribeLayer(up, LayerText::kFull), "upsample 2x3 nearest");

  LayerDesc crop;
  crop.kind = LayerKind::kCrop;
  crop.crop.rule = CropRule::kToSecondInput;
  crop.crop.excess_rows_from_top = false;
  EXPECT_EQ(DescribeLayer(crop, LayerText::kBrief), "crop");
  EXPECT_EQ(DescribeLayer(crop, LayerText::kFull),
            "crop to 2nd input (rows from bottom, cols from left)");
  LayerGeometry cut;
  cut.crop = {0, 1, 2, 0};
  EXPECT_EQ(DescribePadding(crop, cut), "crop 0,1,2,0");

  LayerDesc cat;
  cat.kind = LayerKind::kConcat;
  cat.inputs = {0, 1, 2};
  EXPECT_EQ(DescribeLayer(cat, LayerText::kBrief), "concat 3");
  EXPECT_EQ(DescribeLayer(cat, LayerText::kFull), "concat channels");
  EXPECT_EQ(DescribePadding(cat, cut), "-");

  LayerDesc add;
  add.kind = LayerKind::kAdd;
  add.add.activation = Activation::kRelu;
  EXPECT_EQ(DescribeLayer(add, LayerText::kFull), "add + relu");

  LayerDesc deconv;
  deconv.kind = LayerKind::kConvTranspose2D;
  deconv.deconv.in_channels = 4;
  deconv.deconv.out_channels = 2;
  deconv.deconv.kernel_h = deconv.deconv.kernel_w = 2;
  deconv.deconv.stride_h = deconv.deconv.stride_w = 2;
  deconv.deconv.output_padding_h = 1;
  EXPECT_EQ(DescribeLayer(deconv, LayerText::kBrief), "deconv 2x2/s2");
  EXPECT_EQ(DescribeLayer(deconv, LayerText::kFull), "deconv 2x2/s2 outpad 1,0");
  EXPECT_EQ(LayerParameterCount(deconv), 2u * 2u * 4u * 2u + 2u);

  LayerDesc pool;
  pool.kind = LayerKind::kPool2D;
  pool.pool.kind = PoolKind::kArgMax;
  pool.pool.kernel_h = pool.pool.kernel_w = 2;
  pool.pool.stride_h = pool.pool.stride_w = 2;
  pool.pool.ceil_mode = true;
  pool.pool.indices_column_major = true;
  EXPECT_EQ(DescribeLayer(pool, LayerText::kBrief), "argmax-pool 2x2/s2");
  EXPECT_EQ(DescribeLayer(pool, LayerText::kFull), "argmax-pool 2x2/s2 ceil column-major");

  LayerDesc resize;
  resize.kind = LayerKind::kResize;
  resize.resize.mode = ResizeMode::kCubic;
  resize.resize.scale_num_h = 3;
  resize.resize.scale_den_h = 2;
  resize.resize.scale_num_w = 2;
  EXPECT_EQ(DescribeLayer(resize, LayerText::kBrief), "resize cubic");
  EXPECT_EQ(DescribeLayer(resize, LayerText::kFull), "resize cubic x3/2,2 half_pixel a=-0.75");

  LayerDesc affine;
  affine.kind = LayerKind::kChannelAffine;
  affine.affine.channels = 5;
  affine.affine.activation = Activation::kClip;
  affine.affine.clip_max = 6.0f;
  EXPECT_EQ(DescribeLayer(affine, LayerText::kBrief), "scale+shift");
  EXPECT_EQ(DescribeLayer(affine, LayerText::kFull), "scale+shift per channel + clip(0..6)");
  EXPECT_EQ(LayerParameterCount(affine), 10u);
}

TEST(LayerKinds, ThePhaseRuleSeesANearest2xUpsamplingThroughACrop) {
  std::vector<LayerDesc> layers(4);
  layers[0].kind = LayerKind::kUpsample;
  layers[0].upsample = {2, 2};
  layers[0].inputs = {kModelInput};
  layers[1].kind = LayerKind::kCrop;
  layers[1].inputs = {0};
  layers[2].kind = LayerKind::kUpsample;
  layers[2].upsample = {2, 1};
  layers[2].inputs = {kModelInput};
  layers[3].kind = LayerKind::kCrop;
  layers[3].inputs = {kModelInput};
  int crop = 7;
  EXPECT_EQ(ReadsNearest2xUpsampling(layers, 0, &crop), 0);
  EXPECT_EQ(crop, -1);
  EXPECT_EQ(ReadsNearest2xUpsampling(layers, 1, &crop), 0);
  EXPECT_EQ(crop, 1);
  EXPECT_EQ(ReadsNearest2xUpsampling(layers, 2, &crop), -1);  // 2x1 is not the phase rule's
  EXPECT_EQ(ReadsNearest2xUpsampling(layers, 3, &crop), -1);  // a crop of the model input
  EXPECT_EQ(crop, -1);
  EXPECT_EQ(ReadsNearest2xUpsampling(layers, kModelInput, &crop), -1);
}

}  // namespace
}  // namespace sfrt
