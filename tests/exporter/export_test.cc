// exporter::Export (sfrt/exporter/export.h): the whole export as a library call, on a .sfrt
// source written by the test. The command's own behaviour is checked by the CLI tests
// (tests/tools); these check what a program calling the library sees.
#include "sfrt/exporter/export.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/model.h"

namespace sfrt::exporter {
namespace {

namespace fs = std::filesystem;

// A SceneEDNet-shaped model at 1/16 width with the given units, written as a .sfrt file.
std::string WriteSource(const std::string& name, const std::string& units) {
  ModelSpec spec = SceneEdNetSpec(16, 3);
  spec.output.units = units;
  spec.input.traced_height = 32;
  spec.input.traced_width = 48;
  Result<std::vector<uint8_t>> bytes = SerializeModel(spec);
  EXPECT_TRUE(bytes.ok()) << bytes.message();
  const fs::path dir = fs::path(testing::TempDir()) / "export_test";
  fs::create_directories(dir);
  const std::string path = (dir / name).string();
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes->data()),
             static_cast<std::streamsize>(bytes->size()));
  return path;
}

std::shared_ptr<const Model> Load(const std::vector<uint8_t>& bytes) {
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy);
  EXPECT_TRUE(model.ok()) << model.message();
  return model.ok() ? *model : nullptr;
}

ExportOptions OptionsFor(const std::string& source) {
  ExportOptions options;
  options.source = source;
  options.destination = source + ".out";
  return options;
}

TEST(Export, ASfrtSourceKeepsEveryFieldNotGivenAndTakesTheOnesGiven) {
  ExportOptions options = OptionsFor(WriteSource("keep.sfrt", "metres"));
  options.metadata.training = TrainingState::kTrained;
  options.metadata.focal_px = 700.0f;
  const ExportResult result = Export(options);
  ASSERT_TRUE(result.status.ok()) << result.status.message();
  ASSERT_NE(result.model, nullptr);
  const std::shared_ptr<const Model> model = Load(result.bytes);
  ASSERT_NE(model, nullptr);
  EXPECT_EQ(model->metadata().output.units, "metres");  // kept
  EXPECT_EQ(model->metadata().training, TrainingState::kTrained);
  EXPECT_EQ(model->metadata().camera.focal_px, 700.0f);
  EXPECT_EQ(model->metadata().camera.baseline, CameraSpec{}.baseline);
  EXPECT_EQ(model->layers().size(), result.model->layers().size());
  ASSERT_TRUE(result.traced_output.has_value());
  EXPECT_EQ(result.traced_output->channels, 3);
  EXPECT_FALSE(fs::exists(options.destination)) << "Export writes nothing";
}

TEST(Export, ImageFlagsOnAPlainTensorAreRefusedNamingTheFlag) {
  ExportOptions options = OptionsFor(WriteSource("tensor.sfrt", ""));
  options.metadata.input_kind = InputKindChoice::kTensor;
  options.metadata.scale = 2.0f;
  const ExportResult result = Export(options);
  ASSERT_FALSE(result.status.ok());
  EXPECT_NE(result.status.message().find("--scale describes image inputs"), std::string::npos)
      << result.status.message();
  EXPECT_TRUE(result.bytes.empty());
}

TEST(Export, AFailedParityCheckKeepsItsFiguresAndSaysNothingIsWritten) {
  ExportOptions options = OptionsFor(WriteSource("parity.sfrt", ""));
  CheckOptions& check = options.check;
  check.kind = CheckOptions::Kind::kParity;
  check.input = {"in.npy", "(32, 48, 12)", 32, 48, 12, std::vector<float>(32 * 48 * 12, 100.0f)};
  // Without a reference the check passes and gives the output's shape.
  const ExportResult sized = Export(options);
  ASSERT_TRUE(sized.status.ok()) << sized.status.message();
  ASSERT_TRUE(sized.check.has_value());
  EXPECT_TRUE(sized.check->passed);
  // A reference far from any output this model gives: every pixel is over the tolerance.
  const TensorShape out = sized.check->output;
  check.reference = CheckArray{"ref.npy", "(h, w, 3)",  out.height,
                               out.width, out.channels, std::vector<float>(out.elements(), 1e6f)};
  check.tolerance = 1e-4;
  const ExportResult result = Export(options);
  ASSERT_FALSE(result.status.ok());
  EXPECT_NE(result.status.message().find("parity check failed"), std::string::npos);
  EXPECT_NE(result.status.message().find("; nothing written to " + options.destination),
            std::string::npos)
      << result.status.message();
  ASSERT_TRUE(result.check.has_value());
  EXPECT_TRUE(result.check->ran);
  EXPECT_TRUE(result.check->compared);
  EXPECT_FALSE(result.check->passed);
  EXPECT_EQ(result.check->pixels_over, result.check->pixels);
  EXPECT_GT(result.check->relative_error, 0.9);
}

