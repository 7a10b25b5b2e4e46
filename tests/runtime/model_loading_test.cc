// The loader's contract on bad files: every damaged or foreign file is rejected with one line
// that names the file and what is wrong, and nothing crashes (run under the asan preset too).
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include "common/bf16_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/model.h"
#include "sfrt_model_generated.h"

namespace sfrt {
namespace {

namespace fb = ::sfrt::schema;

std::vector<uint8_t> GoodModelBytes() {
  return testing::SerializeOrDie(exporter::SceneEdNetSpec(16));
}

// The tests here edit fields as a crafted file would, so the file checksum is made valid again
// (where the root table still verifies) and the checks behind it see the edit; the checksum
// itself is tested in tests/fuzz/model_fault_injection_test.cc.
Result<std::shared_ptr<const Model>> LoadBytes(std::vector<uint8_t> bytes) {
  (void)exporter::UpdateFileChecksum(bytes);
  return Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy, {}, "bad.sfrt");
}

// Expects a rejection whose single-line message names the file and contains `needle`.
void ExpectRejected(const Result<std::shared_ptr<const Model>>& result, const std::string& needle) {
  ASSERT_FALSE(result.ok());
  const std::string& m = result.message();
  EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  EXPECT_NE(m.find("bad.sfrt"), std::string::npos) << m;
  EXPECT_NE(m.find(needle), std::string::npos)
      << "message: " << m << "\nexpected to contain: " << needle;
}

fb::Conv2D* MutableConv(std::vector<uint8_t>& bytes, int layer) {
  auto* model = fb::GetMutableModel(bytes.data());
  auto* l = model->mutable_layers()->GetMutableObject(layer);
  return static_cast<fb::Conv2D*>(l->mutable_op());
}

TEST(ModelLoading, AcceptsAGoodModelAndReadsItsMetadata) {
  const auto bytes = GoodModelBytes();
  auto model = LoadBytes(bytes);
  ASSERT_TRUE(model.ok()) << model.message();
  const ModelMetadata& md = (*model)->metadata();
  EXPECT_EQ(md.schema_major, kSchemaVersionMajor);
  EXPECT_EQ(md.input.channels, 12);
  EXPECT_EQ(md.input.color_order, "BGR");
  EXPECT_EQ(md.input.image_order, (std::vector<std::string>{"left0", "right0", "left1", "right1"}));
  EXPECT_EQ(md.output.channels, 3);
  EXPECT_FLOAT_EQ(md.camera.focal_px, 1050.0f);
  EXPECT_FLOAT_EQ(md.camera.cx, 479.5f);
  EXPECT_EQ((*model)->layers().size(), 16u);
  EXPECT_EQ((*model)->layers()[0].conv.padding_rule, PaddingRule::kSameUpper);
  EXPECT_FLOAT_EQ((*model)->layers()[0].conv.leaky_slope, 0.3f);
}

// The few words titles and logs give a model's arithmetic (sfrt run --profile's plots, the ROS
// nodes' start line and /diagnostics), from what its layers run in.
TEST(ModelLoading, PrecisionSummaryNamesTheReducedPrecisionsAndFp16Weights) {
  ModelMetadata md;
  EXPECT_EQ(PrecisionSummary(md), "fp32");
  md.weight_type = WeightType::kFloat16;
  EXPECT_EQ(PrecisionSummary(md), "fp32 (fp16 weights)");
  const auto int8 = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16)));
  EXPECT_EQ(PrecisionSummary(int8->metadata()), "int8 (some layers fp32)");
  const auto bf16 = testing::LoadOrDie(testing::Bf16Spec(exporter::SceneEdNetSpec(16)));
  EXPECT_EQ(PrecisionSummary(bf16->metadata()), "bf16 (some layers fp32)");
  md.weight_type = WeightType::kFloat32;
  md.has_int8 = md.has_bf16 = true;
  EXPECT_EQ(PrecisionSummary(md), "int8+bf16+fp32");
}

