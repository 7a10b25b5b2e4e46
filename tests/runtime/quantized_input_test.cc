// The uint8 input path (Session::InputQuantization, QuantizeInput, RunQuantized): an input
// quantised by QuantizeInput gives Run()'s output bit for bit on every ISA, special values
// included, and sessions that cannot take it say so.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "common/session_compare.h"
#include "common/unet_spec.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/session.h"

namespace sfrt {
namespace {

std::unique_ptr<Session> Make(std::shared_ptr<const Model> model, Isa isa, int threads) {
  SessionOptions options;
  options.isa = isa;
  options.threads = threads;
  options.max_height = 96;
  options.max_width = 128;
  auto session = Session::Create(std::move(model), options);
  EXPECT_TRUE(session.ok()) << session.message();
  return session.ok() ? std::move(session).value() : nullptr;
}

// A camera-like input with the values a quantiser must get right at its edges.
std::vector<float> InputWithSpecialValues(int h, int w) {
  std::vector<float> in = testing::RandomImage(h, w, 12, 11);
  const float specials[] = {std::numeric_limits<float>::quiet_NaN(),
                            std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity(),
                            1e30f,
                            -1e30f,
                            0.0f,
                            -0.0f,
                            255.0f,
                            0.5f,
                            1.5f,
                            2.5f};
  for (size_t i = 0; i < std::size(specials) && i * 37 < in.size(); ++i) {
    in[i * 37] = specials[i];
  }
  return in;
}

void ExpectRunQuantizedIsRun(const std::shared_ptr<const Model>& model) {
  for (Isa isa : SupportedIsas()) {
    for (int threads : {1, 2}) {
      auto session = Make(model, isa, threads);
      ASSERT_NE(session, nullptr);
      const std::optional<QuantParams> q = session->InputQuantization();
      ASSERT_TRUE(q.has_value()) << IsaName(isa);
      for (auto [h, w] : {std::pair{96, 128}, std::pair{45, 61}}) {
        const std::string what = std::string(IsaName(isa)) + " x" + std::to_string(threads) +
                                 " at " + std::to_string(h) + "x" + std::to_string(w);
        const std::vector<float> input = InputWithSpecialValues(h, w);
        std::vector<uint8_t> quantized(session->QuantizedInputBytes(h, w));
        for (size_t i = 0; i < input.size(); ++i) quantized[i] = QuantizeInput(input[i], *q);
        const size_t n = session->OutputShape(h, w)->elements();
        std::vector<float> want(n), got(n, -1.0f);
        ASSERT_TRUE(session->Run(input, h, w, want).ok()) << what;
        std::vector<int64_t> stamps(session->steps().size() + 1);
        const Status s = session->RunQuantized(quantized, h, w, got, stamps);
        ASSERT_TRUE(s.ok()) << what << ": " << s.message();
        EXPECT_EQ(std::memcmp(got.data(), want.data(), n * sizeof(float)), 0) << what;
        for (size_t k = 1; k < stamps.size(); ++k) EXPECT_GE(stamps[k], stamps[k - 1]) << what;
      }
    }
  }
}

TEST(QuantizedInput, RunQuantizedGivesRunsBytesOnEveryIsa) {
  ExpectRunQuantizedIsRun(testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16))));
}

TEST(QuantizedInput, AGraphWhoseInputOnlyInt8LayersReadTakesItToo) {
  ExpectRunQuantizedIsRun(testing::LoadOrDie(testing::Int8Spec(testing::SceneEdNetUSpec(16))));
}

TEST(QuantizedInput, QuantizeInputIsTheKernelsRoundingAndClamping) {
  const QuantParams q{0.5f, 10};
  EXPECT_EQ(QuantizeInput(0.0f, q), 10);
  EXPECT_EQ(QuantizeInput(0.25f, q), 10);   // 0.5 -> ties to even: 0
  EXPECT_EQ(QuantizeInput(0.75f, q), 12);   // 1.5 -> 2
  EXPECT_EQ(QuantizeInput(1.25f, q), 12);   // 2.5 -> 2
  EXPECT_EQ(QuantizeInput(-6.0f, q), 0);    // -12 + 10 clamps at 0
  EXPECT_EQ(QuantizeInput(1e30f, q), 255);  // clamped
  EXPECT_EQ(QuantizeInput(std::numeric_limits<float>::quiet_NaN(), q), 0);  // as -512
}

TEST(QuantizedInput, AFloatFirstLayerMeansNoQuantizedInputAndRunQuantizedSaysWhy) {
  // conv0 float32, the rest int8: the input is read as float32.
  auto mixed = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16), {false}));
  auto plain = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  for (const auto& model : {mixed, plain}) {
    auto session = Make(model, BestIsa(), 1);
    ASSERT_NE(session, nullptr);
    EXPECT_FALSE(session->InputQuantization().has_value());
    std::vector<uint8_t> in(session->QuantizedInputBytes(48, 64));
    std::vector<float> out(48 * 64 * 3);
    const Status s = session->RunQuantized(in, 48, 64, out);
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.message().find("InputQuantization is empty"), std::string::npos) << s.message();
  }
}

TEST(QuantizedInput, AShortBufferIsRefusedNamingBothSizes) {
  auto session =
      Make(testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16))), BestIsa(), 1);
  ASSERT_NE(session, nullptr);
  EXPECT_EQ(session->QuantizedInputBytes(48, 64), size_t{48} * 64 * 12);  // 12: no slack
  std::vector<uint8_t> in(48 * 64 * 12 - 1);
  std::vector<float> out(48 * 64 * 3);
  const Status s = session->RunQuantized(in, 48, 64, out);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("holds 36863 bytes; 48x64 needs 36864"), std::string::npos)
      << s.message();
}

}  // namespace
}  // namespace sfrt
