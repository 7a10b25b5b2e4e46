#include "sfrt/exporter/model_writer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "common/float_ops_spec.h"
#include "sfrt/crc32c.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/exporter/sfrt_importer.h"
#include "sfrt/model.h"
#include "sfrt/sha256.h"

namespace sfrt::exporter {
namespace {

namespace fs = std::filesystem;

TEST(Sha256, MatchesFips180Examples) {
  Sha256 empty;
  EXPECT_EQ(empty.FinishHex(), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  Sha256 abc;
  abc.Update("abc", 3);
  EXPECT_EQ(abc.FinishHex(), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  // Two blocks, fed in uneven pieces.
  const std::string msg = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
  Sha256 split;
  split.Update(msg.data(), 5);
  split.Update(msg.data() + 5, msg.size() - 5);
  EXPECT_EQ(split.FinishHex(), "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Sha256, OfFileMatchesTheSystemSha256sum) {
  const fs::path path = fs::temp_directory_path() / "sfrt_sha_test.bin";
  {
    std::ofstream out(path, std::ios::binary);
    for (int i = 0; i < 300000; ++i) out.put(static_cast<char>(i * 7 + (i >> 8)));
  }
  auto ours = Sha256OfFile(path.string());
  ASSERT_TRUE(ours.ok()) << ours.message();
  const std::string cmd = "sha256sum " + path.string() + " > " + path.string() + ".sum";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::string theirs;
  std::ifstream(path.string() + ".sum") >> theirs;
  EXPECT_EQ(*ours, theirs);
  fs::remove(path);
  fs::remove(path.string() + ".sum");
}

TEST(Sha256, OfMissingFileNamesIt) {
  auto r = Sha256OfFile("/nonexistent/x.onnx");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.message().find("/nonexistent/x.onnx"), std::string::npos);
}

TEST(Crc32c, MatchesTheStandardCheckValue) {
  // The CRC-32C catalogue's check value for "123456789".
  EXPECT_EQ(Crc32c(0, "123456789", 9), 0xE3069283u);
  // Incremental use equals one pass, across the 8-byte slicing boundary.
  const std::string s = "The quick brown fox jumps over the lazy dog";
  EXPECT_EQ(Crc32c(Crc32c(0, s.data(), 13), s.data() + 13, s.size() - 13),
            Crc32c(0, s.data(), s.size()));
}

TEST(ModelWriter, RoundTripsEveryFieldThroughTheRuntimeLoader) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  spec.input.color_order = ColorOrder::kRGB;
  spec.input.image_order = {ImageSlot::kLeft1, ImageSlot::kRight1, ImageSlot::kLeft0,
                            ImageSlot::kRight0};
  spec.input.scale = 1.0f / 255.0f;
  spec.input.mean = {0.1f, 0.2f, 0.3f};
  spec.input.std = {0.5f, 0.6f, 0.7f};
  spec.input.traced_height = 67;
  spec.input.traced_width = 121;
  spec.camera = {721.5f, 0.54f, 609.5f, 172.8f};
  spec.producer = {"9.9.9", "onnx", "m.onnx", "ab12"};
  auto bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  const ModelMetadata& md = (*model)->metadata();
  EXPECT_EQ(md.input.color_order, "RGB");
  EXPECT_EQ(md.input.image_order, (std::vector<std::string>{"left1", "right1", "left0", "right0"}));
  EXPECT_FLOAT_EQ(md.input.scale, 1.0f / 255.0f);
  EXPECT_FLOAT_EQ(md.input.mean[2], 0.3f);
  EXPECT_FLOAT_EQ(md.input.std[1], 0.6f);
  EXPECT_EQ(md.input.traced_height, 67);
  EXPECT_FLOAT_EQ(md.camera.baseline, 0.54f);
  EXPECT_EQ(md.exporter_version, "9.9.9");
  EXPECT_EQ(md.source_file, "m.onnx");
  EXPECT_EQ(md.output.channel_names, (std::vector<std::string>{"dX", "dY", "dZ"}));
  const auto& conv = std::get<ConvSpec>(spec.layers[4]);
  const ConvParams& loaded = (*model)->layers()[4].conv;
  for (size_t i = 0; i < conv.weights_hwio.size(); ++i)
    ASSERT_EQ(loaded.weights[i], conv.weights_hwio[i]);
  EXPECT_EQ((*model)->parameter_count(), 1u * 9 * 12 * 4 + 4 + 9 * 4 * 8 + 8 + 9 * 8 * 16 + 16 +
                                             9 * 16 * 32 + 32 + 9 * 32 * 64 + 64 + 9 * 64 * 64 +
                                             64 + 9 * 64 * 32 + 32 + 9 * 32 * 16 + 16 + 9 * 16 * 8 +
                                             8 + 9 * 8 * 4 + 4 + 9 * 4 * 3 + 3);
}

TEST(ModelWriter, Float16WeightsAreWidenedAtLoadWithinHalfPrecision) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  spec.weight_type = WeightType::kFloat16;
  auto bytes16 = SerializeModel(spec);
  spec.weight_type = WeightType::kFloat32;
  auto bytes32 = SerializeModel(spec);
  ASSERT_TRUE(bytes16.ok() && bytes32.ok());
  EXPECT_LT(bytes16->size(), bytes32->size() * 6 / 10);
  auto model = Model::LoadBuffer(bytes16->data(), bytes16->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_EQ((*model)->metadata().weight_type, WeightType::kFloat16);
  const auto& conv = std::get<ConvSpec>(spec.layers[2]);
  const ConvParams& loaded = (*model)->layers()[2].conv;
  for (size_t i = 0; i < conv.weights_hwio.size(); ++i) {
    // Round to nearest: relative error at most 2^-11 for normal halves.
    ASSERT_NEAR(loaded.weights[i], conv.weights_hwio[i],
                std::abs(conv.weights_hwio[i]) / 2048 + 1e-7f);
  }
}

TEST(ModelWriter, RejectsABrokenChainNamingTheLayer) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  std::get<ConvSpec>(spec.layers[2]).in_channels = 99;
  auto bytes = SerializeModel(spec);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("layer 2 'conv2'"), std::string::npos) << bytes.message();
}

TEST(ModelWriter, RejectsWrongWeightCounts) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  std::get<ConvSpec>(spec.layers[0]).weights_hwio.pop_back();
  auto bytes = SerializeModel(spec);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("'conv0'"), std::string::npos) << bytes.message();
}

