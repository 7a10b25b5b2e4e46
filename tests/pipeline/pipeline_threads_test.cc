// Proves sink.h's thread promise: a sink's Write(), Retract() and Completed() all come from the
// output stage's thread (not the caller's, not the source's), one call at a time; Start() comes
// on RunPipeline()'s thread before any stage starts, Stop() on it once every stage thread has
// ended, and Finished() on it after Stop().
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "pipeline/fake_window.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/sink.h"

namespace sfrt::pipeline {
namespace {

namespace fs = std::filesystem;

constexpr int kH = 32;
constexpr int kW = 48;

// Counts the stage threads that have ended: a stage thread's copy is armed by on_stage_start,
// and its destructor runs when that thread exits, before RunPipeline() can join it.
struct ExitCounter {
  std::atomic<int>* exited = nullptr;
  ~ExitCounter() {
    if (exited != nullptr) exited->fetch_add(1);
  }
};
thread_local ExitCounter t_exit_counter;

// What every call saw: its thread, whether another call was inside a sink at the same time, and
// how far the stages were.
struct CallLog {
  struct Call {
    std::string what;  // "<sink>.<method>"
    std::thread::id thread;
    int stages_started = 0;  // on_stage_start calls before this call
    int stages_exited = 0;   // stage threads ended before this call
  };
  std::mutex mu;
  std::vector<Call> calls;
  std::atomic<int> inside{0};
  std::atomic<int> overlaps{0};
  std::atomic<int> stages_started{0};
  std::atomic<int> stages_exited{0};
  std::thread::id stage_thread[4];

  // Marks a call inside a sink for its whole length; the yield and sleep widen the window in
  // which a second call from another thread would be seen.
  void Enter(const std::string& what) {
    if (inside.fetch_add(1) != 0) overlaps.fetch_add(1);
    std::this_thread::yield();
    std::this_thread::sleep_for(std::chrono::microseconds(50));
    {
      std::lock_guard<std::mutex> lock(mu);
      calls.push_back(
          {what, std::this_thread::get_id(), stages_started.load(), stages_exited.load()});
    }
    std::this_thread::yield();
    if (inside.load() != 1) overlaps.fetch_add(1);
    inside.fetch_sub(1);
  }
};

// Records every call; Write() fails on the windows `fail_write` says.
class RecordingSink : public FlowSink {
 public:
  RecordingSink(std::string name, CallLog* log, std::function<bool(int64_t window)> fail_write)
      : name_(std::move(name)), log_(log), fail_write_(std::move(fail_write)) {}
  std::string name() const override { return name_; }
  Status Start() override {
    log_->Enter(name_ + ".Start");
    return Status::Ok();
  }
  Status Write(const FlowFrame& frame) override {
    log_->Enter(name_ + ".Write");
    ++writes;
    if (fail_write_ && fail_write_(frame.meta->window)) {
      return Status::Error("window " + std::to_string(frame.meta->window) + " refused");
    }
    return Status::Ok();
  }
  void Retract() override {
    log_->Enter(name_ + ".Retract");
    ++retracts;
  }
  Status Completed(const WindowRecord&) override {
    log_->Enter(name_ + ".Completed");
    ++completed;
    return Status::Ok();
  }
  Status Stop() override {
    log_->Enter(name_ + ".Stop");
    return Status::Ok();
  }
  Status Finished(const nlohmann::json&) override {
    log_->Enter(name_ + ".Finished");
    return Status::Ok();
  }
  int writes = 0, retracts = 0, completed = 0;

 private:
  std::string name_;
  CallLog* log_;
  std::function<bool(int64_t)> fail_write_;
};

// Windows (k, k+1) of seeded noise; records the threads Next() runs on.
class NoiseSource : public FrameSource {
 public:
  explicit NoiseSource(int windows) : windows_(windows) {}
  Result<cv::Size> Open() override { return cv::Size(kW, kH); }
  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>&) override {
    {
      std::lock_guard<std::mutex> lock(mu_);
      threads_.insert(std::this_thread::get_id());
    }
    if (next_ >= windows_) return Fetch::kEnd;
    for (auto [mat, k] : {std::pair{&item->left0, 2 * next_},
                          {&item->right0, 2 * next_ + 1},
                          {&item->left1, 2 * next_ + 2},
                          {&item->right1, 2 * next_ + 3}}) {
      mat->create(kH, kW, CV_8UC3);
      cv::RNG rng(static_cast<uint64_t>(1000 + k));
      rng.fill(*mat, cv::RNG::UNIFORM, 0, 256);
    }
    item->meta.sequence = "seq";
    StampFakeWindow(&item->meta, next_);
    ++next_;
    return Fetch::kWindow;
  }
  std::string Describe() const override { return "noise"; }
  std::string kind() const override { return "noise"; }
  std::optional<int64_t> total_windows() const override { return windows_; }
  bool live() const override { return false; }
  void ToJson(nlohmann::json* out) const override { (*out)["noise"] = true; }

