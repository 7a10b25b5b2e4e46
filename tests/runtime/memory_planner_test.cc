#include "memory_planner.h"

#include <gtest/gtest.h>

#include <random>

namespace sfrt {
namespace {

TEST(MemoryPlanner, ChainOfLayersBecomesPingPong) {
  // A chain: tensor i is written by step i and read by step i+1.
  std::vector<BufferRequest> requests;
  for (int i = 0; i < 6; ++i) requests.push_back({1000, i, i + 1});
  const ArenaPlan plan = PlanArena(requests);
  EXPECT_FALSE(PlanHasOverlap(requests, plan));
  // Two 1000-byte buffers rounded to 64 bytes each.
  EXPECT_EQ(plan.total_bytes, 2 * 1024u);
}

TEST(MemoryPlanner, OffsetsAreAlignedTo64Bytes) {
  const std::vector<BufferRequest> requests = {{100, 0, 1}, {3, 0, 2}, {65, 1, 2}, {1, 2, 3}};
  const ArenaPlan plan = PlanArena(requests);
  for (size_t off : plan.offsets) EXPECT_EQ(off % kArenaAlignment, 0u);
  EXPECT_EQ(plan.total_bytes % kArenaAlignment, 0u);
  EXPECT_FALSE(PlanHasOverlap(requests, plan));
}

TEST(MemoryPlanner, ReusesMemoryOfTensorsThatAreNoLongerLive) {
  // Big tensor dies at step 1; the later big tensor must land on the same bytes.
  const std::vector<BufferRequest> requests = {{4096, 0, 1}, {64, 1, 2}, {4096, 2, 3}};
  const ArenaPlan plan = PlanArena(requests);
  EXPECT_FALSE(PlanHasOverlap(requests, plan));
  EXPECT_EQ(plan.total_bytes, 4096u + 64u);
}

TEST(MemoryPlanner, RandomLifetimesNeverOverlapAndStayWithinTotal) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<BufferRequest> requests(1 + rng() % 24);
    for (auto& r : requests) {
      r.bytes = 1 + rng() % 5000;
      r.first_use = static_cast<int>(rng() % 20);
      r.last_use = r.first_use + static_cast<int>(rng() % 6);
    }
    const ArenaPlan plan = PlanArena(requests);
    ASSERT_FALSE(PlanHasOverlap(requests, plan)) << "trial " << trial;
    size_t peak_live = 0;  // a lower bound any plan must meet
    for (int step = 0; step < 26; ++step) {
      size_t live = 0;
      for (size_t i = 0; i < requests.size(); ++i) {
        ASSERT_LE(plan.offsets[i] + requests[i].bytes, plan.total_bytes);
        if (requests[i].first_use <= step && step <= requests[i].last_use)
          live += requests[i].bytes;
      }
      peak_live = std::max(peak_live, live);
    }
    EXPECT_GE(plan.total_bytes, peak_live);
  }
}

TEST(MemoryPlanner, OverlapCheckDetectsABadPlan) {
  const std::vector<BufferRequest> requests = {{128, 0, 2}, {128, 1, 3}};
  ArenaPlan bad;
  bad.offsets = {0, 64};
  bad.total_bytes = 192;
  EXPECT_TRUE(PlanHasOverlap(requests, bad));
}

}  // namespace
}  // namespace sfrt
