// TopicSource (ros/src/topic_source.h), the node's pair handoff, without a ROS master: pairs are
// handed in as the spinner's thread would, windows taken as the source stage would.
#include "sfrt/pipeline/topic_source.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace sfrt::pipeline {
namespace {

class RecordingLog final : public LogSink {
 public:
  void Write(LogLevel, std::string_view tag, std::string_view text) override {
    std::lock_guard<std::mutex> lock(mu);
    lines.push_back(std::string(tag) + ": " + std::string(text));
  }
  std::mutex mu;
  std::vector<std::string> lines;
};

// A bgr8 image whose every byte is `value`.
struct Frame {
  Frame(int h, int w, uint8_t value, int64_t stamp, std::string encoding = "bgr8", int channels = 3)
      : bytes(static_cast<size_t>(h * w * channels), value) {
    view.stamp_ns = stamp;
    view.encoding = std::move(encoding);
    view.height = static_cast<uint32_t>(h);
    view.width = static_cast<uint32_t>(w);
    view.step = static_cast<uint32_t>(w * channels);
    view.data = bytes.data();
    view.size = bytes.size();
  }
  std::vector<uint8_t> bytes;
  ImageMessage view;
};

void Hand(TopicSource* source, uint8_t value, int64_t stamp, int h = 8, int w = 12) {
  Frame l(h, w, value, stamp), r(h, w, static_cast<uint8_t>(value + 100), stamp);
  source->OnPair(l.view, r.view, "left_cam");
}

TEST(TopicSource, ConsecutivePairsFormWindowsThatContinueTheLastOne) {
  RecordingLog log;
  TopicSourceOptions o;
  o.input_queue = 4;
  o.log = &log;
  TopicSource source(o);
  for (int i = 0; i < 3; ++i) Hand(&source, static_cast<uint8_t>(i), 1000 + i);
  Result<cv::Size> size = source.Open();
  ASSERT_TRUE(size.ok()) << size.message();
  EXPECT_EQ(*size, cv::Size(12, 8));
  EXPECT_EQ(source.frame_id(), "left_cam");
  std::atomic<bool> stop{false};
  WindowItem item;
  for (int k = 0; k < 2; ++k) {
    Result<Fetch> f = source.Next(&item, stop);
    ASSERT_TRUE(f.ok() && *f == Fetch::kWindow);
    EXPECT_EQ(item.meta.window, k);
    EXPECT_EQ(item.meta.frame0, k);
    EXPECT_EQ(item.meta.frame1, k + 1);
    EXPECT_EQ(item.meta.continues, k > 0);
    EXPECT_EQ(item.meta.stamp_ns[0], 1000 + k);
    EXPECT_EQ(item.meta.stamp_ns[1], 1001 + k);
    EXPECT_EQ(item.left0.at<cv::Vec3b>(3, 4)[0], k);
    EXPECT_EQ(item.right0.at<cv::Vec3b>(3, 4)[2], k + 100);
    EXPECT_EQ(item.left1.at<cv::Vec3b>(7, 11)[1], k + 1);
    EXPECT_EQ(item.right1.at<cv::Vec3b>(0, 0)[0], k + 101);
  }
  stop = true;
  Result<Fetch> end = source.Next(&item, stop);
  ASSERT_TRUE(end.ok());
  EXPECT_EQ(*end, Fetch::kEnd);
  EXPECT_EQ(source.drops(), 0u);
  EXPECT_TRUE(log.lines.empty());
}

TEST(TopicSource, AFullInputQueueDropsTheOldestPairAndCountsIt) {
  TopicSourceOptions o;
  o.input_queue = 1;
  TopicSource source(o);
  for (int i = 0; i < 3; ++i) Hand(&source, static_cast<uint8_t>(i), 1000 + i);
  EXPECT_EQ(source.drops(), 2u);  // pairs 0 and 1 gave way to the newest
  ASSERT_TRUE(source.Open().ok());
  Hand(&source, 3, 1003);  // pair 2 waits: pair 3 takes its place
  EXPECT_EQ(source.drops(), 3u);
  std::atomic<bool> stop{false};
  WindowItem item;
  std::atomic<bool> done{false};
  // Pair 3 becomes pair t; pair 4 completes the window. The feeder waits until Next() has
  // taken pair 3, which pair 4 would otherwise replace in the one-pair queue.
  std::thread feeder([&] {
    while (source.queued() != 0 && !done) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    // One pair at a time, each after the last was taken (none dropped), stamps increasing.
    for (int64_t stamp = 1004; !done; ++stamp) {
      Hand(&source, 4, stamp);
      while (source.queued() != 0 && !done) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    }
  });
  Result<Fetch> f = source.Next(&item, stop);
  done = true;
  feeder.join();
  ASSERT_TRUE(f.ok() && *f == Fetch::kWindow);
  EXPECT_EQ(item.meta.stamp_ns[0], 1003);
  EXPECT_EQ(item.meta.stamp_ns[1], 1004);
  EXPECT_EQ(item.left0.at<cv::Vec3b>(0, 0)[0], 3);
}

// Takes every window the queued pairs form (with stop set, Next() takes the queued pairs and
// returns kEnd once the queue is empty).
std::vector<std::pair<int64_t, int64_t>> WindowStamps(TopicSource* source) {
  std::vector<std::pair<int64_t, int64_t>> out;
  const std::atomic<bool> stop{true};
  WindowItem item;
  while (true) {
    Result<Fetch> f = source->Next(&item, stop);
    EXPECT_TRUE(f.ok());
    if (!f.ok() || *f == Fetch::kEnd) return out;
    out.emplace_back(item.meta.stamp_ns[0], item.meta.stamp_ns[1]);
  }
}

TEST(TopicSource, StampsThatGoBackStartANewChainSoNoWindowRunsBackwards) {
  TopicSourceOptions o;
  o.input_queue = 8;
  TopicSource source(o);
  // A bag played twice (`rosbag play` again, or -l): the stamps start over.
  for (int64_t stamp : {1000, 1033, 1066, 0, 33}) Hand(&source, 1, stamp);
  ASSERT_TRUE(source.Open().ok());
  EXPECT_EQ(WindowStamps(&source),
            (std::vector<std::pair<int64_t, int64_t>>{{1000, 1033}, {1033, 1066}, {0, 33}}));
  EXPECT_EQ(source.chain_counts().stream_restarts, 1);
  EXPECT_EQ(source.chain_counts().windows, 3);
}

TEST(TopicSource, ASkippedPairOrAStampGapBreaksTheChain) {
  TopicSourceOptions o;
  o.input_queue = 8;
  o.warn_period_s = 60;
  RecordingLog log;
  o.log = &log;
  TopicSource source(o);
  Hand(&source, 1, 1000);
  Hand(&source, 1, 1033);
  Frame l(8, 12, 0, 1066, "yuv422", 2), r(8, 12, 0, 1066, "yuv422", 2);
  source.OnPair(l.view, r.view, "left_cam");  // skipped: the chain breaks
  Hand(&source, 1, 1100);
  Hand(&source, 1, 1133);
  Hand(&source, 1, 1233);  // two frames missing upstream (ApproximateTime found no partner)
  Hand(&source, 1, 1266);
  ASSERT_TRUE(source.Open().ok());
  EXPECT_EQ(WindowStamps(&source),
            (std::vector<std::pair<int64_t, int64_t>>{{1000, 1033}, {1100, 1133}, {1233, 1266}}));
  EXPECT_EQ(source.chain_counts().broken_by_loss, 1);
  EXPECT_EQ(source.chain_counts().skipped_for_gap, 1);
}

TEST(TopicSource, PairsItCannotConvertAreSkippedWithOneWarningNamingTheEncoding) {
  RecordingLog log;
  TopicSourceOptions o;
  o.log = &log;
  o.warn_period_s = 60;
  TopicSource source(o);
  for (int i = 0; i < 4; ++i) {
    Frame l(8, 12, 0, i, "yuv422", 2), r(8, 12, 0, i, "yuv422", 2);
    source.OnPair(l.view, r.view, "left_cam");
  }
  Hand(&source, 1, 10, 8, 12);
  Hand(&source, 2, 11, 6, 12);  // another size than the first pair's
  EXPECT_EQ(source.bad_pairs(), 5u);
  EXPECT_EQ(source.pairs(), 1u);
  ASSERT_EQ(log.lines.size(), 1u);  // rate-limited: one warning for all
  EXPECT_NE(log.lines[0].find("encoding 'yuv422'"), std::string::npos) << log.lines[0];
  EXPECT_NE(log.lines[0].find("skipped 1 stereo pair(s)"), std::string::npos) << log.lines[0];
}

TEST(TopicSource, OpenReturnsAnErrorWhenStoppedBeforeTheFirstPair) {
  std::atomic<bool> stop{true};
  TopicSourceOptions o;
  o.stop = &stop;
  TopicSource source(o);
  Result<cv::Size> size = source.Open();
  ASSERT_FALSE(size.ok());
  EXPECT_NE(size.message().find("before the first stereo pair"), std::string::npos);
}

}  // namespace
}  // namespace sfrt::pipeline