TEST(ModelWriter, RejectsChannelNamesThatDoNotCountTheOutputChannels) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  spec.output.channel_names = {"dX", "dY"};
  auto bytes = SerializeModel(spec);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("output.channel_names has 2 names for an output of 3 channels"),
            std::string::npos)
      << bytes.message();
}

TEST(ModelWriter, APlainTensorInputWithAnyChannelCountRoundTrips) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  ConvSpec& first = std::get<ConvSpec>(spec.layers[0]);
  first.in_channels = 5;
  first.weights_hwio.resize(static_cast<size_t>(first.kernel_h) * first.kernel_w * 5 *
                            first.out_channels);
  spec.input.channels = 5;
  spec.input.image_order.clear();
  SetOutputChannels(spec, 3);
  auto bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_EQ((*model)->metadata().input.channels, 5);
  EXPECT_TRUE((*model)->metadata().input.image_order.empty());
  EXPECT_EQ((*model)->metadata().output.channel_names.size(), 3u);
}

// SceneEDNet at 1/16 width reading `channels` input channels (8 for two RGB-D frames) in `order`.
ModelSpec RgbdSpec(std::vector<ImageSlot> order, int channels = 8) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  ConvSpec& first = std::get<ConvSpec>(spec.layers[0]);
  first.in_channels = channels;
  first.weights_hwio.resize(static_cast<size_t>(first.kernel_h) * first.kernel_w * channels *
                            first.out_channels);
  spec.input.channels = channels;
  spec.input.image_order = std::move(order);
  return spec;
}

