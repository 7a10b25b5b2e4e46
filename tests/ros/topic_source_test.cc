// TopicSource (ros/src/topic_source.h), the node's pair handoff, without a ROS master: pairs are
// handed in as the spinner's thread would, windows taken as the source stage would.
#include "topic_source.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace sfrt::ros {
namespace {

class RecordingLog final : public pipeline::LogSink {
 public:
  void Write(pipeline::LogLevel, std::string_view tag, std::string_view text) override {
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
  detail::ImageView view;
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
  pipeline::WindowItem item;
  for (int k = 0; k < 2; ++k) {
    Result<pipeline::Fetch> f = source.Next(&item, stop);
    ASSERT_TRUE(f.ok() && *f == pipeline::Fetch::kWindow);
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
  Result<pipeline::Fetch> end = source.Next(&item, stop);
  ASSERT_TRUE(end.ok());
  EXPECT_EQ(*end, pipeline::Fetch::kEnd);
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
  pipeline::WindowItem item;
  std::atomic<bool> done{false};
  // Pair 3 becomes pair t; pair 4 completes the window. The feeder waits until Next() has
  // taken pair 3, which pair 4 would otherwise replace in the one-pair queue.
  std::thread feeder([&] {
    while (source.queued() != 0 && !done) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    while (!done) {
      Hand(&source, 4, 1004);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  Result<pipeline::Fetch> f = source.Next(&item, stop);
  done = true;
  feeder.join();
  ASSERT_TRUE(f.ok() && *f == pipeline::Fetch::kWindow);
  EXPECT_EQ(item.meta.stamp_ns[0], 1003);
  EXPECT_EQ(item.meta.stamp_ns[1], 1004);
  EXPECT_EQ(item.left0.at<cv::Vec3b>(0, 0)[0], 3);
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
}  // namespace sfrt::ros
