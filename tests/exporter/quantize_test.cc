#include "sfrt/exporter/quantize.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "common/unet_spec.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/model.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"
#include "sfrt/sha256.h"
#include "sfrt/shapes.h"

namespace sfrt::exporter {
namespace {

constexpr int kHeight = 32;
constexpr int kWidth = 48;

// Frames of smooth random images (pixel values 0..255, like the raw input SceneEDNet takes).
CalibrationSet RandomFrames(int frames, uint32_t seed, int channels = 12) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> phase(0.0f, 6.28f);
  std::uniform_real_distribution<float> noise(-8.0f, 8.0f);
  CalibrationSet set;
  set.frames = frames;
  set.height = kHeight;
  set.width = kWidth;
  set.channels = channels;
  set.values.resize(static_cast<size_t>(frames) * kHeight * kWidth * channels);
  size_t i = 0;
  for (int f = 0; f < frames; ++f) {
    std::vector<float> p(static_cast<size_t>(channels));
    for (float& v : p) v = phase(rng);
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        for (int c = 0; c < channels; ++c) {
          const float base = 128.0f + 100.0f * std::sin(0.2f * x + 0.15f * y + p[c]);
          set.values[i++] = std::clamp(base + noise(rng), 0.0f, 255.0f);
        }
      }
    }
  }
  return set;
}

std::vector<uint8_t> Bytes(const ModelSpec& spec) {
  auto bytes = SerializeModel(spec);
  EXPECT_TRUE(bytes.ok()) << bytes.message();
  return bytes.ok() ? *bytes : std::vector<uint8_t>{};
}

std::shared_ptr<const Model> LoadSpec(const ModelSpec& spec) {
  const std::vector<uint8_t> bytes = Bytes(spec);
  auto model = Model::LoadBuffer(bytes.data(), bytes.size(), BufferOwnership::kCopy);
  EXPECT_TRUE(model.ok()) << model.message();
  return model.ok() ? *model : nullptr;
}

std::vector<const ConvSpec*> Convs(const ModelSpec& spec) {
  std::vector<const ConvSpec*> convs;
  for (const LayerSpec& l : spec.layers) {
    if (const auto* c = std::get_if<ConvSpec>(&l)) convs.push_back(c);
  }
  return convs;
}

TEST(QuantizeWeights, EveryWeightRoundTripsWithinHalfAQuantumOfItsChannel) {
  constexpr int kOut = 5;
  std::mt19937 rng(3);
  std::normal_distribution<float> dist(0.0f, 1.0f);
  std::vector<float> w(3 * 3 * 7 * kOut);
  const float magnitude[kOut] = {1.0f, 1e-3f, 40.0f, 0.0f, 0.25f};  // channel 3: all zeros
  for (size_t k = 0; k < w.size(); ++k) w[k] = dist(rng) * magnitude[k % kOut];
  std::vector<int8_t> q;
  std::vector<float> scales;
  QuantizeWeights(w, kOut, &q, &scales);
  ASSERT_EQ(q.size(), w.size());
  ASSERT_EQ(scales.size(), static_cast<size_t>(kOut));
  EXPECT_EQ(scales[3], 1.0f);
  for (int o = 0; o < kOut; ++o) {
    float max_abs = 0;
    int max_q = 0;
    for (size_t k = static_cast<size_t>(o); k < w.size(); k += kOut) {
      max_abs = std::max(max_abs, std::fabs(w[k]));
      max_q = std::max(max_q, std::abs(static_cast<int>(q[k])));
      const double back = static_cast<double>(scales[static_cast<size_t>(o)]) * q[k];
      ASSERT_LE(std::fabs(back - w[k]), scales[static_cast<size_t>(o)] * 0.5 * (1 + 1e-6))
          << "channel " << o << " index " << k;
      ASSERT_LE(std::abs(static_cast<int>(q[k])), 127);
    }
    if (max_abs > 0) {
      EXPECT_FLOAT_EQ(scales[static_cast<size_t>(o)], max_abs / 127.0f) << "channel " << o;
      EXPECT_EQ(max_q, 127) << "channel " << o;
    } else {
      EXPECT_EQ(max_q, 0);
    }
  }
}