TEST(ModelLoading, WeightsAreUsedInPlaceAt64ByteAlignedAddresses) {
  const auto bytes = GoodModelBytes();
  auto model = LoadBytes(bytes);
  ASSERT_TRUE(model.ok()) << model.message();
  for (const LayerDesc& l : (*model)->layers()) {
    if (l.kind != LayerKind::kConv2D) continue;
    EXPECT_EQ(reinterpret_cast<uintptr_t>(l.conv.weights) % 64, 0u) << l.name;
    EXPECT_EQ(reinterpret_cast<uintptr_t>(l.conv.bias) % 64, 0u) << l.name;
  }
}

TEST(ModelLoading, RejectsAnEmptyFile) {
  const auto path = std::filesystem::temp_directory_path() / "sfrt_empty_test.sfrt";
  { std::ofstream(path.string()).flush(); }
  auto model = Model::LoadFile(path.string());
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find(path.string()), std::string::npos) << model.message();
  EXPECT_NE(model.message().find("empty"), std::string::npos) << model.message();
  std::filesystem::remove(path);
}

TEST(ModelLoading, RejectsAMissingFileNamingIt) {
  auto model = Model::LoadFile("/nonexistent/dir/model.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("/nonexistent/dir/model.sfrt"), std::string::npos);
  EXPECT_NE(model.message().find("No such file"), std::string::npos) << model.message();
}

TEST(ModelLoading, LoadsFromAMemoryMappedFile) {
  const auto bytes = GoodModelBytes();
  const auto path = std::filesystem::temp_directory_path() / "sfrt_good_test.sfrt";
  std::ofstream(path.string(), std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  auto model = Model::LoadFile(path.string());
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_EQ((*model)->file_bytes(), bytes.size());
  std::filesystem::remove(path);
}

TEST(ModelLoading, RejectsATruncatedFile) {
  const auto bytes = GoodModelBytes();
  ExpectRejected(LoadBytes({bytes.begin(), bytes.begin() + 6}), "too small");
  ExpectRejected(LoadBytes({bytes.begin(), bytes.begin() + bytes.size() / 2}),
                 "truncated or damaged");
  ExpectRejected(LoadBytes({bytes.begin(), bytes.end() - 1}), "truncated or damaged");
}

TEST(ModelLoading, RejectsAWrongFileIdentifier) {
  auto bytes = GoodModelBytes();
  std::memcpy(bytes.data() + 4, "ONNX", 4);
  ExpectRejected(LoadBytes(bytes), "file identifier is 'ONNX', expected 'SFRT'");
}

TEST(ModelLoading, RejectsANewerMajorVersionNamingBothVersions) {
  auto bytes = GoodModelBytes();
  auto* version = fb::GetMutableModel(bytes.data())->mutable_version();
  version->mutate_major(static_cast<uint16_t>(kSchemaVersionMajor + 1));
  version->mutate_minor(3);
  const std::string newer = std::to_string(kSchemaVersionMajor + 1) + ".3";
  const std::string ours = std::to_string(kSchemaVersionMajor) + ".x";
  ExpectRejected(LoadBytes(bytes), "schema version " + newer);
  ExpectRejected(LoadBytes(bytes), "reads version " + ours);
}

TEST(ModelLoading, AcceptsANewerMinorVersion) {
  auto bytes = GoodModelBytes();
  fb::GetMutableModel(bytes.data())->mutable_version()->mutate_minor(kSchemaVersionMinor + 5);
  auto model = LoadBytes(bytes);
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_EQ((*model)->metadata().schema_minor, kSchemaVersionMinor + 5);
}

TEST(ModelLoading, RejectsAFlippedWeightByteThroughTheChecksum) {
  auto bytes = GoodModelBytes();
  auto* conv = MutableConv(bytes, 4);
  conv->mutable_weights()->mutable_data()->Mutate(17, conv->weights()->data()->Get(17) ^ 0x10);
  ExpectRejected(LoadBytes(bytes), "weights checksum mismatch");
}

TEST(ModelLoading, SkipsTheChecksumWhenAskedTo) {
  auto bytes = GoodModelBytes();
  auto* conv = MutableConv(bytes, 4);
  conv->mutable_weights()->mutable_data()->Mutate(17, conv->weights()->data()->Get(17) ^ 0x10);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy,
                                 LoadOptions{.verify_checksum = false});
  EXPECT_TRUE(model.ok()) << model.message();
}

TEST(ModelLoading, RejectsInconsistentChannelsNamingTheLayerAndField) {
  auto bytes = GoodModelBytes();
  MutableConv(bytes, 1)->mutate_in_channels(5);
  ExpectRejected(LoadBytes(bytes),
                 "layer 1 'conv1': in_channels is 5 but its input has 4 channels");
}

TEST(ModelLoading, RejectsAWeightShapeThatDisagreesWithTheLayer) {
  auto bytes = GoodModelBytes();
  MutableConv(bytes, 0)->mutable_weights()->mutable_shape()->Mutate(3, 7);
  ExpectRejected(LoadBytes(bytes),
                 "layer 0 'conv0': weights.shape is (3,3,12,7); expected (3,3,12,4)");
}

std::vector<uint8_t> Int8ModelBytes() {
  return testing::SerializeOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16)));
}

