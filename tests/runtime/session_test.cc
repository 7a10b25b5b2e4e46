#include "sfrt/session.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/model_builders.h"
#include "memory_planner.h"
#include "sfrt/exporter/sceneednet_spec.h"

namespace sfrt {
namespace {

std::vector<float> RandomImage(int h, int w, int c, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(0.0f, 255.0f);
  std::vector<float> v(static_cast<size_t>(h) * w * c);
  for (float& x : v) x = dist(rng);
  return v;
}

std::vector<float> RunOnce(Session& session, const std::vector<float>& input, int h, int w) {
  auto shape = session.OutputShape(h, w);
  EXPECT_TRUE(shape.ok()) << shape.message();
  std::vector<float> out(shape.ok() ? shape->elements() : 0, std::nanf(""));
  Status s = session.Run(input, h, w, out);
  EXPECT_TRUE(s.ok()) << s.message();
  return out;
}

TEST(Session, ProducesAFiniteOutputOfTheInputSize) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  auto session = Session::Create(model, {67, 121});
  ASSERT_TRUE(session.ok()) << session.message();
  const auto out = RunOnce(**session, RandomImage(67, 121, 12, 1), 67, 121);
  ASSERT_EQ(out.size(), 67u * 121u * 3u);
  for (float v : out) ASSERT_TRUE(std::isfinite(v));
}

TEST(Session, SmallerInputsGiveTheSameResultAsASessionPlannedForThem) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  auto big = Session::Create(model, {80, 96});
  ASSERT_TRUE(big.ok()) << big.message();
  for (auto [h, w] : {std::pair{33, 47}, {80, 96}, {1, 1}, {64, 17}}) {
    auto exact = Session::Create(model, {h, w});
    ASSERT_TRUE(exact.ok()) << exact.message();
    const auto input = RandomImage(h, w, 12, static_cast<uint32_t>(h * w));
    EXPECT_EQ(RunOnce(**big, input, h, w), RunOnce(**exact, input, h, w)) << h << "x" << w;
  }
}

TEST(Session, RepeatedRunsAreBitIdentical) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  auto session = Session::Create(model, {40, 50});
  ASSERT_TRUE(session.ok());
  const auto input = RandomImage(40, 50, 12, 9);
  const auto first = RunOnce(**session, input, 40, 50);
  RunOnce(**session, RandomImage(40, 50, 12, 10), 40, 50);  // dirty the arena
  EXPECT_EQ(RunOnce(**session, input, 40, 50), first);
}

TEST(Session, TimedRunGivesTheSameOutputAndOrderedStepTimestamps) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  auto session = Session::Create(model, {40, 50});
  ASSERT_TRUE(session.ok());
  const auto input = RandomImage(40, 50, 12, 3);
  const auto untimed = RunOnce(**session, input, 40, 50);
  std::vector<float> timed(untimed.size());
  std::vector<int64_t> stamps((*session)->steps().size() + 1, -1);
  const Status s = (*session)->Run(input, 40, 50, timed, stamps);
  ASSERT_TRUE(s.ok()) << s.message();
  EXPECT_EQ(timed, untimed);
  for (size_t k = 1; k < stamps.size(); ++k) {
    EXPECT_GE(stamps[k], stamps[k - 1]) << "step " << k - 1 << " ended before it started";
  }
  EXPECT_GT(stamps.back(), stamps.front());
}

TEST(Session, TimedRunRejectsATimestampBufferTooShortForThePlan) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  auto session = Session::Create(model, {40, 50});
  ASSERT_TRUE(session.ok());
  std::vector<float> input(40 * 50 * 12, 1.0f), output(40 * 50 * 3);
  std::vector<int64_t> stamps((*session)->steps().size());
  const Status s = (*session)->Run(input, 40, 50, output, stamps);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("step timestamp buffer"), std::string::npos) << s.message();
}

TEST(Session, PlanHasNoOverlapsAndFitsTheArena) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  auto session = Session::Create(model, {540, 960, Isa::kRef});
  ASSERT_TRUE(session.ok());
  std::vector<BufferRequest> requests;
  ArenaPlan plan;
  for (const PlannedTensor& t : (*session)->plan()) {
    requests.push_back({t.bytes, t.producer, t.last_consumer});
    plan.offsets.push_back(t.offset);
    EXPECT_LE(t.offset + t.bytes, (*session)->arena_bytes());
  }
  plan.total_bytes = (*session)->arena_bytes();
  EXPECT_FALSE(PlanHasOverlap(requests, plan));
  // 14 tensors: 16 layers minus the crop (a view) and the output (the caller's buffer).
  EXPECT_EQ(requests.size(), 14u);
}

TEST(Session, ArenaForFullWidthAt540x960IsPinned) {
  // Regression guard (TFLite Micro's arena threshold test): the ping-pong plan needs the two
  // largest neighbours, up4 (544x960x128) and conv9's input/output pair. A planner change that
  // grows this should be a conscious decision.
  // The reference path keeps every tensor; the fused plan is pinned in session_isa_test.
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(1));
  auto session = Session::Create(model, {540, 960, Isa::kRef});
  ASSERT_TRUE(session.ok()) << session.message();
  const size_t up4 = 544ull * 960 * 128 * 4;
  const size_t conv9 = 540ull * 960 * 64 * 4;
  EXPECT_EQ((*session)->arena_bytes(), up4 + conv9);
}

TEST(Session, RejectsInputsLargerThanPlanned) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  auto session = Session::Create(model, {32, 32});
  ASSERT_TRUE(session.ok());
  std::vector<float> in(33 * 32 * 12), out(33 * 32 * 3);
  Status s = (*session)->Run(in, 33, 32, out);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("33x32"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("32x32"), std::string::npos) << s.message();
}

TEST(Session, RejectsBuffersThatAreTooSmall) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  auto session = Session::Create(model, {16, 16});
  ASSERT_TRUE(session.ok());
  std::vector<float> in(16 * 16 * 12), out(16 * 16 * 3);
  std::vector<float> small_in(16 * 16 * 12 - 1), small_out(16 * 16 * 3 - 1);
  EXPECT_FALSE((*session)->Run(small_in, 16, 16, out).ok());
  EXPECT_FALSE((*session)->Run(in, 16, 16, small_out).ok());
  EXPECT_TRUE((*session)->Run(in, 16, 16, out).ok());
}

TEST(Session, RejectsANonPositiveMaximumSize) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  auto session = Session::Create(model, {0, 960});
  ASSERT_FALSE(session.ok());
  EXPECT_NE(session.message().find("0x960"), std::string::npos) << session.message();
}

}  // namespace
}  // namespace sfrt