TEST(ActivationQuantParams, RealZeroIsExactlyRepresentableAndTheRangeIsCovered) {
  struct Case {
    double lo, hi;
  };
  for (const Case& c : {Case{-1.0, 3.0}, Case{2.0, 5.0}, Case{-5.0, -2.0}, Case{-0.3, 0.0},
                        Case{0.0, 17.5}, Case{-1e-3, 250.0}}) {
    const QuantParams q = ActivationQuantParams(c.lo, c.hi);
    const double lo = std::min(c.lo, 0.0);
    const double hi = std::max(c.hi, 0.0);
    ASSERT_GT(q.scale, 0.0f);
    ASSERT_GE(q.zero_point, 0);
    ASSERT_LE(q.zero_point, 255);
    // 0 quantises to the zero point exactly, and the zero point dequantises to 0.
    EXPECT_EQ(std::nearbyint(0.0 / q.scale) + q.zero_point, q.zero_point);
    // q = 0 and q = 255 reach the ends of the range, within one quantum.
    EXPECT_NEAR(q.scale * (0 - q.zero_point), lo, q.scale) << c.lo << ".." << c.hi;
    EXPECT_NEAR(q.scale * (255 - q.zero_point), hi, q.scale) << c.lo << ".." << c.hi;
  }
  EXPECT_EQ(ActivationQuantParams(2.0, 5.0).zero_point, 0);      // lo widened to 0
  EXPECT_EQ(ActivationQuantParams(-5.0, -2.0).zero_point, 255);  // hi widened to 0
  EXPECT_EQ(ActivationQuantParams(0.0, 0.0), (QuantParams{1.0f, 0}));
}

TEST(ParseCalibrationMethod, AcceptsPercentilesFrom50To100AndMinmax) {
  auto p = ParseCalibrationMethod("percentile:99.99");
  ASSERT_TRUE(p.ok()) << p.message();
  EXPECT_EQ(p->percentile, 99.99);
  EXPECT_EQ(p->text, "percentile:99.99");
  auto m = ParseCalibrationMethod("minmax");
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->percentile, 100.0);
  for (const char* bad :
       {"percentile:49", "percentile:101", "percentile:", "percentile:9x", "entropy", ""}) {
    auto r = ParseCalibrationMethod(bad);
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_NE(r.message().find("'" + std::string(bad) + "'"), std::string::npos) << r.message();
  }
}

TEST(Quantize, SameInputsGiveTheSameFileBytesTwice) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(3, 11);
  QuantizeOptions options;
  auto a = Quantize(spec, data, options);
  auto b = Quantize(spec, data, options);
  ASSERT_TRUE(a.ok()) << a.message();
  ASSERT_TRUE(b.ok()) << b.message();
  const std::vector<uint8_t> bytes_a = Bytes(a->spec);
  EXPECT_FALSE(bytes_a.empty());
  EXPECT_EQ(bytes_a, Bytes(b->spec));
}

TEST(Quantize, Int8ModelStaysCloseToFloat32OnASceneEdNetShapedModel) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(4, 21);
  auto result = Quantize(spec, data, {});
  ASSERT_TRUE(result.ok()) << result.message();
  for (const ConvSpec* c : Convs(result->spec)) EXPECT_EQ(c->precision, Precision::kInt8);
  EXPECT_GT(result->calibration.output_rms_rel, 0.0f);
  EXPECT_LT(result->calibration.output_rms_rel, 0.05f);
  EXPECT_LT(result->calibration.output_max_rel, 0.2f);

  // A frame the calibration never saw.
  const CalibrationSet held_out = RandomFrames(1, 99);
  auto fp32 = LoadSpec(spec);
  auto int8 = LoadSpec(result->spec);
  ASSERT_TRUE(fp32 && int8);
  EXPECT_TRUE(int8->metadata().has_int8);
  std::vector<float> a(static_cast<size_t>(kHeight) * kWidth * 3);
  std::vector<float> b(a.size());
  ASSERT_TRUE(RunReferenceForward(*fp32, held_out.values, kHeight, kWidth, a).ok());
  ASSERT_TRUE(RunReferenceForward(*int8, held_out.values, kHeight, kWidth, b).ok());
  double diff2 = 0, ref2 = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    diff2 += (static_cast<double>(b[i]) - a[i]) * (static_cast<double>(b[i]) - a[i]);
    ref2 += static_cast<double>(a[i]) * a[i];
  }
  EXPECT_LT(std::sqrt(diff2 / ref2), 0.05);
}

TEST(Quantize, AnInt8ConvolutionHandsTheNextItsOwnOutputQuantAndTheLoaderAgrees) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  auto result = Quantize(spec, RandomFrames(2, 31), {});
  ASSERT_TRUE(result.ok()) << result.message();
  const std::vector<const ConvSpec*> convs = Convs(result->spec);
  for (size_t j = 0; j + 1 < convs.size(); ++j) {
    EXPECT_EQ(convs[j]->output_quant, convs[j + 1]->input_quant) << convs[j]->name;
  }
  for (const ConvSpec* c : convs) {
    EXPECT_TRUE(c->weights_hwio.empty());
    EXPECT_EQ(c->weights_q.size(), 9u * c->in_channels * c->out_channels);
    EXPECT_GT(c->output_quant.scale, 0.0f);
    // Leaky ReLU outputs are mostly positive but reach below 0: the zero point sits low.
    EXPECT_GE(c->input_quant.zero_point, 0);
    EXPECT_LE(c->input_quant.zero_point, 255);
  }
  EXPECT_NE(LoadSpec(result->spec), nullptr);
}

