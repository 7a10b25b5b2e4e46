// ImportKerasH5 on the Keras 2 HDF5 files tests/fixtures/gen_keras_h5.py writes with h5py in
// Keras' own layout (FIXTURES keras_models), against PyTorch outputs computed from the same
// weights with TensorFlow 'same' padding. Fails, never skips, when the files are missing.
#include "sfrt/exporter/keras_importer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <tuple>
#include <variant>
#include <vector>

#include "sfrt/exporter/model_writer.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/io/npy.h"
#include "sfrt/session.h"

namespace sfrt::exporter {
namespace {

constexpr double kRelativeTolerance = 1e-4;  // vs PyTorch, relative to the largest |value|
constexpr double kFp16Tolerance = 1e-2;      // fp16 weights vs fp32 weights

std::string Fixture(const std::string& file) { return std::string(SFRT_FIXTURE_DIR) + "/" + file; }

KerasImportResult Import(const std::string& name, const std::string& architecture = "") {
  KerasImportOptions options;
  options.architecture_json = architecture;
  Result<KerasImportResult> r = ImportKerasH5(Fixture(name + ".h5"), options);
  EXPECT_TRUE(r.ok()) << r.message();
  return r.ok() ? std::move(r).value() : KerasImportResult{};
}

// Serialises `spec`, loads it and runs it on `input` (H x W x 12). Empty on failure.
std::vector<float> RunModel(const ModelSpec& spec, const io::NpyArray& input, size_t* file_bytes) {
  auto bytes = SerializeModel(spec);
  EXPECT_TRUE(bytes.ok()) << bytes.message();
  if (!bytes.ok()) return {};
  if (file_bytes != nullptr) *file_bytes = bytes->size();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  EXPECT_TRUE(model.ok()) << model.message();
  if (!model.ok() || input.shape.size() != 3) return {};
  const int h = static_cast<int>(input.shape[0]);
  const int w = static_cast<int>(input.shape[1]);
  SessionOptions options;
  options.max_height = h;
  options.max_width = w;
  auto session = Session::Create(*model, options);
  EXPECT_TRUE(session.ok()) << session.message();
  if (!session.ok()) return {};
  auto shape = (*session)->OutputShape(h, w);
  EXPECT_TRUE(shape.ok()) << shape.message();
  if (!shape.ok()) return {};
  std::vector<float> out(shape->elements());
  const Status s = (*session)->Run(input.data, h, w, out);
  EXPECT_TRUE(s.ok()) << s.message();
  return s.ok() ? out : std::vector<float>{};
}

io::NpyArray Npy(const std::string& file) {
  auto a = io::ReadNpy(Fixture(file));
  EXPECT_TRUE(a.ok()) << a.message();
  return a.ok() ? std::move(a).value() : io::NpyArray{};
}

// Max |actual - expected| over max |expected|; infinity on size mismatch or non-finite values.
double RelativeError(const std::vector<float>& actual, const std::vector<float>& expected) {
  if (actual.size() != expected.size() || expected.empty()) return INFINITY;
  double max_ref = 0, max_err = 0;
  for (size_t i = 0; i < actual.size(); ++i) {
    if (!std::isfinite(actual[i])) return INFINITY;
    max_ref = std::max(max_ref, std::fabs(static_cast<double>(expected[i])));
    max_err = std::max(max_err, std::fabs(static_cast<double>(actual[i]) - expected[i]));
  }
  return max_ref > 0 ? max_err / max_ref : max_err;
}

// Imports `model_case`.h5, runs it on `data_case`'s input, returns the error relative to
// PyTorch's output for that input.
double ErrorAgainstPyTorch(const std::string& model_case, const std::string& data_case,
                           const std::string& architecture = "") {
  const KerasImportResult imported = Import(model_case, architecture);
  if (imported.spec.layers.empty()) return INFINITY;
  const std::vector<float> out = RunModel(imported.spec, Npy(data_case + ".input.npy"), nullptr);
  const double rel = RelativeError(out, Npy(data_case + ".output.npy").data);
  std::printf("  %-28s on %-22s relative error %.3g\n", model_case.c_str(), data_case.c_str(), rel);
  return rel;
}

const ConvSpec* FindConv(const ModelSpec& spec, const std::string& name) {
  for (const LayerSpec& l : spec.layers) {
    if (const auto* c = std::get_if<ConvSpec>(&l); c != nullptr && c->name == name) return c;
  }
  return nullptr;
}

std::vector<std::string> LayerNames(const ModelSpec& spec) {
  std::vector<std::string> names;
  for (const LayerSpec& l : spec.layers) {
    std::visit([&names](const auto& s) { names.push_back(s.name); }, l);
  }
  return names;
}

TEST(KerasImport, FixtureSuiteIsPresent) {
  EXPECT_TRUE(std::filesystem::is_regular_file(Fixture("keras_suite.json")))
      << "tests/fixtures/gen_keras_h5.py did not run into " << SFRT_FIXTURE_DIR;
}

TEST(KerasImport, EveryFixtureModelMatchesPyTorch) {
  for (const char* name :
       {"keras_w16_67x121", "keras_w16_540x960", "keras_w1_35x61", "keras_multigpu_w16_67x121",
        "keras_seq_67x121", "keras_anysize_w16_67x121", "keras_bn_w16_67x121",
        "keras_unet_bn_w16_67x121", "keras_unet_bn_w16_37x53", "keras_separable_37x53",
        "keras_decoder_36x52", "keras_bilinear_tf2_36x52"}) {
    SCOPED_TRACE(name);
    EXPECT_LE(ErrorAgainstPyTorch(name, name), kRelativeTolerance);
  }
}

const ResizeSpec* FindResize(const ModelSpec& spec, const std::string& name) {
  for (const LayerSpec& l : spec.layers) {
    if (const auto* r = std::get_if<ResizeSpec>(&l); r != nullptr && r->name == name) return r;
  }
  return nullptr;
}

// A bilinear UpSampling2D becomes a linear Resize by its factors. A file saved by Keras 2.9 ran
// on TensorFlow 2: the half-pixel grid, said in a note (EveryFixtureModelMatchesPyTorch runs it).
TEST(KerasImport, BilinearUpsamplingOfATensorFlow2FileSamplesOnTheHalfPixelGrid) {
  const KerasImportResult imported = Import("keras_bilinear_tf2_36x52");
  for (auto [name, fh, fw] : {std::tuple{"up_sampling2d_1", 2, 2}, {"up_sampling2d_2", 3, 2}}) {
    SCOPED_TRACE(name);
    const ResizeSpec* resize = FindResize(imported.spec, name);
    ASSERT_NE(resize, nullptr);
    EXPECT_EQ(resize->params.mode, ResizeMode::kLinear);
    EXPECT_EQ(resize->params.coordinates, ResizeCoordinates::kHalfPixel);
    EXPECT_EQ(resize->params.scale_num_h, fh);
    EXPECT_EQ(resize->params.scale_den_h, 1);
    EXPECT_EQ(resize->params.scale_num_w, fw);
    EXPECT_EQ(resize->params.scale_den_w, 1);
  }
  EXPECT_TRUE(std::any_of(imported.notes.begin(), imported.notes.end(), [](const std::string& n) {
    return n.find("half-pixel grid (the file was saved by Keras 2.9.0)") != std::string::npos;
  }));
}

// Keras 2.2.4 ran on TensorFlow 1 or 2, whose grids differ, and the file does not say which:
// the importer asks, naming the layer; told "asymmetric" (TensorFlow 1, as the fixture's
// reference assumes) it matches, told "half-pixel" it does not.
TEST(KerasImport, BilinearUpsamplingOfAKeras22FileNeedsTheGridStated) {
  const std::string path = Fixture("keras_bilinear_tf1_36x52.h5");
  Result<KerasImportResult> refused = ImportKerasH5(path);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.message().find(path + ": layer 'up_sampling2d_1' (UpSampling2D): bilinear "
                                          "interpolation samples on a grid that depends on"),
            std::string::npos)
      << refused.message();
  EXPECT_NE(refused.message().find("--keras-bilinear"), std::string::npos) << refused.message();

