// Session::Work (session.h, StepWork): each planned step's multiply-accumulates and bytes, for
// sfrt bench's roofline, against a per-pixel count written for clarity: every output pixel of a
// fused upsample->3x3 convolution with phase kernels is visited, and those whose window lies
// inside the upsampled map take 4 taps, the others 9 (on the Winograd phase path, the tiles of
// the low-resolution pixels they read take 9 products per phase); a Winograd step takes (m+2)^2
// products per m x m tile.
#include <gtest/gtest.h>

#include <algorithm>
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

std::unique_ptr<Session> MakeSession(std::shared_ptr<const Model> model, Isa isa, int h, int w,
                                     const KernelTuning& tuning = {}) {
  SessionOptions options;
  options.tuning = tuning;
  options.isa = isa;
  options.max_height = h;
  options.max_width = w;
  auto session = Session::Create(std::move(model), options);
  EXPECT_TRUE(session.ok()) << session.message();
  return session.ok() ? std::move(session).value() : nullptr;
}

bool Named(const PlannedStep& step, const char* part) {
  return std::string(step.kernel).find(part) != std::string::npos;
}

// The step's MACs counted pixel by pixel: a phase pixel (3x3 window inside C, the upsampled and
// cropped map the convolution reads) takes 4 taps, every other pixel 9. On the Winograd phase
// path the phase pixels take none; instead each 2x2 tile of the low-resolution rows and columns
// they read takes 9 products for each of the 4 phases.
uint64_t CountPhaseMacs(const std::vector<LayerGeometry>& g, const PlannedStep& step,
                        const ConvParams& p) {
  const LayerGeometry& conv = g[static_cast<size_t>(step.last_layer)];
  const LayerGeometry& before = g[static_cast<size_t>(step.last_layer - 1)];  // upsample or crop
  const TensorShape& c = before.output;
  const bool cropped = step.last_layer - 1 > step.first_layer;
  const int crop_top = cropped ? before.crop.top : 0;
  const int crop_left = cropped ? before.crop.left : 0;
  const bool winograd = Named(step, "winograd");
  uint64_t taps = 0;
  int row_lo = 1 << 30, row_hi = -1, col_lo = 1 << 30, col_hi = -1;
  for (int oy = 0; oy < conv.output.height; ++oy) {
    for (int ox = 0; ox < conv.output.width; ++ox) {
      const int cy = oy - conv.pads.top;
      const int cx = ox - conv.pads.left;
      const bool inside = cy >= 0 && cy + 3 <= c.height && cx >= 0 && cx + 3 <= c.width;
      taps += inside ? (winograd ? 0 : 4) : 9;
      if (inside) {  // the low-resolution pixel its phase kernel starts at
        row_lo = std::min(row_lo, (cy + crop_top) / 2);
        row_hi = std::max(row_hi, (cy + crop_top) / 2);
        col_lo = std::min(col_lo, (cx + crop_left) / 2);
        col_hi = std::max(col_hi, (cx + crop_left) / 2);
      }
    }
  }
  if (winograd && row_hi >= 0) {
    const int tiles = ((row_hi - row_lo + 2) / 2) * ((col_hi - col_lo + 2) / 2);
    taps += static_cast<uint64_t>(tiles) * 9 * 4;
  }
  return taps * static_cast<uint64_t>(p.in_channels) * static_cast<uint64_t>(p.out_channels);
}

// A plain Winograd F(m x m, 3 x 3) step: (m + 2)^2 products per m x m output tile.
uint64_t CountWinogradMacs(const LayerGeometry& conv, const PlannedStep& step,
                           const ConvParams& p) {
  const int m = Named(step, "_f4x4_") ? 4 : 2;
  const uint64_t tiles = static_cast<uint64_t>((conv.output.height + m - 1) / m) *
                         static_cast<uint64_t>((conv.output.width + m - 1) / m);
  return tiles * static_cast<uint64_t>((m + 2) * (m + 2)) * static_cast<uint64_t>(p.in_channels) *
         static_cast<uint64_t>(p.out_channels);
}

bool IsUpConv(const PlannedStep& step) {
  return std::string(step.kernel).rfind("upconv", 0) == 0 ||
         std::string(step.kernel).find("UpConv") != std::string::npos;
}

