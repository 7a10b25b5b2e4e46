// Session::Work (session.h, StepWork): each planned step's multiply-accumulates and bytes, for
// sfrt bench's roofline, against a per-pixel count written for clarity: every output pixel of a
// fused upsample->3x3 convolution with phase kernels is visited, and those whose window lies
// inside the upsampled map take 4 taps, the others 9.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "common/bf16_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/session.h"
#include "sfrt/shapes.h"

namespace sfrt {
namespace {

std::unique_ptr<Session> MakeSession(std::shared_ptr<const Model> model, Isa isa, int h, int w) {
  SessionOptions options;
  options.isa = isa;
  options.max_height = h;
  options.max_width = w;
  auto session = Session::Create(std::move(model), options);
  EXPECT_TRUE(session.ok()) << session.message();
  return session.ok() ? std::move(session).value() : nullptr;
}

// The step's MACs counted pixel by pixel: a phase pixel (3x3 window inside C, the upsampled and
// cropped map the convolution reads) takes 4 taps, every other pixel 9.
uint64_t CountPhaseMacs(const std::vector<LayerGeometry>& g, const PlannedStep& step,
                        const ConvParams& p) {
  const LayerGeometry& conv = g[static_cast<size_t>(step.last_layer)];
  const TensorShape& c = g[static_cast<size_t>(step.last_layer - 1)].output;  // upsample or crop
  uint64_t taps = 0;
  for (int oy = 0; oy < conv.output.height; ++oy) {
    for (int ox = 0; ox < conv.output.width; ++ox) {
      const int cy = oy - conv.pads.top;
      const int cx = ox - conv.pads.left;
      const bool inside = cy >= 0 && cy + 3 <= c.height && cx >= 0 && cx + 3 <= c.width;
      taps += inside ? 4 : 9;
    }
  }
  return taps * static_cast<uint64_t>(p.in_channels) * static_cast<uint64_t>(p.out_channels);
}

bool IsUpConv(const PlannedStep& step) {
  return std::string(step.kernel).rfind("upconv", 0) == 0 ||
         std::string(step.kernel).find("UpConv") != std::string::npos;
}

// Checks every step of `model` on `isa` at h x w; returns how many phase steps it saw.
int ExpectWorkMatchesTheCount(std::shared_ptr<const Model> model, Isa isa, int h, int w) {
  auto session = MakeSession(model, isa, h, w);
  if (session == nullptr) return 0;
  std::vector<LayerGeometry> g(model->layers().size());
  EXPECT_TRUE(InferGeometry(*model, h, w, g).ok());
  auto work = session->Work(h, w);
  EXPECT_TRUE(work.ok()) << work.message();
  if (!work.ok()) return 0;
  EXPECT_EQ(work->size(), session->steps().size());
  int phase_steps = 0;
  uint64_t nominal = 0;
  uint64_t actual = 0;
  for (size_t k = 0; k < work->size(); ++k) {
    const PlannedStep& step = session->steps()[k];
    const StepWork& sw = (*work)[k];
    const std::string what = std::string(IsaName(isa)) + " step " + std::to_string(k) + " " +
                             step.kernel + " at " + std::to_string(h) + "x" + std::to_string(w);
    actual += sw.macs;
    if (step.quantize) {
      EXPECT_EQ(sw.macs, 0u) << what;
      EXPECT_EQ(sw.bytes_read, sw.bytes_written * (step.precision == Precision::kInt8 ? 4 : 2))
          << what << ": a float32 tensor converted to uint8 or bf16";
      continue;
    }
    const LayerDesc& layer = model->layers()[static_cast<size_t>(step.last_layer)];
    uint64_t step_nominal = 0;
    for (int i = step.first_layer; i <= step.last_layer; ++i) {
      step_nominal += g[static_cast<size_t>(i)].macs;
    }
    nominal += step_nominal;
    if (layer.kind != LayerKind::kConv2D) {
      EXPECT_EQ(sw.macs, 0u) << what;
      continue;
    }
    const ConvParams& p = layer.conv;
    const uint64_t elt = step.precision == Precision::kInt8       ? 1
                         : step.precision == Precision::kBFloat16 ? 2
                                                                  : 4;
    const uint64_t per_tap = static_cast<uint64_t>(p.in_channels) * p.out_channels;
    const uint64_t plain = 9 * per_tap * elt;
    if (IsUpConv(step) && step.last_layer > step.first_layer) {
      ++phase_steps;
      EXPECT_EQ(sw.macs, CountPhaseMacs(g, step, p)) << what;
      EXPECT_LT(sw.macs, step_nominal) << what;
      EXPECT_EQ(sw.weight_bytes, plain + 16 * per_tap * elt) << what << ": 3x3 and phase kernels";
      // It reads the low-resolution map, never the upsampled one.
      const LayerDesc& up = model->layers()[static_cast<size_t>(step.first_layer)];
      const TensorShape& low = up.inputs[0] == kModelInput
                                   ? g.front().input
                                   : g[static_cast<size_t>(up.inputs[0])].output;
      EXPECT_EQ(sw.bytes_read, low.elements() * elt) << what;
    } else {
      EXPECT_EQ(sw.macs, step_nominal) << what;
      EXPECT_EQ(sw.weight_bytes, static_cast<uint64_t>(p.kernel_h) * p.kernel_w * per_tap * elt)
          << what;
    }
    EXPECT_GT(sw.bytes_written, 0u) << what;
  }
  if (phase_steps > 0) {
    EXPECT_LT(actual, nominal) << IsaName(isa);
  }
  return phase_steps;
}

TEST(SessionWork, Int8StepsCountPhasePixelsAtFourTapsOnEveryIsa) {
  auto model = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16)));
  ASSERT_NE(model, nullptr);
  for (Isa isa : SupportedIsas()) {
    // 45x61: odd, so the decoder crops and pads oddly.
    for (auto [h, w] : {std::pair{96, 128}, std::pair{45, 61}}) {
      const int phase_steps = ExpectWorkMatchesTheCount(model, isa, h, w);
      if (isa != Isa::kRef) {
        EXPECT_EQ(phase_steps, 4) << IsaName(isa) << ": conv6-conv9 fused";
      }
    }
  }
}