  const io::NpyArray input = Npy("keras_bilinear_tf1_36x52.input.npy");
  const std::vector<float> expected = Npy("keras_bilinear_tf1_36x52.output.npy").data;
  KerasImportOptions options;
  options.bilinear_grid = KerasBilinearGrid::kAsymmetric;
  Result<KerasImportResult> asymmetric = ImportKerasH5(path, options);
  ASSERT_TRUE(asymmetric.ok()) << asymmetric.message();
  EXPECT_LE(RelativeError(RunModel(asymmetric->spec, input, nullptr), expected),
            kRelativeTolerance);
  options.bilinear_grid = KerasBilinearGrid::kHalfPixel;
  Result<KerasImportResult> half_pixel = ImportKerasH5(path, options);
  ASSERT_TRUE(half_pixel.ok()) << half_pixel.message();
  EXPECT_GT(RelativeError(RunModel(half_pixel->spec, input, nullptr), expected), 1e-2);
}

// DepthwiseConv2D (depth_multiplier 2) and a Conv2D with groups and dilation_rate keep them;
// EveryFixtureModelMatchesPyTorch runs the model.
TEST(KerasImport, DepthwiseAndGroupedDilatedConvolutionsKeepTheirGroupsAndDilation) {
  const KerasImportResult imported = Import("keras_separable_37x53");
  const ConvSpec* depthwise = FindConv(imported.spec, "depthwise");
  ASSERT_NE(depthwise, nullptr);
  EXPECT_EQ(depthwise->groups, 8);
  EXPECT_EQ(depthwise->in_channels, 8);
  EXPECT_EQ(depthwise->out_channels, 16);
  EXPECT_EQ(depthwise->dilation_h, 2);
  EXPECT_EQ(depthwise->dilation_w, 2);
  EXPECT_EQ(depthwise->pads, (Pads{2, 2, 2, 2}));  // 'same' for the 5x5 dilated extent
  const ConvSpec* grouped = FindConv(imported.spec, "grouped");
  ASSERT_NE(grouped, nullptr);
  EXPECT_EQ(grouped->groups, 4);
  EXPECT_EQ(grouped->dilation_h, 1);
  EXPECT_EQ(grouped->dilation_w, 2);
  EXPECT_EQ(grouped->weights_hwio.size(), 3u * 3 * 4 * 8);
}

// Conv2DTranspose becomes a transposed convolution whose crops and output padding place
// TensorFlow's output (gen_keras_h5.py decoder_layers; EveryFixtureModelMatchesPyTorch runs
// it): 'same' 3x3/2 crops its extra row at the bottom, output_padding 1 keeps it, 'valid' 1x1/2
// adds a row and column of bias; the BatchNormalization and ReLU after a Conv2DTranspose fold
// and fuse into it; pooling layers keep their kind, window and rule.
TEST(KerasImport, Conv2DTransposeAndPoolingKeepTensorFlowsPlacement) {
  const KerasImportResult imported = Import("keras_decoder_36x52");
  const ModelSpec& spec = imported.spec;
  ASSERT_EQ(spec.layers.size(), 10u) << ::testing::PrintToString(LayerNames(spec));
  auto deconv = [&](size_t i) { return std::get_if<ConvTransposeSpec>(&spec.layers[i]); };
  auto pool = [&](size_t i) { return std::get_if<PoolSpec>(&spec.layers[i]); };
  ASSERT_NE(pool(1), nullptr);
  EXPECT_EQ(pool(1)->kind, PoolKind::kMax);
  EXPECT_EQ(pool(1)->stride_h, 2);  // strides None: the pool size
  EXPECT_EQ(pool(1)->padding_rule, PaddingRule::kExplicit);
  ASSERT_NE(pool(2), nullptr);
  EXPECT_EQ(pool(2)->kind, PoolKind::kAverage);
  EXPECT_EQ(pool(2)->padding_rule, PaddingRule::kSameUpper);
  EXPECT_FALSE(pool(2)->count_include_pad);
  ASSERT_NE(deconv(3), nullptr);
  EXPECT_EQ(deconv(3)->name, "deconv1");
  EXPECT_EQ(deconv(3)->activation, Activation::kRelu);
  EXPECT_EQ(deconv(3)->pads, (Pads{0, 0, 0, 0}));
  ASSERT_NE(deconv(5), nullptr);
  EXPECT_EQ(deconv(5)->pads, (Pads{0, 0, 1, 1}));  // top, left, bottom, right
  EXPECT_EQ(deconv(5)->activation, Activation::kLeakyRelu);
  ASSERT_NE(deconv(7), nullptr);
  EXPECT_EQ(deconv(7)->pads, (Pads{0, 1, 1, 1}));
  EXPECT_EQ(deconv(7)->output_padding_h, 0);
  ASSERT_NE(deconv(8), nullptr);
  EXPECT_EQ(deconv(8)->pads, (Pads{0, 0, 0, 0}));
  EXPECT_EQ(deconv(8)->output_padding_h, 1);
  EXPECT_EQ(deconv(8)->output_padding_w, 1);
  // Keras' kernel (kh, kw, filters, in) became HWIO (kh, kw, in, filters).
  EXPECT_EQ(deconv(8)->in_channels, 8);
  EXPECT_EQ(deconv(8)->weights_hwio.size(), 8u * 8);
}

// A BatchNormalization after a Conv2D with activation 'linear' is folded into it: the same 11
// convolutions as without it, and (above) PyTorch's output with the normalisation as a layer.
TEST(KerasImport, BatchNormalizationAfterAConvIsFoldedIntoIt) {
  auto with = ImportKerasH5(Fixture("keras_bn_w16_67x121.h5"));
  auto without = ImportKerasH5(Fixture("keras_w16_67x121.h5"));
  ASSERT_TRUE(with.ok()) << with.message();
  ASSERT_TRUE(without.ok()) << without.message();
  EXPECT_EQ(LayerNames(with->spec), LayerNames(without->spec));
}

// SceneEDNet-U with BatchNormalization and Concatenate (gen_keras_h5.py unet_layers): a graph of
// eleven convolutions (the normalisations folded into them), four Concats, three crops to the
// skip's size and one to the input's; built at 37x53, it matches PyTorch at 67x121 (same
// weights), so the crops hold at a size they were not built for.
TEST(KerasImport, SceneEdNetUWithBatchNormAndConcatenateIsAGraphThatHoldsAtAnotherSize) {
  const KerasImportResult imported = Import("keras_unet_bn_w16_37x53");
  const ModelSpec& spec = imported.spec;
  ASSERT_EQ(spec.layers.size(), 23u);
  EXPECT_TRUE(IsGraph(spec));
  EXPECT_EQ(spec.input.name, "input_1");
  int convs = 0, cats = 0, skip_crops = 0;
  for (const LayerSpec& l : spec.layers) {
    EXPECT_FALSE(std::visit([](const auto& x) { return x.name; }, l).starts_with("batch_norm"));
    convs += std::holds_alternative<ConvSpec>(l);
    cats += std::holds_alternative<ConcatSpec>(l);
    if (const auto* crop = std::get_if<CropSpec>(&l)) {
      skip_crops += crop->rule == CropRule::kToSecondInput;
    }
  }
  EXPECT_EQ(convs, 11);
  EXPECT_EQ(cats, 4);
  EXPECT_EQ(skip_crops, 3);
  EXPECT_LE(ErrorAgainstPyTorch("keras_unet_bn_w16_37x53", "keras_unet_bn_w16_67x121"),
            kRelativeTolerance);
}

TEST(KerasImport, WeightsOnlyFileWithArchitectureJsonMatchesPyTorch) {
  EXPECT_LE(ErrorAgainstPyTorch("keras_weights_w16_67x121", "keras_weights_w16_67x121",
                                Fixture("keras_weights_w16_67x121.json")),
            kRelativeTolerance);
}

TEST(KerasImport, WeightsOnlyFileWithoutArchitectureNamesTheFix) {
  auto r = ImportKerasH5(Fixture("keras_weights_w16_67x121.h5"));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.message().find("weights-only"), std::string::npos) << r.message();
  EXPECT_NE(r.message().find("--architecture"), std::string::npos) << r.message();
}