TEST(ModelWriter, TwoRgbdFramesRoundTripWithTheirDepthPreprocessingFromSchema111) {
  ModelSpec spec =
      RgbdSpec({ImageSlot::kColor1, ImageSlot::kDepth1, ImageSlot::kColor0, ImageSlot::kDepth0});
  spec.input.depth_mean = 2.5f;
  spec.input.depth_std = 1.25f;
  spec.input.depth_invalid = -3.0f;
  auto bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  const InputDesc& in = (*model)->metadata().input;
  EXPECT_EQ(in.image_order, (std::vector<std::string>{"color1", "depth1", "color0", "depth0"}));
  EXPECT_TRUE(in.is_rgbd());
  EXPECT_FALSE(in.is_tensor());
  EXPECT_EQ(in.depth_mean, 2.5f);
  EXPECT_EQ(in.depth_std, 1.25f);
  EXPECT_EQ(in.depth_invalid, -3.0f);
  // Re-exporting the file (sfrt export M.sfrt) keeps the frames and their preprocessing.
  const fs::path path = fs::temp_directory_path() / "sfrt_rgbd_roundtrip.sfrt";
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes->data()),
             static_cast<std::streamsize>(bytes->size()));
  auto again = ImportSfrt(path.string());
  fs::remove(path);
  ASSERT_TRUE(again.ok()) << again.message();
  EXPECT_EQ(again->input.image_order, spec.input.image_order);
  EXPECT_EQ(again->input.depth_mean, 2.5f);
  EXPECT_EQ(again->input.depth_std, 1.25f);
  EXPECT_EQ(again->input.depth_invalid, -3.0f);

  // A 1.10 reader would not know the slots: the writer refuses to label them 1.10.
  SerializeOptions v110;
  v110.schema_minor = 10;
  auto old = SerializeModel(spec, v110);
  ASSERT_FALSE(old.ok());
  EXPECT_NE(old.message().find("input: RGB-D frames (image slot color1) need schema 1.11; "
                               "writing 1.10"),
            std::string::npos)
      << old.message();
}

TEST(ModelWriter, LoaderRefusesAnRgbdOrderThatMixesKindsRepeatsOrMissesASlot) {
  const struct {
    std::vector<ImageSlot> order;
    int channels;
    const char* error;
  } cases[] = {
      {{ImageSlot::kColor0, ImageSlot::kDepth0, ImageSlot::kLeft1, ImageSlot::kDepth1},
       8,
       "input.image_order mixes stereo images and RGB-D frames (color0,depth0,left1,depth1)"},
      {{ImageSlot::kColor0, ImageSlot::kDepth0, ImageSlot::kColor0, ImageSlot::kDepth1},
       8,
       "input.image_order names color0 twice"},
      {{ImageSlot::kColor0, ImageSlot::kDepth0},
       4,
       "input.image_order names 2 of the RGB-D frames' slots (color0,depth0); must name color0, "
       "depth0, color1 and depth1"},
      {{ImageSlot::kColor0, ImageSlot::kDepth0, ImageSlot::kColor1, ImageSlot::kDepth1},
       12,
       "input.image_order names 4 images (8 channels) but input.channels is 12"},
  };
  for (const auto& c : cases) {
    const ModelSpec spec = RgbdSpec(c.order, c.channels);
    auto bytes = SerializeModel(spec);
    ASSERT_TRUE(bytes.ok()) << bytes.message();
    auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
    ASSERT_FALSE(model.ok()) << c.error;
    EXPECT_NE(model.message().find(c.error), std::string::npos) << model.message();
  }
  ModelSpec spec =
      RgbdSpec({ImageSlot::kColor0, ImageSlot::kDepth0, ImageSlot::kColor1, ImageSlot::kDepth1});
  spec.input.depth_std = 0.0f;
  auto bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("must be finite, depth_std non-zero"), std::string::npos)
      << model.message();
}

