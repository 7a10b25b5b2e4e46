// sfrt_ros2's left/right pairing by stamp (ros2/src/stamp_pairer.h).
#include "stamp_pairer.h"

#include <gtest/gtest.h>

#include <utility>
#include <vector>

namespace sfrt::ros2 {
namespace {

constexpr int64_t kMs = 1'000'000;

struct Recorder {
  std::vector<std::pair<int64_t, int64_t>> pairs;  // left, right stamps in ms
  StampPairer::PairCallback callback() {
    return [this](const pipeline::ImageMessage& l, const pipeline::ImageMessage& r,
                  const std::string& frame_id) {
      EXPECT_EQ(frame_id, "left_camera");
      EXPECT_EQ(l.size, 3u);
      EXPECT_EQ(l.data[0], static_cast<uint8_t>(l.stamp_ns / kMs));  // the bytes came along
      pairs.push_back({l.stamp_ns / kMs, r.stamp_ns / kMs});
    };
  }
};

void Add(StampPairer* p, int side, int64_t ms) {
  const uint8_t bytes[3] = {static_cast<uint8_t>(ms), 0, 0};
  pipeline::ImageMessage m;
  m.stamp_ns = ms * kMs;
  m.encoding = "bgr8";
  m.data = bytes;
  m.size = 3;
  p->Add(side, m, side == 0 ? "left_camera" : "right_camera");
}

TEST(StampPairer, WithTheFrameIntervalAPairGoesOutAsSoonAsNoLaterFrameCouldPairBetter) {
  Recorder rec;
  StampPairer p(8 * kMs, 30 * kMs, 5, rec.callback());
  Add(&p, 0, 100);
  EXPECT_TRUE(rec.pairs.empty());
  Add(&p, 1, 102);  // a right frame 30 ms later would be 28 ms away: this pair is final
  ASSERT_EQ(rec.pairs.size(), 1u);
  EXPECT_EQ(rec.pairs[0], std::make_pair(int64_t{100}, int64_t{102}));
}

TEST(StampPairer, WithoutTheFrameIntervalAPairWaitsForTheNextFrames) {
  Recorder rec;
  StampPairer p(8 * kMs, 0, 5, rec.callback());
  Add(&p, 0, 100);
  Add(&p, 1, 102);
  EXPECT_TRUE(rec.pairs.empty());
  Add(&p, 0, 133);
  Add(&p, 1, 135);
  ASSERT_EQ(rec.pairs.size(), 1u);
  EXPECT_EQ(rec.pairs[0], std::make_pair(int64_t{100}, int64_t{102}));
}

TEST(StampPairer, AFrameWithNoPartnerWithinTheSlopIsDroppedAndCounted) {
  Recorder rec;
  StampPairer p(8 * kMs, 30 * kMs, 5, rec.callback());
  Add(&p, 0, 100);
  Add(&p, 0, 133);  // the right frame of 100 was lost
  Add(&p, 1, 134);
  ASSERT_EQ(rec.pairs.size(), 1u);
  EXPECT_EQ(rec.pairs[0], std::make_pair(int64_t{133}, int64_t{134}));
  EXPECT_EQ(p.unpaired(0), 1u);
  EXPECT_EQ(p.unpaired(1), 0u);
}

TEST(StampPairer, TheClosestOfTwoCandidatesIsTaken) {
  Recorder rec;
  StampPairer p(20 * kMs, 0, 5, rec.callback());
  Add(&p, 1, 90);  // 10 ms from the left frame
  Add(&p, 1, 99);  // 1 ms: the better partner
  Add(&p, 0, 100);
  Add(&p, 0, 140);
  Add(&p, 1, 141);
  ASSERT_GE(rec.pairs.size(), 1u);
  EXPECT_EQ(rec.pairs[0], std::make_pair(int64_t{100}, int64_t{99}));
  EXPECT_EQ(p.unpaired(1), 1u);
}

TEST(StampPairer, AFullQueueDropsItsOldestImage) {
  Recorder rec;
  StampPairer p(8 * kMs, 30 * kMs, 2, rec.callback());
  Add(&p, 0, 100);
  Add(&p, 0, 133);
  Add(&p, 0, 166);  // queue of 2: 100 goes
  EXPECT_EQ(p.unpaired(0), 1u);
  Add(&p, 1, 134);  // 133 pairs; 166 stays
  ASSERT_EQ(rec.pairs.size(), 1u);
  EXPECT_EQ(rec.pairs[0], std::make_pair(int64_t{133}, int64_t{134}));
}

}  // namespace
}  // namespace sfrt::ros2