TEST(KerasImport, AuthorsArchitectureKeepsNamesAndBecomesSizeRules) {
  const KerasImportResult r = Import("keras_w16_540x960");
  const ModelSpec& spec = r.spec;
  EXPECT_EQ(LayerNames(spec),
            (std::vector<std::string>{"conv0", "conv1", "conv2", "conv3", "conv4", "conv5",
                                      "up_sampling2d_1", "conv6", "up_sampling2d_2", "conv7",
                                      "up_sampling2d_3", "conv8", "up_sampling2d_4", "cropping2d_1",
                                      "conv9", "output"}));
  EXPECT_EQ(spec.input.channels, 12);
  EXPECT_EQ(spec.input.traced_height, 540);
  EXPECT_EQ(spec.input.traced_width, 960);
  EXPECT_EQ(spec.output.channels, 3);
  EXPECT_EQ(spec.producer.source_format, "keras-h5");
  EXPECT_EQ(spec.producer.source_file, "keras_w16_540x960.h5");
  EXPECT_EQ(spec.producer.source_sha256.size(), 64u);
  for (const LayerSpec& l : spec.layers) {
    if (const auto* c = std::get_if<ConvSpec>(&l)) {
      EXPECT_EQ(c->padding_rule, PaddingRule::kSameUpper) << c->name;
      if (c->name == "output") {
        EXPECT_EQ(c->activation, Activation::kNone);
      } else {
        EXPECT_EQ(c->activation, Activation::kLeakyRelu) << c->name;
        EXPECT_EQ(c->leaky_slope, 0.3f) << c->name;  // 0.30000001192092896 in the JSON
      }
    }
  }
  // Keras 'same' at 540: conv0 (stride 2) pads 0 on top and 1 at the bottom.
  const ConvSpec* conv0 = FindConv(spec, "conv0");
  ASSERT_NE(conv0, nullptr);
  EXPECT_EQ(conv0->pads, (Pads{0, 0, 1, 1}));
  // The authors' Cropping2D(((4, 0), (0, 0))) is 16*ceil(H/16)-H rows from the top at 540x960.
  const auto& crop = std::get<CropSpec>(spec.layers[13]);
  EXPECT_EQ(crop.rule, CropRule::kToInputSize);
  EXPECT_TRUE(crop.excess_rows_from_top);
  EXPECT_TRUE(crop.excess_cols_from_left);
  EXPECT_EQ(crop.amounts, (Pads{4, 0, 0, 0}));
  EXPECT_TRUE(r.notes.empty());
}

