#include "sfrt/pipeline/latest_queue.h"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

namespace sfrt::pipeline {
namespace {

TEST(LatestQueue, NewestWinsKeepsTheNewestAndCountsDrops) {
  LatestQueue<int> q(2, QueuePolicy::kNewestWins);
  for (int i = 1; i <= 5; ++i) {
    int item = i;
    ASSERT_TRUE(q.Push(&item));
  }
  EXPECT_EQ(q.drops(), 3u);  // 1, 2, 3 were overtaken
  int out = 0;
  ASSERT_TRUE(q.Pop(&out));
  EXPECT_EQ(out, 4);
  ASSERT_TRUE(q.Pop(&out));
  EXPECT_EQ(out, 5);
  EXPECT_EQ(q.size(), 0u);
  EXPECT_EQ(q.pushed(), 5u);
  EXPECT_EQ(q.popped(), 2u);
}

TEST(LatestQueue, NewestWinsWithOneSlotHandsOutOnlyTheLatest) {
  LatestQueue<int> q(1, QueuePolicy::kNewestWins);
  for (int i = 0; i < 10; ++i) {
    int item = i;
    ASSERT_TRUE(q.Push(&item));
  }
  int out = -1;
  ASSERT_TRUE(q.Pop(&out));
  EXPECT_EQ(out, 9);
  EXPECT_EQ(q.drops(), 9u);
}

TEST(LatestQueue, BlockDeliversEveryItemInOrderWithoutDrops) {
  LatestQueue<int> q(1, QueuePolicy::kBlock);
  constexpr int kItems = 200;
  std::thread producer([&] {
    for (int i = 0; i < kItems; ++i) {
      int item = i;
      ASSERT_TRUE(q.Push(&item));
    }
    q.Close();
  });
  std::vector<int> got;
  int out = 0;
  while (q.Pop(&out)) got.push_back(out);
  producer.join();
  ASSERT_EQ(got.size(), static_cast<size_t>(kItems));
  for (int i = 0; i < kItems; ++i) EXPECT_EQ(got[i], i);
  EXPECT_EQ(q.drops(), 0u);
}

TEST(LatestQueue, CloseDrainsQueuedItemsThenEnds) {
  LatestQueue<int> q(3, QueuePolicy::kNewestWins);
  int a = 1, b = 2;
  ASSERT_TRUE(q.Push(&a));
  ASSERT_TRUE(q.Push(&b));
  q.Close();
  int c = 3;
  EXPECT_FALSE(q.Push(&c));  // refused after Close
  EXPECT_EQ(c, 3);           // and untouched
  int out = 0;
  ASSERT_TRUE(q.Pop(&out));
  EXPECT_EQ(out, 1);
  ASSERT_TRUE(q.Pop(&out));
  EXPECT_EQ(out, 2);
  EXPECT_FALSE(q.Pop(&out));
}

TEST(LatestQueue, DiscardThrowsAwayQueuedItemsAndCountsThem) {
  LatestQueue<int> q(3, QueuePolicy::kBlock);
  for (int i = 0; i < 3; ++i) {
    int item = i;
    ASSERT_TRUE(q.Push(&item));
  }
  q.Discard();
  int out = 0;
  EXPECT_FALSE(q.Pop(&out));
  EXPECT_EQ(q.discarded(), 3u);
  EXPECT_EQ(q.drops(), 0u);
}

TEST(LatestQueue, CloseWakesABlockedConsumerAndABlockedProducer) {
  LatestQueue<int> consumer_side(1, QueuePolicy::kBlock);
  bool popped = true;
  std::thread consumer([&] {
    int out = 0;
    popped = consumer_side.Pop(&out);
  });
  LatestQueue<int> producer_side(1, QueuePolicy::kBlock);
  int first = 1;
  ASSERT_TRUE(producer_side.Push(&first));
  bool pushed = true;
  std::thread producer([&] {
    int item = 2;
    pushed = producer_side.Push(&item);  // full: waits until Close
  });
  consumer_side.Close();
  producer_side.Close();
  consumer.join();
  producer.join();
  EXPECT_FALSE(popped);
  EXPECT_FALSE(pushed);
}

TEST(LatestQueue, ItemsMoveBySwappingSoBuffersAreRecycled) {
  // Slots are made by the factory with their buffers allocated; a Push hands the producer a
  // slot's buffer back, so no buffer is ever allocated after construction.
  LatestQueue<std::vector<float>> q(1, QueuePolicy::kNewestWins,
                                    [] { return std::vector<float>(64, -1.0f); });
  std::vector<float> mine(64, 7.0f);
  const float* mine_data = mine.data();
  ASSERT_TRUE(q.Push(&mine));
  ASSERT_EQ(mine.size(), 64u);  // the slot's preallocated buffer
  EXPECT_EQ(mine[0], -1.0f);
  EXPECT_NE(mine.data(), mine_data);
  std::vector<float> out;
  ASSERT_TRUE(q.Pop(&out));
  EXPECT_EQ(out.data(), mine_data);  // the very buffer pushed, not a copy
  EXPECT_EQ(out[0], 7.0f);
}

}  // namespace
}  // namespace sfrt::pipeline
