// A bag recorder's input side (sfrt/pipeline/flow_messages.h): the recording source hands every
// stereo pair it reads to the recorder once, stamped and numbered as the flow is; a recorder's
// error ends the run naming it; the flow and the inputs take turns on the one writer.
#include <gtest/gtest.h>

#include <atomic>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "sfrt/pipeline/flow_messages.h"

namespace sfrt::pipeline {
namespace {

struct Written {
  std::string topic;
  int64_t stamp_ns;
  uint32_t seq;
  std::string frame_id;
  std::string encoding;
  uint8_t first_byte;
};

// Keeps what it is given; fails from the `fail_at`th image on (0: never); counts calls that
// overlapped another call (two threads inside the writer at once).
class FakeWriter final : public MessageWriter {
 public:
  std::string WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                         const std::string& frame_id, const std::string& encoding,
                         uint32_t /*height*/, uint32_t /*width*/, uint32_t /*step*/,
                         const uint8_t* data) override {
    Enter();
    std::string e;
    if (fail_at != 0 && written.size() + 1 >= fail_at) {
      e = "disk full";
    } else {
      written.push_back({topic, stamp_ns, seq, frame_id, encoding, data[0]});
    }
    Leave();
    return e;
  }
  std::string WriteHeader(const std::string&, int64_t, uint32_t, const std::string&) override {
    Enter();
    Leave();
    return "";
  }

  std::vector<Written> written;
  size_t fail_at = 0;
  std::atomic<int> overlaps{0};

 private:
  void Enter() {
    if (inside_.exchange(true)) ++overlaps;
    std::this_thread::yield();
  }
  void Leave() { inside_ = false; }
  std::atomic<bool> inside_{false};
};

class RecorderOf final : public InputRecorder {
 public:
  RecorderOf(FlowRecorder* recorder, MessageWriter* writer)
      : recorder_(recorder), writer_(writer) {}
  Status RecordInputs(const WindowItem& item) override {
    return recorder_->WriteInputs(item, writer_);
  }

 private:
  FlowRecorder* recorder_;
  MessageWriter* writer_;
};

struct WindowSpec {
  int64_t frame0, frame1;
  bool continues;
};

// Windows of 2x3 images whose every byte is frame * 10 + side, stamped (frame + 1) * 100 ms.
class FakeSource final : public FrameSource {
 public:
  explicit FakeSource(std::vector<WindowSpec> windows) : windows_(std::move(windows)) {}
  Result<cv::Size> Open() override { return cv::Size(3, 2); }
  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>&) override {
    if (next_ == windows_.size()) return Fetch::kEnd;
    const WindowSpec& w = windows_[next_++];
    item->meta = FrameMeta{};
    item->meta.window = static_cast<int64_t>(next_ - 1);
    item->meta.frame0 = w.frame0;
    item->meta.frame1 = w.frame1;
    item->meta.continues = w.continues;
    item->meta.stamp_ns[0] = (w.frame0 + 1) * 100'000'000;
    item->meta.stamp_ns[1] = (w.frame1 + 1) * 100'000'000;
    const auto fill = [](cv::Mat* m, int64_t frame, int side) {
      m->create(2, 3, CV_8UC3);
      m->setTo(cv::Scalar::all(static_cast<double>(frame * 10 + side)));
    };
    fill(&item->left0, w.frame0, 0);
    fill(&item->right0, w.frame0, 1);
    fill(&item->left1, w.frame1, 0);
    fill(&item->right1, w.frame1, 1);
    return Fetch::kWindow;
  }
  std::string Describe() const override { return "fake: three windows"; }
  std::string kind() const override { return "fake"; }
  std::optional<int64_t> total_windows() const override {
    return static_cast<int64_t>(windows_.size());
  }
  bool live() const override { return true; }
  void ToJson(nlohmann::json* out) const override { (*out)["fake"] = true; }
  uint64_t drops() const override { return 7; }

 private:
  std::vector<WindowSpec> windows_;
  size_t next_ = 0;
};

FlowRecordingOptions Options() {
  FlowRecordingOptions o;
  o.path = "drive.mcap";
  o.frame_id = "cam_l";
  o.right_frame_id = "cam_r";
  o.left_topic = "/stereo/left";
  o.right_topic = "/stereo/right";
  return o;
}

// Windows 0-1 and 1-2 (continuing), then 4-5 after a gap.
std::vector<WindowSpec> ThreeWindows() { return {{0, 1, false}, {1, 2, true}, {4, 5, false}}; }