TEST(KerasImport, ModelBuiltAt540x960MatchesPyTorchAt67x121) {
  // Same seed and widths, so the same weights: the crop and padding rules taken from the model
  // built at 540x960 must reproduce PyTorch at 67x121 (13 rows and 7 columns cropped there).
  EXPECT_LE(ErrorAgainstPyTorch("keras_w16_540x960", "keras_w16_67x121"), kRelativeTolerance);
}

TEST(KerasImport, MultiGpuCheckpointExportsTheNestedModelAndSaysSo) {
  const KerasImportResult nested = Import("keras_multigpu_w16_67x121");
  const KerasImportResult plain = Import("keras_w16_67x121");
  ASSERT_EQ(nested.notes.size(), 1u);
  EXPECT_NE(nested.notes[0].find("multi_gpu_model"), std::string::npos) << nested.notes[0];
  EXPECT_NE(nested.notes[0].find("'model_1'"), std::string::npos) << nested.notes[0];
  EXPECT_EQ(LayerNames(nested.spec), LayerNames(plain.spec));
  for (const char* name : {"conv0", "conv5", "output"}) {
    const ConvSpec* a = FindConv(nested.spec, name);
    const ConvSpec* b = FindConv(plain.spec, name);
    ASSERT_TRUE(a != nullptr && b != nullptr) << name;
    EXPECT_EQ(a->weights_hwio, b->weights_hwio) << name;
    EXPECT_EQ(a->bias, b->bias) << name;
  }
}

