// The pipeline's bag replay (sfrt/pipeline/bag_replay.h) over an in-memory bag: how left and right
// pair by stamp, how windows are named and broken, and what a bad frame or a bad topic does. The
// ROS 1 and rosbag2 adapters replay through it (tests/ros, tests/ros2 run them end to end).
#include "sfrt/pipeline/bag_replay.h"

#include <gtest/gtest.h>

#include <atomic>
#include <string>
#include <vector>

namespace sfrt::pipeline {
namespace {

constexpr int64_t kMs = 1'000'000;

struct StoredMessage {
  int side;
  int64_t stamp_ms;
  std::string encoding = "bgr8";
  int height = 4;
  int width = 6;
  uint8_t value = 0;  // every pixel's bytes
};

// A bag held in memory: messages in the given order, numbered per topic as a bag numbers them.
class MemoryBag final : public ImageBag {
 public:
  explicit MemoryBag(std::vector<StoredMessage> messages) : messages_(std::move(messages)) {}

  Result<BagProbe> Open(const std::string& path, const std::string& left,
                        const std::string& right) override {
    opened_path = path;
    opened_topics[0] = left;
    opened_topics[1] = right;
    BagProbe probe;
    probe.left_type = probe.right_type = "sensor_msgs/msg/Image";
    probe.format = "memory";
    for (const StoredMessage& m : messages_)
      ++(m.side == 0 ? probe.left_messages : probe.right_messages);
    return probe;
  }

  Result<bool> Next(BagImage* out) override {
    if (next_ == messages_.size()) return false;
    const StoredMessage& m = messages_[next_++];
    const size_t bytes = static_cast<size_t>(m.height) * m.width * 3;
    pixels_.assign(bytes, m.value);
    out->side = m.side;
    out->index = read_[m.side]++;
    out->message.stamp_ns = m.stamp_ms * kMs;
    out->message.compressed = false;
    out->message.encoding = m.encoding;
    out->message.height = static_cast<uint32_t>(m.height);
    out->message.width = static_cast<uint32_t>(m.width);
    out->message.step = static_cast<uint32_t>(m.width * 3);
    out->message.data = pixels_.data();
    out->message.size = pixels_.size();
    return true;
  }

  std::string opened_path;
  std::string opened_topics[2];

