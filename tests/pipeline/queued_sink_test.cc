// QueuedSink (queued_sink.h): inner sinks on a thread of their own behind a bounded queue.
#include "sfrt/pipeline/queued_sink.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

namespace sfrt::pipeline {
namespace {

// Window k of a 2x3 flow whose every value is k, with its own metadata and left image.
struct Window {
  explicit Window(int k) : flow(2 * 3 * 3, static_cast<float>(k)), left(2, 3, CV_8UC3) {
    meta.window = k;
    meta.sequence = "seq";
    meta.frame0 = k;
    meta.frame1 = k + 1;
    meta.capture_ns[1] = 1000 + k;
    left.setTo(cv::Scalar::all(k));
    frame.meta = &meta;
    frame.flow = flow;
    frame.height = 2;
    frame.width = 3;
    frame.channels = 3;
    frame.left_image = &left;
  }
  FrameMeta meta;
  std::vector<float> flow;
  cv::Mat left;
  FlowFrame frame;
};

// Records what it is given on the queue's thread; optionally waits for a gate before each write,
// or fails one window.
class RecordingSink : public FlowSink {
 public:
  std::string name() const override { return "recording"; }
  Status Start() override {
    started = true;
    return Status::Ok();
  }
  Status Write(const FlowFrame& f) override {
    {
      std::unique_lock<std::mutex> lock(mu);
      entered.push_back(f.meta->window);
      cv.notify_all();
      cv.wait(lock, [&] { return open; });
    }
    if (f.meta->window == fail_window) return Status::Error("disk full");
    EXPECT_EQ(f.flow.size(), 18u);
    EXPECT_EQ(f.flow[17], static_cast<float>(f.meta->window));
    EXPECT_EQ(f.left_image->at<cv::Vec3b>(1, 2)[0], f.meta->window);
    written.push_back(f.meta->window);
    writer = std::this_thread::get_id();
    return Status::Ok();
  }
  void Retract() override { retracted.push_back(written.back()); }
  Status Stop() override {
    stopped = true;
    return Status::Ok();
  }
  void WaitEntered(size_t n) {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait(lock, [&] { return entered.size() >= n; });
  }
  void Open() {
    std::lock_guard<std::mutex> lock(mu);
    open = true;
    cv.notify_all();
  }