TEST(KerasImport, CropStaysExplicitWhenTheBuiltSizeIsUnknown) {
  const KerasImportResult r = Import("keras_anysize_w16_67x121");
  EXPECT_EQ(r.spec.input.traced_height, 0);
  const auto& crop = std::get<CropSpec>(r.spec.layers[13]);
  EXPECT_EQ(crop.rule, CropRule::kExplicit);
  EXPECT_EQ(crop.amounts, (Pads{13, 7, 0, 0}));
  bool noted = false;
  for (const std::string& n : r.notes) noted |= n.find("cropping2d_1") != std::string::npos;
  EXPECT_TRUE(noted);
}

TEST(KerasImport, SequentialFoldsZeroPaddingAndFusesActivations) {
  const ModelSpec spec = Import("keras_seq_67x121").spec;
  EXPECT_EQ(LayerNames(spec),
            (std::vector<std::string>{"conv2d_1", "conv2d_2", "conv2d_3", "up_sampling2d_1",
                                      "cropping2d_1", "conv2d_4"}));
  const ConvSpec* c1 = FindConv(spec, "conv2d_1");
  const ConvSpec* c2 = FindConv(spec, "conv2d_2");
  const ConvSpec* c3 = FindConv(spec, "conv2d_3");
  ASSERT_TRUE(c1 != nullptr && c2 != nullptr && c3 != nullptr);
  EXPECT_EQ(c1->activation, Activation::kRelu);
  // ZeroPadding2D(((1, 1), (2, 0))) + 'valid': explicit pads, the same at every size.
  EXPECT_EQ(c2->padding_rule, PaddingRule::kExplicit);
  EXPECT_EQ(c2->pads, (Pads{1, 2, 1, 0}));
  EXPECT_EQ(c2->activation, Activation::kRelu);       // Activation('relu') fused
  EXPECT_EQ(c2->bias, std::vector<float>(16, 0.0f));  // use_bias False
  EXPECT_EQ(c3->kernel_h, 5);
  EXPECT_EQ(c3->kernel_w, 3);
  EXPECT_EQ(c3->stride_h, 2);
  EXPECT_EQ(c3->stride_w, 1);
  EXPECT_EQ(c3->activation, Activation::kLeakyRelu);
  EXPECT_EQ(c3->leaky_slope, 0.2f);
  const auto& up = std::get<UpsampleSpec>(spec.layers[3]);
  EXPECT_EQ(up.factor_h, 4);
  EXPECT_EQ(up.factor_w, 2);
  EXPECT_EQ(std::get<CropSpec>(spec.layers[4]).rule, CropRule::kToInputSize);
}