 private:
  std::vector<StoredMessage> messages_;
  size_t next_ = 0;
  int64_t read_[2] = {0, 0};
  std::vector<uint8_t> pixels_;
};

BagReplaySpec Spec() {
  BagReplaySpec spec;
  spec.path = "drive.mcap";
  spec.left_topic = "left/image_rect";
  spec.right_topic = "/right/image_rect";
  spec.pair_tolerance_ms = 8;
  return spec;
}

// Every window the source gives, until its end or an error (returned in *error).
std::vector<WindowItem> Drain(FrameSource* source, Status* error) {
  std::vector<WindowItem> windows;
  const std::atomic<bool> stop{false};
  while (true) {
    WindowItem item;
    Result<Fetch> fetched = source->Next(&item, stop);
    if (!fetched.ok()) {
      *error = fetched.status();
      return windows;
    }
    if (*fetched == Fetch::kEnd) return windows;
    windows.push_back(item);
  }
}

TEST(BagReplay, PairsByStampAndNamesEachWindowByTheLeftMessageNumbers) {
  // Right images 2 ms after their left ones, one pair every 33 ms.
  std::vector<StoredMessage> messages;
  for (int i = 0; i < 4; ++i) {
    messages.push_back({0, 33 * i, "bgr8", 4, 6, static_cast<uint8_t>(10 * i)});
    messages.push_back({1, 33 * i + 2, "rgb8", 4, 6, static_cast<uint8_t>(10 * i + 1)});
  }
  auto bag = std::make_unique<MemoryBag>(messages);
  MemoryBag* raw = bag.get();
  std::unique_ptr<FrameSource> source = MakeBagReplaySource(Spec(), std::move(bag));
  Result<cv::Size> size = source->Open();
  ASSERT_TRUE(size.ok()) << size.message();
  EXPECT_EQ(*size, cv::Size(6, 4));
  EXPECT_EQ(raw->opened_path, "drive.mcap");
  EXPECT_EQ(raw->opened_topics[0], "/left/image_rect");  // made absolute
  EXPECT_EQ(raw->opened_topics[1], "/right/image_rect");
  Status error = Status::Ok();
  std::vector<WindowItem> windows = Drain(source.get(), &error);
  ASSERT_TRUE(error.ok()) << error.message();
  ASSERT_EQ(windows.size(), 3u);
  for (int w = 0; w < 3; ++w) {
    const FrameMeta& m = windows[w].meta;
    EXPECT_EQ(m.frame0, w);
    EXPECT_EQ(m.frame1, w + 1);
    EXPECT_EQ(m.stamp_ns[0], 33 * w * kMs);
    EXPECT_EQ(m.stamp_ns[1], 33 * (w + 1) * kMs);
    EXPECT_EQ(m.left0_path, "drive.mcap:/left/image_rect:" + std::to_string(w));
    EXPECT_EQ(windows[w].left0.at<cv::Vec3b>(0, 0)[0], 10 * w);
    EXPECT_EQ(windows[w].right1.at<cv::Vec3b>(0, 0)[0],
              10 * (w + 1) + 1);  // rgb8 -> BGR: same grey
  }
  EXPECT_EQ(source->drops(), 0u);
  EXPECT_EQ(source->chain_counts().windows, 3);
}

TEST(BagReplay, ARightFrameMissingLeavesItsLeftUnpairedAndNoWindowSpansTheGap) {
  std::vector<StoredMessage> messages;
  for (int i = 0; i < 5; ++i) {
    messages.push_back({0, 33 * i});
    if (i != 2) messages.push_back({1, 33 * i + 1});
  }
  std::unique_ptr<FrameSource> source =
      MakeBagReplaySource(Spec(), std::make_unique<MemoryBag>(messages));
  ASSERT_TRUE(source->Open().ok());
  Status error = Status::Ok();
  std::vector<WindowItem> windows = Drain(source.get(), &error);
  ASSERT_TRUE(error.ok()) << error.message();
  // Pairs 0, 1, 3, 4: windows 0->1 and 3->4; none from 1 to 3.
  ASSERT_EQ(windows.size(), 2u);
  EXPECT_EQ(windows[0].meta.frame0, 0);
  EXPECT_EQ(windows[0].meta.frame1, 1);
  EXPECT_EQ(windows[1].meta.frame0, 3);
  EXPECT_EQ(windows[1].meta.frame1, 4);
  EXPECT_EQ(source->drops(), 1u);
  EXPECT_GE(source->chain_counts().broken_by_loss, 1);
}

TEST(BagReplay, AnUnconvertibleEncodingStopsTheRunNamingTheTopicAndTheMessage) {
  std::vector<StoredMessage> messages = {{0, 0}, {1, 1}, {0, 33, "yuv422"}, {1, 34}};
  std::unique_ptr<FrameSource> source =
      MakeBagReplaySource(Spec(), std::make_unique<MemoryBag>(messages));
  ASSERT_TRUE(source->Open().ok());
  Status error = Status::Ok();
  (void)Drain(source.get(), &error);
  ASSERT_FALSE(error.ok());
  EXPECT_NE(error.message().find("/left/image_rect message 1"), std::string::npos)
      << error.message();
  EXPECT_NE(error.message().find("yuv422"), std::string::npos) << error.message();
}

TEST(BagReplay, UnderSkipABadFrameIsRecordedAndTheNextWindowStartsAfterIt) {
  std::vector<StoredMessage> messages = {{0, 0},  {1, 1},  {0, 33, "yuv422"}, {1, 34},
                                         {0, 66}, {1, 67}, {0, 99},           {1, 100}};
  BagReplaySpec spec = Spec();
  spec.on_bad_frame = camera::BadFramePolicy::kSkip;
  std::unique_ptr<FrameSource> source =
      MakeBagReplaySource(spec, std::make_unique<MemoryBag>(messages));
  ASSERT_TRUE(source->Open().ok());
  Status error = Status::Ok();
  std::vector<WindowItem> windows = Drain(source.get(), &error);
  ASSERT_TRUE(error.ok()) << error.message();
  ASSERT_EQ(windows.size(), 1u);  // 2 -> 3 only: pair 0 has no consecutive partner
  EXPECT_EQ(windows[0].meta.frame0, 2);
  EXPECT_EQ(windows[0].meta.frame1, 3);
  ASSERT_EQ(source->bad_frames().size(), 1u);
  EXPECT_EQ(source->bad_frames()[0].path, "drive.mcap:/left/image_rect message 1");
}

TEST(BagReplay, TheSameTopicTwiceOrNoTopicIsRefusedBeforeTheBagIsOpened) {
  BagReplaySpec spec = Spec();
  spec.right_topic = "/left/image_rect";
  MemoryBag bag({});
  Result<BagProbe> probe = ProbeBag(spec, &bag);
  ASSERT_FALSE(probe.ok());
  EXPECT_NE(probe.message().find("both '/left/image_rect'"), std::string::npos) << probe.message();
  EXPECT_TRUE(bag.opened_path.empty());
  spec.right_topic = "";
  EXPECT_FALSE(ProbeBag(spec, &bag).ok());
  EXPECT_TRUE(bag.opened_path.empty());
}

}  // namespace
}  // namespace sfrt::pipeline