TEST(ModelWriter, UnitsAndTrainingStateRoundTripFromSchema12) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  spec.output.units = "metres";
  spec.training = TrainingState::kTrained;
  auto bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  const ModelMetadata& md = (*model)->metadata();
  EXPECT_EQ(md.schema_minor, kSchemaVersionMinor);
  EXPECT_EQ(md.output.units, "metres");
  EXPECT_TRUE(md.output.units_declared);
  EXPECT_EQ(md.training, TrainingState::kTrained);
}

TEST(ModelWriter, UnitsNotStatedAreWrittenAsUnknown) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  auto bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_EQ((*model)->metadata().output.units, "unknown");
  EXPECT_EQ((*model)->metadata().training, TrainingState::kUnknown);
}

TEST(ModelWriter, OlderLayoutsCarryNeitherUnitsNorTrainingState) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  spec.output.units = "metres";
  spec.training = TrainingState::kUntrained;
  for (int minor : {0, 1}) {
    SerializeOptions options;
    options.schema_minor = minor;
    auto bytes = SerializeModel(spec, options);
    ASSERT_TRUE(bytes.ok()) << bytes.message();
    auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
    ASSERT_TRUE(model.ok()) << model.message();
    const ModelMetadata& md = (*model)->metadata();
    EXPECT_EQ(md.schema_minor, minor);
    EXPECT_FALSE(md.output.units_declared);
    EXPECT_EQ(md.training, TrainingState::kUnknown);
  }
}

// SceneEDNet w16 with conv0..conv2 int8 (seeded int8 weights, chained quantisation) and a
// calibration record, as the quantiser would write it.
ModelSpec Int8Spec() {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> byte(-127, 127);
  std::uniform_real_distribution<float> scale(1e-3f, 1e-1f);
  QuantParams in{0.75f, 0};
  for (size_t i = 0; i < 3; ++i) {
    auto& c = std::get<ConvSpec>(spec.layers[i]);
    c.precision = Precision::kInt8;
    c.weights_q.resize(c.weights_hwio.size());
    for (int8_t& q : c.weights_q) q = static_cast<int8_t>(byte(rng));
    c.weights_hwio.clear();
    c.weight_scales.resize(static_cast<size_t>(c.out_channels));
    for (float& s : c.weight_scales) s = scale(rng);
    c.input_quant = in;
    c.output_quant = {scale(rng), static_cast<int>(i) * 40 + 3};
    in = c.output_quant;
  }
  CalibrationDesc cal;
  cal.method = "percentile:99.99";
  cal.data_sha256 = std::string(64, 'a');
  cal.frames = 7;
  cal.height = 96;
  cal.width = 128;
  cal.output_max_rel = 0.125f;
  cal.output_rms_rel = 0.0175f;
  cal.layers = {{"conv0", Precision::kInt8, 0.01f},
                {"conv1", Precision::kInt8, 0.02f},
                {"conv3", Precision::kFloat32, 0.015f}};
  spec.calibration = cal;
  return spec;
}