TEST(KerasImport, Fp16WeightsHalveTheFileAndStayWithin1e2OfFp32) {
  ModelSpec spec = Import("keras_w1_35x61").spec;  // full width: 21.3 M parameters
  const io::NpyArray input = Npy("keras_w1_35x61.input.npy");
  size_t fp32_bytes = 0;
  size_t fp16_bytes = 0;
  const std::vector<float> fp32 = RunModel(spec, input, &fp32_bytes);
  spec.weight_type = WeightType::kFloat16;
  const std::vector<float> fp16 = RunModel(spec, input, &fp16_bytes);
  ASSERT_GT(fp32_bytes, 0u);
  const double ratio = static_cast<double>(fp16_bytes) / static_cast<double>(fp32_bytes);
  const double rel = RelativeError(fp16, fp32);
  std::printf("  fp16/fp32 file size %zu/%zu = %.4f, output relative difference %.3g\n", fp16_bytes,
              fp32_bytes, ratio, rel);
  EXPECT_GT(ratio, 0.49);
  EXPECT_LT(ratio, 0.51);
  EXPECT_LE(rel, kFp16Tolerance);
  EXPECT_GT(rel, 0.0);  // the weights really were rounded
  EXPECT_LE(RelativeError(fp16, Npy("keras_w1_35x61.output.npy").data), kFp16Tolerance);
}