// Checks every step of `model` on `isa` at h x w; returns how many phase steps it saw.
int ExpectWorkMatchesTheCount(std::shared_ptr<const Model> model, Isa isa, int h, int w,
                              const KernelTuning& tuning = {}) {
  auto session = MakeSession(model, isa, h, w, tuning);
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
      // The 3x3 kernel (the border) and the phase kernels: 4 taps each, or on the Winograd path
      // their 3x3 transformed points.
      const uint64_t phase_taps = Named(step, "winograd") ? 4 * 9 : 4 * 4;
      EXPECT_EQ(sw.weight_bytes, plain + phase_taps * per_tap * elt) << what;
      // It reads the low-resolution map, never the upsampled one.
      const LayerDesc& up = model->layers()[static_cast<size_t>(step.first_layer)];
      const TensorShape& low = up.inputs[0] == kModelInput
                                   ? g.front().input
                                   : g[static_cast<size_t>(up.inputs[0])].output;
      EXPECT_EQ(sw.bytes_read, low.elements() * elt) << what;
    } else if (Named(step, "winograd")) {
      EXPECT_EQ(sw.macs, CountWinogradMacs(g[static_cast<size_t>(step.last_layer)], step, p))
          << what;
      const uint64_t points = Named(step, "_f4x4_") ? 36 : 16;
      EXPECT_EQ(sw.weight_bytes, points * per_tap * 4) << what << ": the transformed kernels";
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

// Float32 on every Winograd setting: the tile chosen per layer with the phases' F(2x2, 2x2) (the
// default), F(2x2, 3x3), F(4x4, 3x3), direct phases only, and no Winograd. 1/4 width: the phases'
// Winograd path needs 64 channels in and out (conv6 and conv7 have them).
TEST(SessionWork, WinogradStepsCountTheirTransformedProducts) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(4));
  ASSERT_NE(model, nullptr);
  KernelTuning f2, f4, direct_phases, off;
  f2.winograd_tile = 2;
  f4.winograd_tile = 4;
  direct_phases.winograd_upconv = false;
  off.winograd_tile = 0;
  for (Isa isa : SupportedIsas()) {
    for (const KernelTuning& tuning : {KernelTuning{}, f2, f4, direct_phases, off}) {
      for (auto [h, w] : {std::pair{96, 128}, std::pair{45, 61}}) {
        ExpectWorkMatchesTheCount(model, isa, h, w, tuning);
      }
    }
    if (isa == Isa::kRef) continue;
    // The default plan has both kinds of Winograd step, so the counts above covered them.
    auto session = MakeSession(model, isa, 96, 128);
    ASSERT_NE(session, nullptr);
    int plain = 0, phases = 0;
    for (const PlannedStep& step : session->steps()) {
      plain += Named(step, "conv2d_winograd");
      phases += Named(step, "upconv2x_conv3x3_winograd");
    }
    EXPECT_GT(plain, 0) << IsaName(isa);
    EXPECT_GT(phases, 0) << IsaName(isa);
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

// RunQuantized's work: the input's quantise step moves nothing; every other step is Run()'s.
TEST(SessionWork, TheQuantisedInputsWorkLeavesOutTheInputsQuantiseStep) {
  auto model = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16)));
  ASSERT_NE(model, nullptr);
  auto session = MakeSession(model, BestIsa(), 48, 64);
  ASSERT_NE(session, nullptr);
  auto run = session->Work(48, 64);
  auto quantized = session->Work(48, 64, true);
  ASSERT_TRUE(run.ok() && quantized.ok());
  int skipped = 0;
  for (size_t k = 0; k < run->size(); ++k) {
    const StepWork& a = (*run)[k];
    const StepWork& b = (*quantized)[k];
    if (k == 0) {
      ASSERT_TRUE(session->steps()[0].quantize);
      EXPECT_EQ(a.bytes_read, uint64_t{48} * 64 * 12 * 4);
      EXPECT_EQ(b.bytes(), 0u);
      ++skipped;
      continue;
    }
    EXPECT_EQ(a.macs, b.macs) << k;
    EXPECT_EQ(a.bytes(), b.bytes()) << k;
  }
  EXPECT_EQ(skipped, 1);
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
