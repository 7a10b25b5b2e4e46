// Session::RunObserved: which layers it shows, in what order, and that each shown tensor is the
// one the reference forward pass computes for that layer (the exporter calibrates on it).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "common/bf16_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "common/session_compare.h"
#include "common/unet_spec.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/reference.h"
#include "sfrt/session.h"

namespace sfrt {
namespace {

using LayerValues = std::map<int, std::vector<float>>;

LayerValues ReferenceLayers(const Model& model, const std::vector<float>& input, int h, int w) {
  LayerValues layers;
  const LayerObserver keep = [&](int layer, const TensorShape&, std::span<const float> values) {
    layers[layer].assign(values.begin(), values.end());
  };
  auto shape = InferOutputShape(model, h, w);
  EXPECT_TRUE(shape.ok()) << shape.message();
  std::vector<float> out(shape.ok() ? shape->elements() : 0);
  const Status s = RunReferenceForward(model, input, h, w, out, keep);
  EXPECT_TRUE(s.ok()) << s.message();
  return layers;
}

// The layers a session's steps end in, but the converting steps: what RunObserved may show (all
// but an upsampling that writes only its crop into a Concat in place).
std::vector<int> StepLayers(const Session& session) {
  std::vector<int> layers;
  for (const PlannedStep& step : session.steps()) {
    if (!step.quantize) layers.push_back(step.last_layer);
  }
  return layers;
}

// Largest |got - want| over the layer, relative to its largest |want|; with `quant` (a tensor the
// session may hold as uint8 where the reference holds float32), the difference to the nearer of
// want and want clamped to the uint8 range, less one quantisation step (the rounding of a value
// on a tie may differ), counts.
double LayerError(std::span<const float> got, const std::vector<float>& want,
                  const QuantParams* quant) {
  if (got.size() != want.size()) return INFINITY;
  double max_ref = 0, max_err = 0;
  for (size_t k = 0; k < want.size(); ++k) {
    double e = std::fabs(static_cast<double>(got[k]) - want[k]);
    if (quant != nullptr) {
      const double lo = quant->scale * (0.0 - quant->zero_point);
      const double hi = quant->scale * (255.0 - quant->zero_point);
      const double clamped = std::clamp(static_cast<double>(want[k]), lo, hi);
      e = std::min(e, std::fabs(got[k] - clamped));
      e = std::max(0.0, e - quant->scale);
    }
    max_err = std::max(max_err, e);
    max_ref = std::max(max_ref, std::fabs(static_cast<double>(want[k])));
  }
  return max_ref > 0 ? max_err / max_ref : max_err;
}

// On every ISA with 1 and 2 threads at h x w: RunObserved shows step layers (StepLayers) once
// each, in step order, every convolution, Concat and the output layer among them, each with its
// shape and within `tolerance` (LayerError) of the reference forward's tensor for that layer,
// and gives Run()'s output.
void ExpectObservedLayersMatchTheReference(const exporter::ModelSpec& spec, int h, int w,
                                           double tolerance, const QuantParams* quant = nullptr) {
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  const std::vector<float> input = testing::RandomImage(h, w, 12, 5);
  const LayerValues want = ReferenceLayers(*model, input, h, w);
  for (Isa isa : SupportedIsas()) {
    for (int threads : {1, 2}) {
      SCOPED_TRACE(std::string(IsaName(isa)) + " x" + std::to_string(threads));
      SessionOptions options;
      options.isa = isa;
      options.threads = threads;
      options.max_height = h;
      options.max_width = w;
      auto session = Session::Create(model, options);
      ASSERT_TRUE(session.ok()) << session.message();
      auto out_shape = (*session)->OutputShape(h, w);
      ASSERT_TRUE(out_shape.ok()) << out_shape.message();
      std::vector<float> observed_out(out_shape->elements(), NAN);
      std::vector<float> run_out(out_shape->elements(), NAN);
      std::vector<int> shown;
      const auto geometry = InferGeometry(*model, h, w);
      ASSERT_TRUE(geometry.ok()) << geometry.message();
      const LayerObserver check = [&](int layer, const TensorShape& shape,
                                      std::span<const float> values) {
        shown.push_back(layer);
        const TensorShape& expected = (*geometry)[static_cast<size_t>(layer)].output;
        EXPECT_EQ(shape.height, expected.height) << "layer " << layer;
        EXPECT_EQ(shape.width, expected.width) << "layer " << layer;
        EXPECT_EQ(shape.channels, expected.channels) << "layer " << layer;
        EXPECT_EQ(values.size(), expected.elements()) << "layer " << layer;
        const auto it = want.find(layer);
        ASSERT_NE(it, want.end()) << "layer " << layer;
        EXPECT_LE(LayerError(values, it->second, quant), tolerance)
            << "layer " << layer << " '" << model->layers()[static_cast<size_t>(layer)].name << "'";
      };
      const Status s = (*session)->RunObserved(input, h, w, observed_out, check);
      ASSERT_TRUE(s.ok()) << s.message();
      // In step order, each once; every convolution and Concat, and the output layer.
      const std::vector<int> steps = StepLayers(**session);
      EXPECT_TRUE(std::includes(steps.begin(), steps.end(), shown.begin(), shown.end()));
      EXPECT_TRUE(std::adjacent_find(shown.begin(), shown.end(), std::greater_equal<>()) ==
                  shown.end());
      const auto layers = model->layers();
      for (size_t i = 0; i < layers.size(); ++i) {
        if (layers[i].kind != LayerKind::kConv2D && layers[i].kind != LayerKind::kConcat &&
            i + 1 != layers.size()) {
          continue;
        }
        EXPECT_EQ(std::count(shown.begin(), shown.end(), static_cast<int>(i)), 1)
            << "layer " << i << " '" << layers[i].name << "'";
      }
      ASSERT_TRUE((*session)->Run(input, h, w, run_out).ok());
      EXPECT_EQ(std::memcmp(observed_out.data(), run_out.data(), run_out.size() * sizeof(float)),
                0);
    }
  }
}

TEST(SessionObserver, Float32ChainShowsEachStepsLayerAsTheReferenceComputesIt) {
  // Winograd and SIMD sums in another order than the scalar reference.
  ExpectObservedLayersMatchTheReference(exporter::SceneEdNetSpec(16), 45, 61, 1e-4);
}

TEST(SessionObserver, Int8ChainShowsTheReferencesTensorsBitForBit) {
  // uint8 tensors dequantised as the reference does, int8 sums exact, the same epilogue.
  ExpectObservedLayersMatchTheReference(testing::Int8Spec(exporter::SceneEdNetSpec(16)), 45, 61,
                                        0.0);
}

TEST(SessionObserver, Bf16ChainShowsTensorsNearTheReferences) {
  ExpectObservedLayersMatchTheReference(testing::Bf16Spec(exporter::SceneEdNetSpec(16)), 45, 61,
                                        1e-2);
}

TEST(SessionObserver, Float32GraphShowsConcatsAndConvolutionsAsTheReferenceComputesThem) {
  ExpectObservedLayersMatchTheReference(testing::SceneEdNetUSpec(16), 37, 53, 1e-4);
}

TEST(SessionObserver, Int8GraphShowsItsUint8TensorsDequantisedWithinAStepOfTheReference) {
  // The reference forward of a graph keeps float32 between layers where the session keeps the
  // uint8 tensor every reader would have quantised it to; Concats in place are shown whole.
  const QuantParams hidden{4.0f / 255.0f, 77};
  const exporter::ModelSpec spec = testing::Int8Spec(testing::SceneEdNetUSpec(16));
  ExpectObservedLayersMatchTheReference(spec, 37, 53, 1e-5, &hidden);
}

TEST(SessionObserver, Bf16GraphShowsItsBf16TensorsAndConcatsInPlaceNearTheReferences) {
  ExpectObservedLayersMatchTheReference(testing::Bf16Spec(testing::SceneEdNetUSpec(16, 2)), 37, 53,
                                        1e-2);
}

TEST(SessionObserver, AnEmptyObserverRunsAsRunAndAnOversizedInputFailsAlike) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  ASSERT_NE(model, nullptr);
  SessionOptions options;
  options.max_height = 24;
  options.max_width = 32;
  auto session = Session::Create(model, options);
  ASSERT_TRUE(session.ok()) << session.message();
  const std::vector<float> input = testing::RandomImage(24, 32, 12, 3);
  auto shape = (*session)->OutputShape(24, 32);
  ASSERT_TRUE(shape.ok()) << shape.message();
  std::vector<float> a(shape->elements(), NAN), b(shape->elements(), NAN);
  ASSERT_TRUE((*session)->RunObserved(input, 24, 32, a, {}).ok());
  ASSERT_TRUE((*session)->Run(input, 24, 32, b).ok());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
  int calls = 0;
  const LayerObserver count = [&](int, const TensorShape&, std::span<const float>) { ++calls; };
  const Status s = (*session)->RunObserved(input, 48, 32, a, count);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("outside the session's planned range"), std::string::npos)
      << s.message();
  EXPECT_EQ(calls, 0);
}

}  // namespace
}  // namespace sfrt