  std::mutex mu;
  std::condition_variable cv;
  bool open = true;
  int64_t fail_window = -1;
  std::vector<int64_t> entered, written, retracted;
  std::thread::id writer;
  bool started = false, stopped = false;
};

TEST(QueuedSink, BlockPolicyHandsEveryWindowInOrderToTheInnerSinksOnItsOwnThread) {
  RecordingSink a, b;
  QueuedSink q("pictures", {&a, &b}, 2, QueuePolicy::kBlock);
  ASSERT_TRUE(q.Start().ok());
  EXPECT_TRUE(a.started && b.started);
  for (int k = 0; k < 20; ++k) {
    Window w(k);  // gone once Write() returns: the queue holds its own copy
    ASSERT_TRUE(q.Write(w.frame).ok());
  }
  ASSERT_TRUE(q.Stop().ok());
  EXPECT_TRUE(a.stopped && b.stopped);
  std::vector<int64_t> all(20);
  for (int k = 0; k < 20; ++k) all[k] = k;
  EXPECT_EQ(a.written, all);
  EXPECT_EQ(b.written, all);
  EXPECT_NE(a.writer, std::this_thread::get_id());
  EXPECT_EQ(q.dropped(), 0u);
  EXPECT_EQ(q.write_ms().count, 20u);
}

// The inner sink is held inside window 0: window 1 waits in the one slot; window 2 takes its
// place (newest wins), counted; window 0 and 2 are written.
TEST(QueuedSink, NewestWinsDropsTheOldestWaitingWindowWhenTheEncoderFallsBehind) {
  RecordingSink a;
  a.open = false;
  QueuedSink q("pictures", {&a}, 1, QueuePolicy::kNewestWins);
  ASSERT_TRUE(q.Start().ok());
  Window w0(0), w1(1), w2(2);
  ASSERT_TRUE(q.Write(w0.frame).ok());
  a.WaitEntered(1);
  ASSERT_TRUE(q.Write(w1.frame).ok());
  ASSERT_TRUE(q.Write(w2.frame).ok());  // does not wait for the held encoder
  EXPECT_EQ(q.dropped(), 1u);
  a.Open();
  ASSERT_TRUE(q.Stop().ok());
  EXPECT_EQ(a.written, (std::vector<int64_t>{0, 2}));
  nlohmann::json j;
  q.ToJson(&j);
  EXPECT_EQ(j["dropped"], 1);
  EXPECT_EQ(j["windows"], 2);
  EXPECT_EQ(j["policy"], "newest-wins");
}

// A failure on the queue's thread names the inner sink and the window it failed on; the inner
// sinks before the failing one retract that window, the later windows still go through.
TEST(QueuedSink, InnerFailureNamesTheWindowAndTheSinksBeforeItRetractIt) {
  RecordingSink a, b;
  b.fail_window = 1;
  QueuedSink q("pictures", {&a, &b}, 1, QueuePolicy::kBlock);
  ASSERT_TRUE(q.Start().ok());
  Window w0(0), w1(1);
  ASSERT_TRUE(q.Write(w0.frame).ok());
  ASSERT_TRUE(q.Write(w1.frame).ok());
  Status s = q.Stop();  // drains the queue: window 1 has failed by now
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.message(),
            "recording of window seq_000001 (reported with a later window): disk full");
  EXPECT_EQ(a.written, (std::vector<int64_t>{0, 1}));
  EXPECT_EQ(a.retracted, (std::vector<int64_t>{1}));
  EXPECT_EQ(b.written, (std::vector<int64_t>{0}));
}

TEST(QueuedSink, FailureIsReportedOnceByWriteOrElseByStop) {
  {
    RecordingSink a;
    a.fail_window = 0;
    QueuedSink q("pictures", {&a}, 1, QueuePolicy::kBlock);
    ASSERT_TRUE(q.Start().ok());
    Window w0(0), w1(1), w2(2);
    ASSERT_TRUE(q.Write(w0.frame).ok());
    a.WaitEntered(1);
    Status s = Status::Ok();
    for (int i = 0; i < 5000 && s.ok(); ++i) {  // until the failure is recorded
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      Window probe(100 + i);
      s = q.Write(probe.frame);
    }
    ASSERT_FALSE(s.ok());
    EXPECT_EQ(s.message(),
              "recording of window seq_000000 (reported with a later window): disk full");
    EXPECT_TRUE(q.Write(w2.frame).ok());  // reported once
    EXPECT_TRUE(q.Stop().ok());
  }
  RecordingSink a;
  a.fail_window = 0;
  QueuedSink q("pictures", {&a}, 1, QueuePolicy::kBlock);
  ASSERT_TRUE(q.Start().ok());
  Window w0(0);
  ASSERT_TRUE(q.Write(w0.frame).ok());
  Status s = q.Stop();
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("window seq_000000"), std::string::npos) << s.message();
}

// Retract(): a window still waiting is never written; one already written is retracted by the
// inner sinks on the queue's thread.
TEST(QueuedSink, RetractTakesAWaitingWindowOutOrHasTheInnerSinksUndoIt) {
  RecordingSink a;
  a.open = false;
  QueuedSink q("pictures", {&a}, 1, QueuePolicy::kBlock);
  ASSERT_TRUE(q.Start().ok());
  Window w0(0), w1(1), w2(2);
  ASSERT_TRUE(q.Write(w0.frame).ok());
  a.WaitEntered(1);
  ASSERT_TRUE(q.Write(w1.frame).ok());  // waits in the slot
  q.Retract();                          // window 1 never reaches the inner sink
  a.Open();
  ASSERT_TRUE(q.Write(w2.frame).ok());
  a.WaitEntered(2);
  q.Retract();  // window 2: being written or written, then undone
  ASSERT_TRUE(q.Stop().ok());
  EXPECT_EQ(a.entered, (std::vector<int64_t>{0, 2}));
  EXPECT_EQ(a.retracted, (std::vector<int64_t>{2}));
}

}  // namespace
}  // namespace sfrt::pipeline