TEST(Quantize, CalibrationRecordNamesMethodDataAndErrorsAndSurvivesTheFile) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(2, 41);
  QuantizeOptions options;
  options.method = "percentile:99.9";
  auto result = Quantize(spec, data, options);
  ASSERT_TRUE(result.ok()) << result.message();
  ASSERT_TRUE(result->spec.calibration.has_value());
  const CalibrationDesc& cal = result->calibration;
  EXPECT_EQ(cal.method, "percentile:99.9");
  Sha256 sha;
  sha.Update(data.values.data(), data.values.size() * sizeof(float));
  EXPECT_EQ(cal.data_sha256, sha.FinishHex());
  EXPECT_EQ(cal.frames, 2);
  EXPECT_EQ(cal.height, kHeight);
  EXPECT_EQ(cal.width, kWidth);
  ASSERT_EQ(cal.layers.size(), Convs(spec).size());
  EXPECT_EQ(cal.layers.front().layer, "conv0");
  EXPECT_EQ(cal.layers.back().layer, "output");
  for (const LayerErrorDesc& e : cal.layers) {
    EXPECT_EQ(e.precision, Precision::kInt8);
    EXPECT_GT(e.relative_rms, 0.0f) << e.layer;
  }

  auto model = LoadSpec(result->spec);
  ASSERT_NE(model, nullptr);
  ASSERT_TRUE(model->metadata().calibration.has_value());
  const CalibrationDesc& stored = *model->metadata().calibration;
  EXPECT_EQ(stored.method, cal.method);
  EXPECT_EQ(stored.data_sha256, cal.data_sha256);
  EXPECT_EQ(stored.output_rms_rel, cal.output_rms_rel);
  EXPECT_EQ(stored.output_max_rel, cal.output_max_rel);
  ASSERT_EQ(stored.layers.size(), cal.layers.size());
  for (size_t j = 0; j < cal.layers.size(); ++j) {
    EXPECT_EQ(stored.layers[j].layer, cal.layers[j].layer);
    EXPECT_EQ(stored.layers[j].relative_rms, cal.layers[j].relative_rms);
  }
}

TEST(Quantize, ReportsProgressForEveryFrameOfEveryPass) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  QuantizeOptions options;
  std::vector<std::string> calls;
  options.progress = [&](const char* pass, int frame, int frames) {
    calls.push_back(std::string(pass) + " " + std::to_string(frame) + "/" + std::to_string(frames));
  };
  ASSERT_TRUE(Quantize(spec, RandomFrames(2, 51), options).ok());
  EXPECT_EQ(calls, (std::vector<std::string>{"range 1/2", "range 2/2", "histogram 1/2",
                                             "histogram 2/2", "measure 1/2", "measure 2/2"}));
}

// With either engine, frames on several threads, and (session) threads left over going to each
// frame's session: 5 frames on 2, 3 and 8 threads, 1 frame on 2.
TEST(Quantize, TheThreadCountChangesNoByteOfTheResult) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  for (auto [engine, mode, frames] :
       {std::tuple{CalibrationEngine::kSession, QuantizeMode::kInt8, 5},
        std::tuple{CalibrationEngine::kSession, QuantizeMode::kAuto, 5},
        std::tuple{CalibrationEngine::kSession, QuantizeMode::kAuto, 1},
        std::tuple{CalibrationEngine::kReference, QuantizeMode::kInt8, 5},
        std::tuple{CalibrationEngine::kReference, QuantizeMode::kAuto, 5}}) {
    SCOPED_TRACE(std::string(engine == CalibrationEngine::kSession ? "session " : "reference ") +
                 (mode == QuantizeMode::kInt8 ? "int8 " : "auto ") + std::to_string(frames));
    const CalibrationSet data = RandomFrames(frames, 53);
    QuantizeOptions options;
    options.engine = engine;
    options.mode = mode;
    options.accuracy_budget = 1e-2;  // auto: some steps
    auto one = Quantize(spec, data, options);
    ASSERT_TRUE(one.ok()) << one.message();
    for (int threads : {2, 3, 8}) {
      SCOPED_TRACE(threads);
      options.threads = threads;
      auto many = Quantize(spec, data, options);
      ASSERT_TRUE(many.ok()) << many.message();
      EXPECT_EQ(Bytes(many->spec), Bytes(one->spec));
      EXPECT_EQ(many->auto_steps, one->auto_steps);
      EXPECT_EQ(many->calibration.output_max_rel, one->calibration.output_max_rel);
      EXPECT_EQ(many->calibration.output_rms_rel, one->calibration.output_rms_rel);
    }
    if (mode == QuantizeMode::kAuto) {
      EXPECT_FALSE(one->auto_steps.empty());
    }
  }
}