TEST(ModelWriter, Int8ConvolutionsRoundTripThroughTheLoaderByteForByte) {
  const ModelSpec spec = Int8Spec();
  auto bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();  // checksums and alignment verified
  const ModelMetadata& md = (*model)->metadata();
  EXPECT_EQ(md.schema_minor, kSchemaVersionMinor);
  EXPECT_TRUE(md.has_int8);
  EXPECT_EQ(md.weight_type, WeightType::kFloat32);
  for (size_t i = 0; i < spec.layers.size(); ++i) {
    const auto* c = std::get_if<ConvSpec>(&spec.layers[i]);
    if (c == nullptr) continue;
    const ConvParams& p = (*model)->layers()[i].conv;
    ASSERT_EQ(p.precision, c->precision) << c->name;
    ASSERT_EQ(std::memcmp(p.bias, c->bias.data(), c->bias.size() * sizeof(float)), 0);
    if (c->precision == Precision::kFloat32) {
      ASSERT_EQ(p.weights_q, nullptr);
      ASSERT_EQ(std::memcmp(p.weights, c->weights_hwio.data(), c->weights_hwio.size() * 4), 0);
      continue;
    }
    EXPECT_EQ(p.weights, nullptr);
    ASSERT_EQ(std::memcmp(p.weights_q, c->weights_q.data(), c->weights_q.size()), 0) << c->name;
    ASSERT_EQ(std::memcmp(p.weight_scales, c->weight_scales.data(),
                          c->weight_scales.size() * sizeof(float)),
              0);
    EXPECT_EQ(p.input_quant, c->input_quant) << c->name;
    EXPECT_EQ(p.output_quant, c->output_quant) << c->name;
    EXPECT_EQ(reinterpret_cast<uintptr_t>(p.weights_q) % 64, 0u) << c->name;
  }
  ASSERT_TRUE(md.calibration.has_value());
  const CalibrationDesc& cal = *md.calibration;
  EXPECT_EQ(cal.method, "percentile:99.99");
  EXPECT_EQ(cal.data_sha256, std::string(64, 'a'));
  EXPECT_EQ(cal.frames, 7);
  EXPECT_EQ(cal.height, 96);
  EXPECT_EQ(cal.width, 128);
  EXPECT_EQ(cal.output_max_rel, 0.125f);
  EXPECT_EQ(cal.output_rms_rel, 0.0175f);
  ASSERT_EQ(cal.layers.size(), 3u);
  EXPECT_EQ(cal.layers[2].layer, "conv3");
  EXPECT_EQ(cal.layers[2].precision, Precision::kFloat32);
  EXPECT_EQ(cal.layers[1].relative_rms, 0.02f);
}

TEST(ModelWriter, Int8WeightsAreCoveredByTheWeightsChecksum) {
  auto bytes = SerializeModel(Int8Spec());
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  // Flip one int8 weight and fix the whole-file CRC: only the weights' CRC can catch it.
  const size_t at =
      static_cast<size_t>(reinterpret_cast<const uint8_t*>((*model)->layers()[1].conv.weights_q) -
                          reinterpret_cast<const uint8_t*>((*model)->layers()[0].conv.weights_q));
  auto first =
      std::search(bytes->begin(), bytes->end(),
                  reinterpret_cast<const uint8_t*>((*model)->layers()[0].conv.weights_q),
                  reinterpret_cast<const uint8_t*>((*model)->layers()[0].conv.weights_q) + 64);
  ASSERT_NE(first, bytes->end());
  (*bytes)[static_cast<size_t>(first - bytes->begin()) + at + 5] ^= 0x10;
  ASSERT_TRUE(UpdateFileChecksum(*bytes).ok());
  auto damaged = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_FALSE(damaged.ok());
  EXPECT_NE(damaged.message().find("weights checksum mismatch"), std::string::npos)
      << damaged.message();
}

TEST(ModelWriter, AFloat32FileAt13DiffersFrom12OnlyInTheVersionAndFileChecksum) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16);
  SerializeOptions v12;
  v12.schema_minor = 2;
  auto a = SerializeModel(spec, v12);
  auto b = SerializeModel(spec);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->size(), b->size());
  size_t differing = 0;
  for (size_t i = 0; i < a->size(); ++i) differing += (*a)[i] != (*b)[i];
  EXPECT_GE(differing, 1u);
  EXPECT_LE(differing, 1u + 4u);  // the minor version's low byte, the file CRC-32C
}

TEST(ModelWriter, Bf16LayersNeedSchema14) {
  ModelSpec spec = exporter::SceneEdNetSpec(16);
  std::get<exporter::ConvSpec>(spec.layers[0]).precision = Precision::kBFloat16;
  SerializeOptions v13;
  v13.schema_minor = 3;
  auto bytes = SerializeModel(spec, v13);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("layer 0 'conv0': precision bf16 needs schema 1.4"),
            std::string::npos)
      << bytes.message();
  bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_EQ((*model)->layers()[0].conv.precision, Precision::kBFloat16);
  EXPECT_TRUE((*model)->metadata().has_bf16);
}