struct MalformedCase {
  const char* file;
  std::vector<std::string> expected;  // substrings of the one-line message
};

TEST(KerasImport, MalformedFilesFailWithOneLineNamingTheLayerOrDataset) {
  const std::vector<MalformedCase> cases = {
      {"bad_missing_group.h5",
       {"layer 'conv3' (Conv2D)", "weights group 'model_weights/conv3' is missing"}},
      {"bad_kernel_shape.h5",
       {"layer 'conv2' (Conv2D)",
        "dataset 'model_weights/conv2/conv2/kernel:0' has shape (3, 3, 16, 8); expected (3, 3, "
        "8, 16)"}},
      {"bad_alpha_missing.h5", {"layer 'leaky_re_lu_3' (LeakyReLU)", "no 'alpha'"}},
      {"bad_unknown_layer.h5",
       {"layer 'dense_1' (Dense)", "not supported",
        "InputLayer, Conv2D (any dilation_rate and groups), DepthwiseConv2D, Conv2DTranspose, "
        "BatchNormalization (folded into the convolution before it), LeakyReLU, Activation, "
        "UpSampling2D (nearest and bilinear), MaxPooling2D, AveragePooling2D, Cropping2D, "
        "ZeroPadding2D"}},
      {"bad_truncated.h5", {"truncated", "stored_eof"}},
      {"bad_dilation.h5", {"layer 'conv4' (Conv2D)", "dilation_rate [0,2] is not integers"}},
      {"bad_channels_first.h5", {"layer 'up_sampling2d_2' (UpSampling2D)", "channels_first"}},
      {"bad_activation.h5", {"layer 'output' (Conv2D)", "activation 'tanh'"}},
      {"bad_weight_count.h5",
       {"layer 'conv5' (Conv2D)", "'model_weights/conv5' lists 1 weights", "expected 2"}},
      {"keras_weights_w16_67x121.json", {"not an HDF5 file"}},
      {"no_such_file.h5", {"no such file"}},
  };
  for (const MalformedCase& c : cases) {
    SCOPED_TRACE(c.file);
    auto r = ImportKerasH5(Fixture(c.file));
    ASSERT_FALSE(r.ok());
    const std::string& m = r.message();
    EXPECT_EQ(m.rfind(Fixture(c.file) + ": ", 0), 0u) << m;  // starts with the file
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    for (const std::string& e : c.expected) EXPECT_NE(m.find(e), std::string::npos) << m;
  }
}