  std::set<std::thread::id> threads() const {
    std::lock_guard<std::mutex> lock(mu_);
    return threads_;
  }

 private:
  int windows_;
  int next_ = 0;
  mutable std::mutex mu_;
  std::set<std::thread::id> threads_;
};

TEST(PipelineSinksTest, EverySinkCallComesFromTheOutputThreadOneAtATime) {
  auto model =
      Model::LoadFile(std::string(SFRT_SOURCE_DIR) + "/tools/demo/sceneednet-w16-demo.sfrt");
  ASSERT_TRUE(model.ok()) << model.message();
  const fs::path dir =
      fs::temp_directory_path() / ("sfrt_pipeline_threads_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);

  constexpr int kWindows = 30;
  // "b" refuses windows 2, 7, 12, ...: under kSkip the window is dropped and "a" (before it)
  // retracts it; "c" (after it) never sees it.
  const auto refused = [](int64_t window) { return window % 5 == 2; };
  constexpr int kRefused = kWindows / 5;
  CallLog log;
  RecordingSink a("a", &log, nullptr);
  RecordingSink b("b", &log, refused);
  RecordingSink c("c", &log, nullptr);
  NoiseSource source(kWindows);
  PipelineOptions options;
  options.out_dir = dir.string();
  options.progress = ProgressMode::kOff;
  options.model_path = "demo";
  options.on_output_error = OutputErrorPolicy::kSkip;
  options.picture_queue = 2;  // the pictures' encoder on a thread of its own besides the stages
  options.sinks = {&a, &b, &c};
  options.on_stage_start = [&log](int stage) {
    log.stage_thread[stage] = std::this_thread::get_id();
    t_exit_counter.exited = &log.stages_exited;
    log.stages_started.fetch_add(1);
  };
  const std::thread::id caller = std::this_thread::get_id();
  PipelineResult r = RunPipeline(*model, &source, options);
  fs::remove_all(dir);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  ASSERT_EQ(r.frames, kWindows - kRefused);
  ASSERT_EQ(r.output_errors, kRefused);

  // The counts show every kind of call happened.
  EXPECT_EQ(a.writes, kWindows);
  EXPECT_EQ(a.retracts, kRefused);
  EXPECT_EQ(b.writes, kWindows);
  EXPECT_EQ(b.retracts, 0);
  EXPECT_EQ(c.writes, kWindows - kRefused);
  for (const RecordingSink* s : {&a, &b, &c}) EXPECT_EQ(s->completed, r.frames) << s->name();

  // The stage threads are four distinct threads, none the caller's.
  ASSERT_EQ(log.stages_started.load(), 4);
  ASSERT_EQ(log.stages_exited.load(), 4);
  const std::set<std::thread::id> stages(std::begin(log.stage_thread), std::end(log.stage_thread));
  EXPECT_EQ(stages.size(), 4u);
  EXPECT_EQ(stages.count(caller), 0u);
  const std::thread::id output = log.stage_thread[3];
  // The source ran on the source stage's thread (Open() aside, it is called only from there).
  EXPECT_EQ(source.threads(), std::set<std::thread::id>{log.stage_thread[0]});

  EXPECT_EQ(log.overlaps.load(), 0) << "two sink calls were inside a sink at the same time";
  int per_window = 0, starts = 0, stops = 0, finishes = 0;
  bool stopped = false;  // a Stop() was seen: no Write, Retract or Completed may follow
  for (const CallLog::Call& call : log.calls) {
    const std::string method = call.what.substr(call.what.find('.') + 1);
    SCOPED_TRACE(call.what);
    if (method == "Write" || method == "Retract" || method == "Completed") {
      ++per_window;
      EXPECT_EQ(call.thread, output) << "not on the output stage's thread";
      EXPECT_NE(call.thread, caller);
      EXPECT_NE(call.thread, log.stage_thread[0]);
      EXPECT_FALSE(stopped) << "after a Stop()";
    } else if (method == "Start") {
      ++starts;
      EXPECT_EQ(call.thread, caller);
      EXPECT_EQ(call.stages_started, 0) << "a stage had started";
      EXPECT_EQ(per_window, 0);
    } else if (method == "Stop") {
      ++stops;
      stopped = true;
      EXPECT_EQ(call.thread, caller);
      EXPECT_EQ(call.stages_exited, 4) << "a stage thread was still running";
      EXPECT_EQ(finishes, 0);
    } else if (method == "Finished") {
      ++finishes;
      EXPECT_EQ(call.thread, caller);
      EXPECT_EQ(stops, 3) << "Finished() before every sink's Stop()";
    } else {
      ADD_FAILURE() << "unexpected call";
    }
  }
  EXPECT_EQ(per_window, 2 * kWindows + (kWindows - kRefused) + kRefused + 3 * r.frames);
  EXPECT_EQ(starts, 3);
  EXPECT_EQ(stops, 3);
  EXPECT_EQ(finishes, 3);
}

}  // namespace
}  // namespace sfrt::pipeline