// The session engine computes the float32 layers on other kernels (Winograd, SIMD sums): the
// same weights, ranges within a histogram bin or two of the reference engine's, and the same
// errors to a few percent.
TEST(Quantize, TheSessionEngineFindsTheReferenceEnginesRangesAndErrors) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(3, 61);
  QuantizeOptions options;
  options.engine = CalibrationEngine::kReference;
  auto reference = Quantize(spec, data, options);
  ASSERT_TRUE(reference.ok()) << reference.message();
  options.engine = CalibrationEngine::kSession;
  auto session = Quantize(spec, data, options);
  ASSERT_TRUE(session.ok()) << session.message();
  const std::vector<const ConvSpec*> want = Convs(reference->spec);
  const std::vector<const ConvSpec*> got = Convs(session->spec);
  ASSERT_EQ(got.size(), want.size());
  for (size_t j = 0; j < got.size(); ++j) {
    SCOPED_TRACE(want[j]->name);
    EXPECT_EQ(got[j]->weights_q, want[j]->weights_q);
    for (auto [g, w] : {std::pair{got[j]->input_quant, want[j]->input_quant},
                        std::pair{got[j]->output_quant, want[j]->output_quant}}) {
      EXPECT_NEAR(g.scale, w.scale, 2e-3 * w.scale);
      EXPECT_NEAR(g.zero_point, w.zero_point, 1);
    }
    EXPECT_NEAR(session->calibration.layers[j].relative_rms,
                reference->calibration.layers[j].relative_rms,
                0.05 * reference->calibration.layers[j].relative_rms);
  }
  EXPECT_NEAR(session->calibration.output_rms_rel, reference->calibration.output_rms_rel,
              0.05 * reference->calibration.output_rms_rel);
  EXPECT_NEAR(session->calibration.output_max_rel, reference->calibration.output_max_rel,
              0.05 * reference->calibration.output_max_rel);
}

TEST(Quantize, ThreadsReportEveryFrameOnceInOrderAndZeroThreadsIsAnError) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  QuantizeOptions options;
  options.threads = 2;
  std::vector<std::string> calls;
  options.progress = [&](const char* pass, int frame, int frames) {
    calls.push_back(std::string(pass) + " " + std::to_string(frame) + "/" + std::to_string(frames));
  };
  ASSERT_TRUE(Quantize(spec, RandomFrames(3, 57), options).ok());
  EXPECT_EQ(calls, (std::vector<std::string>{"range 1/3", "range 2/3", "range 3/3", "histogram 1/3",
                                             "histogram 2/3", "histogram 3/3", "measure 1/3",
                                             "measure 2/3", "measure 3/3"}));
  options.threads = 0;
  auto none = Quantize(spec, RandomFrames(3, 57), options);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.message().find("calibration threads 0: must be at least 1"), std::string::npos)
      << none.message();
}

// Per convolution, the largest over its output channels of |the channel's mean error before
// the activation| of `quantised` against `fp32` over `data`, on the reference forward pass (the
// value before the activation recovered by inverting leaky ReLU, as bias correction does).
std::vector<double> LargestChannelMeanErrors(const ModelSpec& fp32, const ModelSpec& quantised,
                                             const CalibrationSet& data) {
  std::vector<int> conv_of_layer;
  std::vector<float> slopes;
  for (const LayerSpec& l : fp32.layers) {
    const auto* c = std::get_if<ConvSpec>(&l);
    conv_of_layer.push_back(c == nullptr ? -1 : static_cast<int>(slopes.size()));
    if (c != nullptr)
      slopes.push_back(c->activation == Activation::kLeakyRelu ? c->leaky_slope : 1);
  }
  // sums[model][conv][channel]
  std::vector<std::vector<std::vector<double>>> sums(
      2, std::vector<std::vector<double>>(slopes.size()));
  const std::shared_ptr<const Model> models[2] = {LoadSpec(fp32), LoadSpec(quantised)};
  std::vector<float> output(static_cast<size_t>(data.height) * data.width * 3);
  const size_t per_frame = static_cast<size_t>(data.height) * data.width * data.channels;
  for (int m = 0; m < 2; ++m) {
    for (int f = 0; f < data.frames; ++f) {
      const LayerObserver add = [&](int layer, const TensorShape& shape,
                                    std::span<const float> values) {
        const int j = conv_of_layer[static_cast<size_t>(layer)];
        if (j < 0) return;
        std::vector<double>& s = sums[m][static_cast<size_t>(j)];
        s.resize(static_cast<size_t>(shape.channels), 0.0);
        for (size_t k = 0; k < values.size(); ++k) {
          const float y = values[k];
          s[k % s.size()] += y >= 0 ? y : static_cast<double>(y) / slopes[static_cast<size_t>(j)];
        }
      };
      const std::span<const float> input(data.values.data() + f * per_frame, per_frame);
      EXPECT_TRUE(
          RunReferenceForward(*models[m], input, data.height, data.width, output, add).ok());
    }
  }
  std::vector<double> largest(slopes.size(), 0.0);
  const double count = static_cast<double>(data.frames) * data.height * data.width;
  for (size_t j = 0; j < slopes.size(); ++j) {
    for (size_t c = 0; c < sums[0][j].size(); ++c) {
      const double mean_error = (sums[1][j][c] - sums[0][j][c]) / count;
      largest[j] = std::max(largest[j], std::fabs(mean_error));
    }
  }
  return largest;
}