// An architecture JSON that does not describe the weights file: a kernel of the wrong shape, or
// weights left over for layers the architecture does not have.
TEST(KerasImport, ArchitectureNotMatchingTheWeightsIsRejected) {
  const std::string json_path =
      (std::filesystem::temp_directory_path() / "sfrt_keras_wrong_arch.json").string();
  struct Case {
    int filters;
    std::string expected;
  };
  for (const Case& c : {Case{5,
                             "layer 'conv0' (Conv2D): dataset 'conv0/conv0/kernel:0' has "
                             "shape (3, 3, 12, 4); expected (3, 3, 12, 5)"},
                        Case{4, "weights group 'conv1' holds 2 weights but no layer"}}) {
    SCOPED_TRACE(c.filters);
    std::FILE* f = std::fopen(json_path.c_str(), "w");
    ASSERT_NE(f, nullptr);
    const std::string text =
        R"({"class_name": "Sequential", "config": {"name": "s", "layers": [
           {"class_name": "Conv2D", "config": {"name": "conv0", "filters": )" +
        std::to_string(c.filters) + R"(, "kernel_size": [3, 3], "strides": [2, 2],
            "padding": "same", "batch_input_shape": [null, 67, 121, 12]}}]}})";
    std::fputs(text.c_str(), f);
    std::fclose(f);
    KerasImportOptions options;
    options.architecture_json = json_path;
    auto r = ImportKerasH5(Fixture("keras_weights_w16_67x121.h5"), options);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find(c.expected), std::string::npos) << r.message();
  }
  std::filesystem::remove(json_path);
}

// Each limit of sfrt/model_limits.h is checked while the architecture is read, naming the layer
// and the field (the loader would reject the written file otherwise).
TEST(KerasImport, LayerPastTheLoaderLimitsNamesTheLayerAndField) {
  const std::string json_path =
      (std::filesystem::temp_directory_path() / "sfrt_keras_limits_arch.json").string();
  const std::string conv0 =
      R"({"class_name": "Conv2D", "config": {"name": "conv0", "filters": 4, "kernel_size": [3, 3],
          "strides": [2, 2], "padding": "same", "batch_input_shape": [null, 67, 121, 12]}})";
  struct Case {
    std::string layers;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {R"({"class_name": "Conv2D", "config": {"name": "conv0", "filters": 4,
          "kernel_size": [32, 3], "padding": "same", "batch_input_shape": [null, 67, 121, 12]}})",
       "layer 'conv0' (Conv2D): 'kernel_size' is missing or not integers in 1..31"},
      {R"({"class_name": "Conv2D", "config": {"name": "conv0", "filters": 4,
          "kernel_size": [3, 3], "strides": [1, 17], "padding": "same",
          "batch_input_shape": [null, 67, 121, 12]}})",
       "layer 'conv0' (Conv2D): strides [1,17] are not integers in 1..16"},
      {R"({"class_name": "Conv2D", "config": {"name": "conv0", "filters": 65537,
          "kernel_size": [3, 3], "padding": "same", "batch_input_shape": [null, 67, 121, 12]}})",
       "layer 'conv0' (Conv2D): 'filters' is missing or not an integer in 1..65536"},
      {R"({"class_name": "Conv2D", "config": {"name": "conv0", "filters": 4,
          "kernel_size": [3, 3], "padding": "same", "batch_input_shape": [null, 67, 121, 65537]}})",
       "channels in 1..65536"},
      {conv0 + R"(, {"class_name": "UpSampling2D", "config": {"name": "up", "size": [65, 1]}})",
       "layer 'up' (UpSampling2D): 'size' is missing or not integers in 1..64"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.expected);
    std::FILE* f = std::fopen(json_path.c_str(), "w");
    ASSERT_NE(f, nullptr);
    const std::string text =
        R"({"class_name": "Sequential", "config": {"name": "s", "layers": [)" + c.layers + "]}}";
    std::fputs(text.c_str(), f);
    std::fclose(f);
    KerasImportOptions options;
    options.architecture_json = json_path;
    auto r = ImportKerasH5(Fixture("keras_weights_w16_67x121.h5"), options);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find(c.expected), std::string::npos) << r.message();
  }
  std::filesystem::remove(json_path);
}

}  // namespace
}  // namespace sfrt::exporter