TEST(Export, QuantisingReadsTheCalibrationOnceForTheVerifiedFloatModel) {
  ExportOptions options = OptionsFor(WriteSource("int8.sfrt", ""));
  options.precision = PrecisionChange::kQuantize;
  options.calibration_name = "--calibration test";
  int reads = 0;
  options.calibration = [&reads](const InputDesc& input, std::string* described) {
    ++reads;
    CalibrationSet set;
    set.frames = 2;
    set.height = input.traced_height;
    set.width = input.traced_width;
    set.channels = input.channels;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> pixel(0.0f, 255.0f);
    set.values.resize(static_cast<size_t>(set.frames) * set.height * set.width * set.channels);
    for (float& v : set.values) v = pixel(rng);
    *described = "2 seeded frames";
    return Result<CalibrationSet>(std::move(set));
  };
  const ExportResult result = Export(options);
  ASSERT_TRUE(result.status.ok()) << result.status.message();
  EXPECT_EQ(reads, 1);
  EXPECT_EQ(result.calibration_described, "2 seeded frames");
  ASSERT_TRUE(result.calibration.has_value());
  EXPECT_EQ(result.calibration->frames, 2);
  const std::shared_ptr<const Model> model = Load(result.bytes);
  ASSERT_NE(model, nullptr);
  int int8 = 0;
  for (const LayerDesc& layer : model->layers()) {
    int8 += layer.kind == LayerKind::kConv2D && layer.conv.precision == Precision::kInt8;
  }
  EXPECT_GT(int8, 0);
}

TEST(Export, ACalibrationReadersErrorIsTheExportsAndNothingIsMade) {
  ExportOptions options = OptionsFor(WriteSource("bad_calibration.sfrt", ""));
  options.precision = PrecisionChange::kQuantize;
  options.calibration = [](const InputDesc&, std::string*) {
    return Result<CalibrationSet>(Status::Error("--calibration x: no frames"));
  };
  const ExportResult result = Export(options);
  ASSERT_FALSE(result.status.ok());
  EXPECT_EQ(result.status.message(), "--calibration x: no frames");
  EXPECT_FALSE(result.calibration.has_value());
}

TEST(Export, SourceFormatOfKnowsTheExtensionsInAnyCaseAndNamesKerasThreeArchives) {
  EXPECT_EQ(SourceFormatOf("a.ONNX").value(), SourceFormat::kOnnx);
  EXPECT_EQ(SourceFormatOf("a.h5").value(), SourceFormat::kKeras);
  EXPECT_EQ(SourceFormatOf("a.HDF5").value(), SourceFormat::kKeras);
  EXPECT_EQ(SourceFormatOf("a.sfrt").value(), SourceFormat::kSfrt);
  const Result<SourceFormat> keras3 = SourceFormatOf("m.keras");
  ASSERT_FALSE(keras3.ok());
  EXPECT_NE(keras3.message().find("m.keras: Keras 3 .keras archives are not supported"),
            std::string::npos);
  EXPECT_FALSE(SourceFormatOf("m").ok());
}

TEST(Export, InputKindChoiceNamesRoundTrip) {
  for (size_t i = 0; i < kInputKindChoiceNames.size(); ++i) {
    const auto kind = static_cast<InputKindChoice>(i);
    EXPECT_EQ(ParseInputKindChoice(InputKindChoiceName(kind)), kind);
  }
  EXPECT_FALSE(ParseInputKindChoice("Images").has_value());
}

}  // namespace
}  // namespace sfrt::exporter