TEST(ModelWriter, Int8LayersAndCalibrationNeedSchema13) {
  ModelSpec spec = Int8Spec();
  SerializeOptions v12;
  v12.schema_minor = 2;
  auto bytes = SerializeModel(spec, v12);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("layer 0 'conv0': precision int8 needs schema 1.3"),
            std::string::npos)
      << bytes.message();
  spec = exporter::SceneEdNetSpec(16);
  spec.calibration = CalibrationDesc{};
  bytes = SerializeModel(spec, v12);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("a calibration record needs schema 1.3"), std::string::npos)
      << bytes.message();
}

TEST(ModelWriter, RejectsAnInt8LayerWithWrongCountsOrFloatWeights) {
  ModelSpec spec = Int8Spec();
  std::get<ConvSpec>(spec.layers[1]).weight_scales.pop_back();
  auto bytes = SerializeModel(spec);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("layer 1 'conv1': holds 288 int8 weights, 7 weight scales"),
            std::string::npos)
      << bytes.message();
  spec = Int8Spec();
  std::get<ConvSpec>(spec.layers[2]).weights_hwio.assign(5, 1.0f);
  bytes = SerializeModel(spec);
  ASSERT_FALSE(bytes.ok());
  EXPECT_NE(bytes.message().find("layer 2 'conv2': precision is int8 but weights_hwio holds 5"),
            std::string::npos)
      << bytes.message();
}

TEST(ModelWriter, LoaderRefusesAnInt8PairWhoseQuantParamsDoNotChain) {
  ModelSpec spec = Int8Spec();
  std::get<ConvSpec>(spec.layers[1]).input_quant.zero_point += 1;
  auto bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("layer 1 'conv1': input_quant"), std::string::npos)
      << model.message();
}

// An int8 file re-exported from itself (sfrt export m.sfrt -o n.sfrt) is the same file.
TEST(SfrtImporter, ReexportOfAnInt8FileWithItsCalibrationIsByteIdentical) {
  auto bytes = SerializeModel(Int8Spec());
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  const fs::path path = fs::temp_directory_path() / "sfrt_int8_reexport_test.sfrt";
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes->data()),
              static_cast<std::streamsize>(bytes->size()));
  }
  auto spec = ImportSfrt(path.string());
  fs::remove(path);
  ASSERT_TRUE(spec.ok()) << spec.message();
  ASSERT_TRUE(spec->calibration.has_value());
  EXPECT_EQ(std::get<ConvSpec>(spec->layers[0]).precision, Precision::kInt8);
  auto again = SerializeModel(*spec);
  ASSERT_TRUE(again.ok()) << again.message();
  EXPECT_EQ(*again, *bytes);
}

// Every field of every layer kind survives a re-export (sfrt export m.sfrt -o n.sfrt): the chain
// of float32 ops (pooling, grouped and dilated convolutions, a channel affine, a resize, a
// transposed convolution) with its pooling an argmax over column-major indices, re-imported and
// written again, is the same file.
TEST(SfrtImporter, ReexportOfEveryFloatOpWithAColumnMajorArgmaxPoolIsByteIdentical) {
  ModelSpec spec = testing::FloatOpsChainSpec();
  PoolSpec& pool = std::get<PoolSpec>(spec.layers[1]);
  pool.kind = PoolKind::kArgMax;
  pool.indices_column_major = true;
  auto bytes = SerializeModel(spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  const fs::path path = fs::temp_directory_path() / "sfrt_float_ops_reexport_test.sfrt";
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes->data()),
              static_cast<std::streamsize>(bytes->size()));
  }
  auto again = ImportSfrt(path.string());
  fs::remove(path);
  ASSERT_TRUE(again.ok()) << again.message();
  EXPECT_TRUE(std::get<PoolSpec>(again->layers[1]).indices_column_major);
  auto rewritten = SerializeModel(*again);
  ASSERT_TRUE(rewritten.ok()) << rewritten.message();
  EXPECT_EQ(*rewritten, *bytes);
}