// Each int8 convolution's bias absorbs the mean error its channels show (with the layers before
// it corrected), so no channel keeps a mean error: what is left comes from rounding the uint8
// outputs (a mean over few pixels in the deep layers of this small model), under 2% of a
// quantisation step and a tenth of the uncorrected model's in all. The output's error drops.
TEST(Quantize, BiasCorrectionLeavesNoChannelAMeanErrorAndLowersTheOutputsError) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(3, 63);
  QuantizeOptions options;
  auto plain = Quantize(spec, data, options);
  ASSERT_TRUE(plain.ok()) << plain.message();
  options.bias_correction = true;
  auto corrected = Quantize(spec, data, options);
  ASSERT_TRUE(corrected.ok()) << corrected.message();
  EXPECT_EQ(corrected->calibration.method, "percentile:99.99, bias correction");

  const std::vector<double> before = LargestChannelMeanErrors(spec, plain->spec, data);
  const std::vector<double> after = LargestChannelMeanErrors(spec, corrected->spec, data);
  const std::vector<const ConvSpec*> convs = Convs(corrected->spec);
  ASSERT_EQ(after.size(), convs.size());
  for (size_t j = 0; j < convs.size(); ++j) {
    SCOPED_TRACE(convs[j]->name);
    EXPECT_GT(before[j], 0.0);
    if (j + 1 < convs.size()) {  // written as uint8: its rounding is what is left
      EXPECT_LT(after[j], 0.02 * convs[j]->output_quant.scale);
    } else {  // the output convolution writes float32
      EXPECT_LT(after[j], 1e-3 * before[j]);
    }
  }
  EXPECT_LT(std::accumulate(after.begin(), after.end(), 0.0),
            0.1 * std::accumulate(before.begin(), before.end(), 0.0));
  // Only the biases moved.
  const std::vector<const ConvSpec*> plain_convs = Convs(plain->spec);
  for (size_t j = 0; j < convs.size(); ++j) {
    EXPECT_EQ(convs[j]->weights_q, plain_convs[j]->weights_q);
    EXPECT_EQ(convs[j]->output_quant, plain_convs[j]->output_quant);
    EXPECT_NE(convs[j]->bias, plain_convs[j]->bias);
  }
  EXPECT_LT(corrected->calibration.output_rms_rel, plain->calibration.output_rms_rel);
}

TEST(Quantize, BiasCorrectionChangesNoByteWithTheThreadCountAndReportsItsPasses) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(3, 65);
  QuantizeOptions options;
  options.bias_correction = true;
  std::vector<std::string> passes;
  options.progress = [&](const char* pass, int frame, int frames) {
    if (frame == frames) passes.emplace_back(pass);
  };
  auto one = Quantize(spec, data, options);
  ASSERT_TRUE(one.ok()) << one.message();
  std::vector<std::string> want = {"range", "histogram", "bias correction: float32"};
  for (const ConvSpec* c : Convs(spec)) want.push_back("bias correction: " + c->name);
  want.emplace_back("measure");
  EXPECT_EQ(passes, want);
  options.progress = nullptr;
  for (int threads : {2, 3}) {
    SCOPED_TRACE(threads);
    options.threads = threads;
    auto many = Quantize(spec, data, options);
    ASSERT_TRUE(many.ok()) << many.message();
    EXPECT_EQ(Bytes(many->spec), Bytes(one->spec));
  }
}

TEST(Quantize, BiasCorrectionIsRefusedInTheAutoMode) {
  QuantizeOptions options;
  options.mode = QuantizeMode::kAuto;
  options.bias_correction = true;
  auto result = Quantize(exporter::SceneEdNetSpec(16, 5), RandomFrames(1, 67), options);
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.message().find("bias correction is for int8 quantisation"), std::string::npos)
      << result.message();
}

TEST(Quantize, AutoWithAHugeBudgetKeepsEveryConvolutionInt8) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  QuantizeOptions options;
  options.mode = QuantizeMode::kAuto;
  options.accuracy_budget = 1e9;
  auto result = Quantize(spec, RandomFrames(2, 61), options);
  ASSERT_TRUE(result.ok()) << result.message();
  EXPECT_TRUE(result->auto_steps.empty());
  for (const ConvSpec* c : Convs(result->spec)) EXPECT_EQ(c->precision, Precision::kInt8);
}