TEST(ModelLoading, AcceptsAnInt8ModelAndReadsItsQuantisation) {
  auto model = LoadBytes(Int8ModelBytes());
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_TRUE((*model)->metadata().has_int8);
  EXPECT_EQ((*model)->metadata().schema_minor, kSchemaVersionMinor);
  const ConvParams& c = (*model)->layers()[1].conv;
  EXPECT_EQ(c.precision, Precision::kInt8);
  EXPECT_EQ(c.weights, nullptr);
  ASSERT_NE(c.weights_q, nullptr);
  ASSERT_NE(c.weight_scales, nullptr);
  EXPECT_GT(c.weight_scales[0], 0.0f);
  EXPECT_EQ(c.input_quant, (QuantParams{4.0f / 255.0f, 77}));
  EXPECT_EQ((*model)->layers()[0].conv.input_quant, (QuantParams{1.0f, 0}));
}

TEST(ModelLoading, RejectsAPrecisionItDoesNotKnowNamingTheLayerAndValue) {
  auto bytes = Int8ModelBytes();
  MutableConv(bytes, 2)->mutate_precision(static_cast<fb::Precision>(9));
  ExpectRejected(LoadBytes(bytes), "layer 2 'conv2': precision is value 9, which this runtime");
}

TEST(ModelLoading, AcceptsABf16ModelWithItsFloat32Weights) {
  auto model = LoadBytes(testing::SerializeOrDie(testing::Bf16Spec(exporter::SceneEdNetSpec(16))));
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_TRUE((*model)->metadata().has_bf16);
  EXPECT_FALSE((*model)->metadata().has_int8);
  EXPECT_EQ((*model)->metadata().schema_minor, kSchemaVersionMinor);
  const ConvParams& c = (*model)->layers()[1].conv;
  EXPECT_EQ(c.precision, Precision::kBFloat16);
  EXPECT_NE(c.weights, nullptr) << "the float32 weights, rounded by the session";
  EXPECT_EQ(c.weights_q, nullptr);
  EXPECT_STREQ(PrecisionName(c.precision), "bf16");
}

TEST(ModelLoading, RejectsInt8WeightsOnABf16Layer) {
  // A bf16 layer rounds float weights: int8 ones (with their scales) are refused.
  auto bytes = Int8ModelBytes();
  MutableConv(bytes, 2)->mutate_precision(fb::Precision::BFloat16);
  ExpectRejected(LoadBytes(bytes), "layer 2 'conv2': weights.dtype is int8");
}