TEST(FlowRecordingTest, TheRecordingSourceHandsEachStereoPairToTheRecorderOnce) {
  FlowRecorder recorder(Options());
  recorder.Start();
  FakeWriter writer;
  RecorderOf inputs(&recorder, &writer);
  std::unique_ptr<FrameSource> source =
      MakeRecordingSource(std::make_unique<FakeSource>(ThreeWindows()), &inputs);
  ASSERT_TRUE(source->Open().ok());
  std::atomic<bool> stop{false};
  WindowItem item;
  int windows = 0;
  for (;;) {
    Result<Fetch> f = source->Next(&item, stop);
    ASSERT_TRUE(f.ok()) << f.message();
    if (*f == Fetch::kEnd) break;
    ++windows;
  }
  EXPECT_EQ(windows, 3);
  const int64_t frames[] = {0, 1, 2, 4, 5};
  ASSERT_EQ(writer.written.size(), 10u);
  for (size_t i = 0; i < 5; ++i) {
    for (int side = 0; side < 2; ++side) {
      const Written& w = writer.written[2 * i + static_cast<size_t>(side)];
      SCOPED_TRACE("frame " + std::to_string(frames[i]) + " side " + std::to_string(side));
      EXPECT_EQ(w.topic, side == 0 ? "/stereo/left" : "/stereo/right");
      EXPECT_EQ(w.frame_id, side == 0 ? "cam_l" : "cam_r");
      EXPECT_EQ(w.encoding, "bgr8");
      EXPECT_EQ(w.stamp_ns, (frames[i] + 1) * 100'000'000);
      EXPECT_EQ(w.seq, static_cast<uint32_t>(frames[i]));
      EXPECT_EQ(w.first_byte, frames[i] * 10 + side);
    }
  }
  EXPECT_EQ(recorder.input_pairs(), 5);
}

TEST(FlowRecordingTest, TheRecordingSourceIsOtherwiseTheSourceItWraps) {
  FlowRecorder recorder(Options());
  FakeWriter writer;
  RecorderOf inputs(&recorder, &writer);
  std::unique_ptr<FrameSource> source =
      MakeRecordingSource(std::make_unique<FakeSource>(ThreeWindows()), &inputs);
  EXPECT_EQ(source->Describe(), "fake: three windows");
  EXPECT_EQ(source->kind(), "fake");
  EXPECT_EQ(source->total_windows(), 3);
  EXPECT_TRUE(source->live());
  EXPECT_EQ(source->drops(), 7u);
  nlohmann::json j;
  source->ToJson(&j);
  EXPECT_EQ(j["fake"], true);
}

TEST(FlowRecordingTest, ARecorderErrorEndsTheRunNamingItAndTheBagStaysFailed) {
  FlowRecorder recorder(Options());
  recorder.Start();
  FakeWriter writer;
  writer.fail_at = 3;  // the left image of the second pair
  RecorderOf inputs(&recorder, &writer);
  std::unique_ptr<FrameSource> source =
      MakeRecordingSource(std::make_unique<FakeSource>(ThreeWindows()), &inputs);
  std::atomic<bool> stop{false};
  WindowItem item;
  Result<Fetch> f = source->Next(&item, stop);
  ASSERT_FALSE(f.ok());
  EXPECT_NE(f.message().find("recording the input images: disk full"), std::string::npos)
      << f.message();
  EXPECT_TRUE(recorder.failed());
  writer.fail_at = 0;
  Status again = recorder.WriteInputs(item, &writer);
  EXPECT_FALSE(again.ok());
  EXPECT_NE(again.message().find("drive.mcap"), std::string::npos) << again.message();
}

TEST(FlowRecordingTest, TheFlowAndTheInputsTakeTurnsOnTheWriter) {
  FlowRecordingOptions o = Options();
  FlowRecorder recorder(o);
  recorder.Start();
  FakeWriter writer;
  FakeSource source({{0, 1, false}});
  WindowItem item;
  std::atomic<bool> stop{false};
  ASSERT_TRUE(source.Next(&item, stop).ok());
  FrameMeta meta = item.meta;
  std::vector<float> flow(2 * 3 * 3, 0.5f);
  FlowFrame frame;
  frame.meta = &meta;
  frame.flow = flow;
  frame.height = 2;
  frame.width = 3;
  frame.channels = 3;
  constexpr int kRounds = 2000;
  std::thread inputs_thread([&] {
    for (int i = 0; i < kRounds; ++i) ASSERT_TRUE(recorder.WriteInputs(item, &writer).ok());
  });
  for (int i = 0; i < kRounds; ++i) ASSERT_TRUE(recorder.Write(frame, &writer).ok());
  inputs_thread.join();
  EXPECT_EQ(writer.overlaps.load(), 0);
  EXPECT_EQ(recorder.windows(), kRounds);
  EXPECT_EQ(recorder.input_pairs(), 2 * kRounds);
  EXPECT_EQ(writer.written.size(), static_cast<size_t>(5 * kRounds));  // 4 images + 1 flow
}

}  // namespace
}  // namespace sfrt::pipeline