TEST(Quantize, AutoWithBudgetZeroPutsEveryConvolutionBackToFloat32) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const size_t convs = Convs(spec).size();
  // With the bf16 step (the default) each layer goes int8 -> bf16 -> fp32: two steps each.
  for (bool auto_bf16 : {true, false}) {
    SCOPED_TRACE(auto_bf16 ? "int8 -> bf16 -> fp32" : "int8 -> fp32");
    QuantizeOptions options;
    options.mode = QuantizeMode::kAuto;
    options.accuracy_budget = 0;
    options.auto_bf16 = auto_bf16;
    auto result = Quantize(spec, RandomFrames(2, 71), options);
    ASSERT_TRUE(result.ok()) << result.message();
    EXPECT_EQ(result->auto_steps.size(), auto_bf16 ? 2 * convs : convs);
    for (const ConvSpec* c : Convs(result->spec)) EXPECT_EQ(c->precision, Precision::kFloat32);
    EXPECT_FALSE(result->spec.calibration.has_value());
    EXPECT_EQ(result->calibration.output_rms_rel, 0.0f);
    // Nothing left quantised: the file is the float32 model's.
    EXPECT_EQ(Bytes(result->spec), Bytes(spec));
  }
}

TEST(Quantize, AutoTriesBf16BeforeFloat32AndRecordsIt) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(2, 81);
  auto all = Quantize(spec, data, {});
  ASSERT_TRUE(all.ok()) << all.message();
  QuantizeOptions options;
  options.mode = QuantizeMode::kAuto;
  options.accuracy_budget = all->calibration.output_rms_rel / 2;
  auto result = Quantize(spec, data, options);
  ASSERT_TRUE(result.ok()) << result.message();
  EXPECT_LE(result->calibration.output_rms_rel, options.accuracy_budget);
  ASSERT_FALSE(result->auto_steps.empty());
  EXPECT_NE(result->auto_steps.front().find(" to bf16: "), std::string::npos)
      << result->auto_steps.front();
  size_t bf16 = 0;
  for (const ConvSpec* c : Convs(result->spec)) bf16 += c->precision == Precision::kBFloat16;
  size_t recorded = 0;
  for (const LayerErrorDesc& e : result->calibration.layers) {
    recorded += e.precision == Precision::kBFloat16;
  }
  EXPECT_EQ(recorded, bf16) << "the calibration record names each layer's precision";
  auto model = LoadSpec(result->spec);
  ASSERT_NE(model, nullptr);  // int8, bf16 and fp32 side by side load
  EXPECT_EQ(model->metadata().has_bf16, bf16 > 0);
}

TEST(Quantize, AutoWithoutBf16AndAMiddleBudgetMeetsItWithSomeConvolutionsInt8) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(2, 81);
  auto all = Quantize(spec, data, {});
  ASSERT_TRUE(all.ok()) << all.message();
  QuantizeOptions options;
  options.mode = QuantizeMode::kAuto;
  options.auto_bf16 = false;
  options.accuracy_budget = all->calibration.output_rms_rel / 2;
  auto result = Quantize(spec, data, options);
  ASSERT_TRUE(result.ok()) << result.message();
  EXPECT_LE(result->calibration.output_rms_rel, options.accuracy_budget);
  EXPECT_FALSE(result->auto_steps.empty());
  size_t int8 = 0;
  for (const ConvSpec* c : Convs(result->spec)) int8 += c->precision == Precision::kInt8;
  EXPECT_GT(int8, 0u);
  EXPECT_LT(int8, Convs(spec).size());
  ASSERT_TRUE(result->spec.calibration.has_value());
  EXPECT_NE(LoadSpec(result->spec), nullptr);  // mixed precision: the quant params still chain
}

TEST(Quantize, AutoWithTheMaxMetricHoldsTheLargestErrorWithinTheBudget) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(2, 81);
  auto all = Quantize(spec, data, {});
  ASSERT_TRUE(all.ok()) << all.message();
  QuantizeOptions options;
  options.mode = QuantizeMode::kAuto;
  options.accuracy_metric = AccuracyMetric::kMax;
  // Between the int8 model's rms and largest errors: only the max metric has work to do.
  options.accuracy_budget = (all->calibration.output_rms_rel + all->calibration.output_max_rel) / 2;
  ASSERT_GT(options.accuracy_budget, all->calibration.output_rms_rel);
  ASSERT_LT(options.accuracy_budget, all->calibration.output_max_rel);
  auto result = Quantize(spec, data, options);
  ASSERT_TRUE(result.ok()) << result.message();
  EXPECT_LE(result->calibration.output_max_rel, options.accuracy_budget);
  ASSERT_FALSE(result->auto_steps.empty());
  // The budget's metric picks the layer too: its largest error rose most.
  EXPECT_NE(result->auto_steps.front().find(": output max "), std::string::npos)
      << result->auto_steps.front();
  EXPECT_NE(result->auto_steps.front().find("; its relative max "), std::string::npos)
      << result->auto_steps.front();

  options.accuracy_metric = AccuracyMetric::kRms;
  auto rms = Quantize(spec, data, options);
  ASSERT_TRUE(rms.ok()) << rms.message();
  EXPECT_TRUE(rms->auto_steps.empty()) << "the rms error is within the budget already";
}

TEST(Quantize, RefusesAllConstantFrames) {
  CalibrationSet data = RandomFrames(2, 1);
  for (size_t i = 0; i < data.values.size(); ++i)
    data.values[i] = i < data.values.size() / 2 ? 0 : 7;
  auto r = Quantize(exporter::SceneEdNetSpec(16, 5), data, {});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.message().find("all 2 calibration frames are constant"), std::string::npos)
      << r.message();
}