TEST(ModelLoading, RejectsInt8WeightsOnAFloat32Layer) {
  auto bytes = Int8ModelBytes();
  MutableConv(bytes, 2)->mutate_precision(fb::Precision::Float32);
  ExpectRejected(LoadBytes(bytes), "layer 2 'conv2': weights.dtype is int8");
}

TEST(ModelLoading, RejectsAnInt8LayerReadingOtherQuantisationThanItsProducerWrites) {
  auto bytes = Int8ModelBytes();
  MutableConv(bytes, 3)->mutable_input_quant()->mutate_zero_point(3);
  ExpectRejected(LoadBytes(bytes),
                 "layer 3 'conv3': input_quant (scale 0.015686, zero_point 3) differs from the "
                 "output_quant of layer 'conv2'");
}

TEST(ModelLoading, RejectsInt8ScalesThatAreNotPositiveOrFinite) {
  {
    auto bytes = Int8ModelBytes();
    MutableConv(bytes, 4)->mutable_weight_scales()->Mutate(5, -1.0f);
    ExpectRejected(LoadBytes(bytes), "layer 4 'conv4': weight_scales[5] is -1");
  }
  {
    auto bytes = Int8ModelBytes();
    MutableConv(bytes, 4)->mutable_output_quant()->mutate_scale(0.0f);
    ExpectRejected(LoadBytes(bytes), "layer 4 'conv4': output_quant.scale is 0");
  }
  {
    auto bytes = Int8ModelBytes();
    MutableConv(bytes, 0)->mutable_input_quant()->mutate_zero_point(256);
    ExpectRejected(LoadBytes(bytes), "layer 0 'conv0': input_quant.zero_point is 256");
  }
}

TEST(ModelLoading, RejectsOutOfRangeParameters) {
  {
    auto bytes = GoodModelBytes();
    MutableConv(bytes, 2)->mutate_stride_h(0);
    ExpectRejected(LoadBytes(bytes), "layer 2 'conv2': stride is 0x2");
  }
  {
    auto bytes = GoodModelBytes();
    MutableConv(bytes, 3)->mutable_pads()->mutate_top(-1);
    ExpectRejected(LoadBytes(bytes), "layer 3 'conv3': pads.top is -1");
  }
}

TEST(ModelLoading, RejectsABorrowedBufferThatIsNotAligned) {
  const auto bytes = GoodModelBytes();
  std::vector<uint8_t> shifted(bytes.size() + 64 + 1);
  uint8_t* base = shifted.data();
  base += (64 - reinterpret_cast<uintptr_t>(base) % 64) % 64 + 1;  // aligned + 1
  std::memcpy(base, bytes.data(), bytes.size());
  auto model = Model::LoadBuffer(base, bytes.size(), BufferOwnership::kBorrow, {}, "bad.sfrt");
  ExpectRejected(model, "64-byte aligned");
}

TEST(ModelLoading, SurvivesEveryTruncationAndRandomCorruption) {
  const auto bytes = GoodModelBytes();
  for (size_t len = 0; len < bytes.size(); len += 1 + bytes.size() / 300) {
    auto model = LoadBytes({bytes.begin(), bytes.begin() + static_cast<ptrdiff_t>(len)});
    EXPECT_FALSE(model.ok()) << "length " << len;
  }
  std::mt19937 rng(3);
  int rejected = 0;
  for (int trial = 0; trial < 300; ++trial) {
    auto damaged = bytes;
    for (int k = 0; k < 4; ++k)
      damaged[rng() % damaged.size()] ^= static_cast<uint8_t>(1 + rng() % 255);
    auto model = LoadBytes(damaged);  // must not crash; may be rejected
    if (!model.ok()) {
      ++rejected;
      EXPECT_EQ(model.message().find('\n'), std::string::npos);
    }
  }
  EXPECT_GT(rejected, 250);  // nearly every flip lands in weights and trips the checksum
}

}  // namespace
}  // namespace sfrt