TEST(SessionWork, Bf16AndFloat32StepsCountTheSameWay) {
  for (bool bf16 : {false, true}) {
    exporter::ModelSpec spec = exporter::SceneEdNetSpec(16);
    auto model = testing::LoadOrDie(bf16 ? testing::Bf16Spec(spec) : spec);
    ASSERT_NE(model, nullptr);
    for (Isa isa : SupportedIsas()) ExpectWorkMatchesTheCount(model, isa, 45, 61);
  }
}

TEST(SessionWork, TheReferencePlanDoesTheNominalWork) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  ASSERT_NE(model, nullptr);
  auto session = MakeSession(model, Isa::kRef, 96, 128);
  ASSERT_NE(session, nullptr);
  auto work = session->Work(96, 128);
  ASSERT_TRUE(work.ok()) << work.message();
  auto geometry = InferGeometry(*model, 96, 128);
  ASSERT_TRUE(geometry.ok());
  uint64_t nominal = 0, actual = 0;
  for (const LayerGeometry& g : *geometry) nominal += g.macs;
  for (const StepWork& w : *work) actual += w.macs;
  EXPECT_EQ(actual, nominal);
  // The input is read once, as float32, by the first step.
  EXPECT_EQ((*work)[0].bytes_read, uint64_t{96} * 128 * 12 * 4);
}

TEST(SessionWork, ASizeBeyondThePlannedMaximumIsRefusedNamingBoth) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  ASSERT_NE(model, nullptr);
  auto session = MakeSession(model, BestIsa(), 48, 64);
  ASSERT_NE(session, nullptr);
  auto work = session->Work(96, 64);
  ASSERT_FALSE(work.ok());
  EXPECT_NE(work.message().find("96x64 exceeds the session's maximum 48x64"), std::string::npos)
      << work.message();
}

}  // namespace
}  // namespace sfrt