TEST(Quantize, RefusesANonFiniteValueNamingFrameAndElement) {
  CalibrationSet data = RandomFrames(2, 1);
  const size_t frame = static_cast<size_t>(kHeight) * kWidth * 12;
  data.values[frame + (3 * kWidth + 5) * 12 + 7] = std::numeric_limits<float>::quiet_NaN();
  auto r = Quantize(exporter::SceneEdNetSpec(16, 5), data, {});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.message().find("calibration frame 1, element [3, 5, 7] (flat index " +
                             std::to_string(frame + (3 * kWidth + 5) * 12 + 7) + ") is NaN"),
            std::string::npos)
      << r.message();
  data.values[frame + (3 * kWidth + 5) * 12 + 7] = 1.0f;
  data.values[4] = -std::numeric_limits<float>::infinity();
  r = Quantize(exporter::SceneEdNetSpec(16, 5), data, {});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.message().find("frame 0, element [0, 0, 4] (flat index 4) is infinite"),
            std::string::npos)
      << r.message();
}

TEST(Quantize, RefusesFramesWithTheWrongChannelCountOrNoFrames) {
  auto r = Quantize(exporter::SceneEdNetSpec(16, 5), RandomFrames(1, 1, 3), {});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.message().find("calibration frames have 3 channels but the model's input has 12"),
            std::string::npos)
      << r.message();
  r = Quantize(exporter::SceneEdNetSpec(16, 5), CalibrationSet{0, kHeight, kWidth, 12, {}}, {});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.message().find("the calibration set is empty"), std::string::npos) << r.message();
}

// Relative rms of `b` against `a`.
double RelativeRms(const std::vector<float>& b, const std::vector<float>& a) {
  double diff2 = 0, ref2 = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    diff2 += (static_cast<double>(b[i]) - a[i]) * (static_cast<double>(b[i]) - a[i]);
    ref2 += static_cast<double>(a[i]) * a[i];
  }
  return std::sqrt(diff2 / ref2);
}

// A graph (SceneEDNet-U's skips: Concats of upsampled and cropped decoder tensors with encoder
// ones), with a range per tensor: each convolution is calibrated on the tensor whose values it
// reads, a Concat's when it reads one, through upsamplings and crops otherwise; conv9, which reads
// a crop of an upsampling, gets phase kernels; the int8 model stays close to float32 on a frame the
// calibration never saw.
TEST(Quantize, Int8GraphIsCalibratedOnWhatEachConvolutionReads) {
  const ModelSpec spec = testing::SceneEdNetUSpec(16, 5);
  QuantizeOptions per_tensor;
  per_tensor.shared_scales = false;
  auto result = Quantize(spec, RandomFrames(4, 21), per_tensor);
  ASSERT_TRUE(result.ok()) << result.message();
  const std::vector<const ConvSpec*> convs = Convs(result->spec);
  ASSERT_EQ(convs.size(), 11u);
  for (const ConvSpec* c : convs) {
    EXPECT_EQ(c->precision, Precision::kInt8) << c->name;
    EXPECT_EQ(c->phase_weights_q.empty(), c->name != "conv9") << c->name;
  }
  // conv1 reads conv0's output; conv6 reads cat1 (a Concat of conv2 and an upsampled tensor),
  // whose range is neither conv2's nor conv5's.
  EXPECT_EQ(convs[0]->output_quant, convs[1]->input_quant);
  EXPECT_NE(convs[6]->input_quant, convs[5]->output_quant);
  EXPECT_LT(result->calibration.output_rms_rel, 0.05f);

  const CalibrationSet held_out = RandomFrames(1, 99);
  auto fp32 = LoadSpec(spec);
  auto int8 = LoadSpec(result->spec);
  ASSERT_TRUE(fp32 && int8);
  EXPECT_TRUE(int8->float32_between_layers());
  std::vector<float> a(static_cast<size_t>(kHeight) * kWidth * 3);
  std::vector<float> b(a.size());
  ASSERT_TRUE(RunReferenceForward(*fp32, held_out.values, kHeight, kWidth, a).ok());
  ASSERT_TRUE(RunReferenceForward(*int8, held_out.values, kHeight, kWidth, b).ok());
  EXPECT_LT(RelativeRms(b, a), 0.05);
}