// The committed default model as it was before schema 1.2: re-exported from the .sfrt file, it
// keeps every weight bit for bit and all its metadata, and takes the units and state given.
TEST(SfrtImporter, ReexportKeepsEveryWeightBitForBitAndTheMetadata) {
  const std::string legacy =
      std::string(SFRT_SOURCE_DIR) + "/tests/data/models/sceneednet-default-schema-1.1.sfrt";
  auto original = Model::LoadFile(legacy);
  ASSERT_TRUE(original.ok()) << original.message();
  auto spec = ImportSfrt(legacy);
  ASSERT_TRUE(spec.ok()) << spec.message();
  EXPECT_EQ(spec->output.units, "");  // a 1.1 file states no units
  spec->output.units = "metres";
  spec->training = TrainingState::kTrained;
  auto bytes = SerializeModel(*spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto again = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(again.ok()) << again.message();

  const ModelMetadata& a = (*original)->metadata();
  const ModelMetadata& b = (*again)->metadata();
  EXPECT_EQ(b.schema_minor, kSchemaVersionMinor);
  EXPECT_EQ(b.output.units, "metres");
  EXPECT_EQ(b.training, TrainingState::kTrained);
  EXPECT_EQ(b.weights_crc32c, a.weights_crc32c);
  EXPECT_EQ(b.name, a.name);
  EXPECT_EQ(b.source_format, a.source_format);
  EXPECT_EQ(b.source_file, a.source_file);
  EXPECT_EQ(b.source_sha256, a.source_sha256);
  EXPECT_EQ(b.input.image_order, a.input.image_order);
  EXPECT_EQ(b.input.color_order, a.input.color_order);
  EXPECT_EQ(b.input.scale, a.input.scale);
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(b.input.mean[c], a.input.mean[c]);
    EXPECT_EQ(b.input.std[c], a.input.std[c]);
  }
  EXPECT_EQ(b.input.traced_height, a.input.traced_height);
  EXPECT_EQ(b.input.traced_width, a.input.traced_width);
  EXPECT_EQ(b.camera.focal_px, a.camera.focal_px);
  EXPECT_EQ(b.camera.baseline, a.camera.baseline);
  EXPECT_EQ(b.camera.cx, a.camera.cx);
  EXPECT_EQ(b.camera.cy, a.camera.cy);
  EXPECT_EQ(b.output.channel_names, a.output.channel_names);
  ASSERT_EQ((*again)->layers().size(), (*original)->layers().size());
  for (size_t i = 0; i < (*original)->layers().size(); ++i) {
    const LayerDesc& la = (*original)->layers()[i];
    const LayerDesc& lb = (*again)->layers()[i];
    ASSERT_EQ(lb.name, la.name);
    ASSERT_EQ(lb.kind, la.kind);
    if (la.kind != LayerKind::kConv2D) continue;
    const ConvParams& ca = la.conv;
    const ConvParams& cb = lb.conv;
    ASSERT_EQ(cb.padding_rule, ca.padding_rule);
    ASSERT_EQ(cb.pads, ca.pads);
    ASSERT_EQ(cb.activation, ca.activation);
    ASSERT_EQ(cb.leaky_slope, ca.leaky_slope);
    const size_t n = static_cast<size_t>(ca.kernel_h) * ca.kernel_w * ca.in_channels *
                     static_cast<size_t>(ca.out_channels);
    ASSERT_EQ(std::memcmp(cb.weights, ca.weights, n * sizeof(float)), 0) << la.name;
    ASSERT_EQ(std::memcmp(cb.bias, ca.bias, ca.out_channels * sizeof(float)), 0) << la.name;
  }
}

}  // namespace
}  // namespace sfrt::exporter