// In SceneEDNet-U, conv1 and conv8 read conv0's output (conv8 through cat3), conv2 and conv7
// conv1's (through cat2), and conv3, conv4 and conv6 read conv2's and conv3's (conv6 through
// cat1, whose upsampled half comes from cat4 = conv5 ++ conv3). conv0 reads the model input,
// conv5 conv4's output, conv9 conv8's through up4, the output conv9's: groups of one. In a chain
// every convolution is a group of its own.
TEST(SharedScaleGroups, GroupsTheConvolutionsThatReadOneTensorThroughCopies) {
  for (const auto& [spec, want] : {std::pair{testing::SceneEdNetUSpec(16, 5),
                                             std::vector<int>{0, 1, 2, 3, 3, 5, 3, 2, 1, 9, 10}},
                                   std::pair{exporter::SceneEdNetSpec(16, 5),
                                             std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10}}}) {
    SCOPED_TRACE(spec.name);
    auto model = LoadSpec(spec);
    ASSERT_NE(model, nullptr);
    std::vector<int> convs;
    for (size_t i = 0; i < model->layers().size(); ++i) {
      if (model->layers()[i].kind == LayerKind::kConv2D) convs.push_back(static_cast<int>(i));
    }
    EXPECT_EQ(SharedScaleGroups(model->layers(), convs), want);
  }
}

// With shared scales (the default) the convolutions of a group read one quantisation, whose range
// covers each member's own, and a session keeps every tensor between them uint8: it quantises
// only the model input, where with a range per tensor it converts float32 before most
// convolutions. The output stays as close to float32.
TEST(Quantize, SharedScalesLetASessionKeepSceneEdNetUTensorsUint8) {
  const ModelSpec spec = testing::SceneEdNetUSpec(16, 5);
  const CalibrationSet frames = RandomFrames(4, 21);
  QuantizeOptions per_tensor;
  per_tensor.shared_scales = false;
  auto own = Quantize(spec, frames, per_tensor);
  auto shared = Quantize(spec, frames, {});
  ASSERT_TRUE(own.ok()) << own.message();
  ASSERT_TRUE(shared.ok()) << shared.message();
  const std::vector<const ConvSpec*> a = Convs(own->spec);
  const std::vector<const ConvSpec*> b = Convs(shared->spec);
  ASSERT_EQ(b.size(), 11u);
  for (int j : {4, 6}) EXPECT_EQ(b[static_cast<size_t>(j)]->input_quant, b[3]->input_quant);
  EXPECT_EQ(b[7]->input_quant, b[2]->input_quant);
  EXPECT_EQ(b[8]->input_quant, b[1]->input_quant);
  for (size_t j = 0; j < b.size(); ++j) {
    // The shared range [lo, hi] holds each member's own.
    const QuantParams& mine = a[j]->input_quant;
    const QuantParams& group = b[j]->input_quant;
    const double lo = -mine.scale * mine.zero_point, hi = mine.scale * (255 - mine.zero_point);
    const double glo = -group.scale * group.zero_point;
    const double ghi = group.scale * (255 - group.zero_point);
    EXPECT_LE(glo, lo + group.scale) << b[j]->name;
    EXPECT_GE(ghi, hi - group.scale) << b[j]->name;
  }
  EXPECT_LT(shared->calibration.output_rms_rel, 0.05f);
  EXPECT_EQ(shared->calibration.method, "percentile:99.99, shared scales");
  EXPECT_EQ(own->calibration.method, "percentile:99.99");

  auto converting_steps = [](const ModelSpec& quantised) {
    auto model = LoadSpec(quantised);
    SessionOptions options;
    options.max_height = kHeight;
    options.max_width = kWidth;
    auto session = Session::Create(model, options);
    EXPECT_TRUE(session.ok()) << session.message();
    int n = 0;
    if (session.ok()) {
      for (const PlannedStep& step : (*session)->steps()) n += step.quantize ? 1 : 0;
    }
    return n;
  };
  EXPECT_EQ(converting_steps(shared->spec), 1);
  EXPECT_GT(converting_steps(own->spec), 4);
}

// A dilated convolution has no int8 form: it stays float32 while the others become int8.
TEST(Quantize, DilatedConvolutionsStayFloat32BesideInt8Ones) {
  ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  auto& c1 = std::get<ConvSpec>(spec.layers[1]);
  c1.dilation_h = c1.dilation_w = 2;
  auto result = Quantize(spec, RandomFrames(2, 21), {});
  ASSERT_TRUE(result.ok()) << result.message();
  const std::vector<const ConvSpec*> convs = Convs(result->spec);
  for (const ConvSpec* c : convs) {
    EXPECT_EQ(c->precision, c == convs[1] ? Precision::kFloat32 : Precision::kInt8) << c->name;
  }
  EXPECT_FALSE(convs[1]->weights_hwio.empty());
  EXPECT_NE(LoadSpec(result->spec), nullptr);
}

TEST(Quantize, RefusesAModelThatIsAlreadyInt8) {
  const ModelSpec spec = exporter::SceneEdNetSpec(16, 5);
  const CalibrationSet data = RandomFrames(1, 2);
  auto once = Quantize(spec, data, {});
  ASSERT_TRUE(once.ok()) << once.message();
  auto twice = Quantize(once->spec, data, {});
  ASSERT_FALSE(twice.ok());
  EXPECT_NE(twice.message().find("layer 0 'conv0' is already int8"), std::string::npos)
      << twice.message();
}

}  // namespace
}  // namespace sfrt::exporter
