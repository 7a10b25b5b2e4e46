// Proves pipeline.h's memory promise for the infer stage: once the first window is through,
// the infer stage's thread allocates nothing (it only swaps and calls Session::Run), also when
// the smaller-input fallback (PipelineOptions::smaller_input_on_miss) switches the size back and
// forth, and with --profile's step times. This program links the counting allocator
// (tests/common/counting_allocator.h), whose per-thread tags attribute every allocation to the
// stage whose thread made it; not built with sanitizers, which own the allocator.
//
// Only the infer stage is held to "no allocation": the preprocess stage's cv::resize allocates
// its scratch tables on every call that changes the size (each window at the fallback size, and
// every window when the frames are not at the model input size), and the output stage writes
// files.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "common/counting_allocator.h"
#include "pipeline/fake_window.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/profiler.h"

namespace sfrt::pipeline {
namespace {

namespace fs = std::filesystem;
using sfrt::testing::SetThreadAllocationTag;
using sfrt::testing::TaggedAllocationCount;

constexpr int kH = 32;
constexpr int kW = 48;
constexpr int kFbH = 20;  // the smaller-input fallback size
constexpr int kFbW = 36;
// Stage s's thread counts under tag s + 1.
constexpr int kStages = 4;
constexpr const char* kStage[kStages] = {"source", "preprocess", "infer", "output"};
constexpr int kInfer = 2;

// Windows (k, k+1) of seeded noise, in lockstep with the output stage: window k is read only
// once window k - 1 is written (and the on-miss state updated), so which size each window runs
// at does not depend on timing, and while the output stage handles window k the other stages
// wait for work. Each window carries a path too long for the small-string buffer, so the meta
// the infer stage swaps holds heap strings.
class LockstepSource : public FrameSource {
 public:
  LockstepSource(int windows, const std::atomic<int64_t>* done) : windows_(windows), done_(done) {}
  Result<cv::Size> Open() override { return cv::Size(kW, kH); }
  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>& stop) override {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (done_->load() < next_ && next_ < windows_ && !stop.load() &&
           std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::microseconds(200));
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
    char path[64];
    std::snprintf(path, sizeof(path), "/data/replay/sequence-a/left/%06d.png", next_);
    item->meta.left0_path = path;
    item->meta.sequence = "sequence-a/left-and-right";
    StampFakeWindow(&item->meta, next_);
    ++next_;
    return Fetch::kWindow;
  }
  std::string Describe() const override { return "lockstep noise"; }
  std::string kind() const override { return "lockstep"; }
  std::optional<int64_t> total_windows() const override { return windows_; }
  bool live() const override { return false; }
  void ToJson(nlohmann::json* out) const override { (*out)["lockstep"] = true; }

 private:
  int windows_;
  int next_ = 0;
  const std::atomic<int64_t>* done_;
};

// A run's allocations per stage thread: after each written window (taken on the output stage,
// while the other stages wait for the next window) and once RunPipeline() has returned (every
// stage thread joined).
struct CountedRun {
  struct Window {
    long count[kStages] = {};
    int input_height = 0;
  };
  PipelineResult result;
  long start_count[kStages] = {};  // before RunPipeline()
  std::vector<Window> windows;
  long final_count[kStages] = {};
  // Infer-stage allocations from the end of window 0 to the end of the run.
  long InferAfterFirstWindow() const {
    return windows.empty() ? -1 : final_count[kInfer] - windows[0].count[kInfer];
  }
  // Stage s's allocations per window (window k: from the end of k - 1 to the end of k), and
  // after the last window; for the messages.
  std::string Table() const {
    std::string text;
    for (int s = 0; s < kStages; ++s) {
      text += std::string(kStage[s]) + ":";
      long before = start_count[s];
      for (const Window& w : windows) {
        text += " " + std::to_string(w.count[s] - before);
        before = w.count[s];
      }
      text += " | after the last window " + std::to_string(final_count[s] - before) + "\n";
    }
    text += "input height:";
    for (const Window& w : windows) text += " " + std::to_string(w.input_height);
    return text + "\n";
  }
};

long StageCount(int stage) { return TaggedAllocationCount(stage + 1); }

CountedRun RunCounted(int windows, PipelineOptions options) {
  CountedRun run;
  auto model =
      Model::LoadFile(std::string(SFRT_SOURCE_DIR) + "/tools/demo/sceneednet-w16-demo.sfrt");
  EXPECT_TRUE(model.ok()) << model.message();
  if (!model.ok()) return run;
  const fs::path dir =
      fs::temp_directory_path() / ("sfrt_pipeline_allocation_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  options.out_dir = dir.string();
  options.progress = ProgressMode::kOff;
  options.model_path = "demo";
  options.write_png = false;
  std::atomic<int64_t> done{0};
  run.windows.reserve(static_cast<size_t>(windows));  // the snapshots allocate nothing
  options.on_stage_start = [](int stage) { SetThreadAllocationTag(stage + 1); };
  options.after_window = [&](const FrameMeta& meta) {
    CountedRun::Window w;
    for (int s = 0; s < kStages; ++s) w.count[s] = StageCount(s);
    w.input_height = meta.input_height;
    run.windows.push_back(w);
    ++done;
  };
  LockstepSource source(windows, &done);
  for (int s = 0; s < kStages; ++s) run.start_count[s] = StageCount(s);
  run.result = RunPipeline(*model, &source, options);
  for (int s = 0; s < kStages; ++s) run.final_count[s] = StageCount(s);
  fs::remove_all(dir);
  EXPECT_TRUE(run.result.status.ok()) << run.result.status.message();
  EXPECT_EQ(run.result.frames, windows);
  EXPECT_EQ(run.windows.size(), static_cast<size_t>(windows));
  // The tag reached the infer stage's thread: its working buffers, made when it starts, count.
  if (!run.windows.empty()) {
    EXPECT_GT(run.windows[0].count[kInfer], run.start_count[kInfer]);
  }
  return run;
}

TEST(PipelineAllocationTest, CountingHooksSeeAnAllocationOnATaggedThread) {
  EXPECT_TRUE(sfrt::testing::CountingHooksAreLive());
  long counted = -1;
  std::thread([&] {
    SetThreadAllocationTag(7);
    const long before = TaggedAllocationCount(7);
    static void* volatile sink = nullptr;
    sink = std::malloc(64);
    std::free(sink);
    sink = ::operator new(64);
    ::operator delete(sink);
    counted = TaggedAllocationCount(7) - before;
    SetThreadAllocationTag(0);
  }).join();
  EXPECT_EQ(counted, 2);
}

// With and without --profile's step times (Session::Run's timed overload), with one session
// thread and a pool of two (the pool's workers are untagged here; zero_allocation_test holds
// Session::Run to no allocation on every thread).
TEST(PipelineAllocationTest, TheInferStageAllocatesNothingAfterTheFirstWindow) {
  for (bool profiled : {false, true}) {
    for (int threads : {1, 2}) {
      SCOPED_TRACE(std::string(profiled ? "profiled, " : "") + std::to_string(threads) +
                   " session threads");
      FrameProfiler profiler(64);
      PipelineOptions options;
      options.threads = threads;
      if (profiled) options.profiler = &profiler;
      const CountedRun run = RunCounted(20, options);
      EXPECT_EQ(run.InferAfterFirstWindow(), 0) << run.Table();
      if (profiled) {
        EXPECT_EQ(profiler.recorded(), 20u);
      }
    }
  }
}

TEST(PipelineAllocationTest, TheInferStageAllocatesNothingWhileTheSizeSwitchesBackAndForth) {
  // A budget every window misses: window 0 runs at the model input size, every later window at
  // the fallback size.
  {
    SCOPED_TRACE("every window over budget");
    PipelineOptions options;
    options.on_miss = config::MissAction::kSmallerInput;
    options.smaller_input_on_miss = {kFbH, kFbW};
    options.budget_ms = 0.001;
    const CountedRun run = RunCounted(20, options);
    EXPECT_EQ(run.result.misses, 20);
    EXPECT_EQ(run.result.fallback_entries, 1);
    EXPECT_EQ(run.result.frames_at_fallback_size, 19);
    EXPECT_EQ(run.InferAfterFirstWindow(), 0) << run.Table();
  }
  // The size switched back and forth: every even window misses (decided by the test seam, not
  // by the clock) and one in-budget window at the fallback size recovers, so the windows
  // alternate between the model input size and the fallback size.
  {
    SCOPED_TRACE("the size switching back and forth");
    PipelineOptions options;
    options.on_miss = config::MissAction::kSmallerInput;
    options.smaller_input_on_miss = {kFbH, kFbW};
    options.budget_ms = 1e7;
    options.recover_after = 1;
    options.miss_verdict = [](const FrameMeta& m, bool) { return m.window % 2 == 0; };
    constexpr int kWindows = 20;
    const CountedRun run = RunCounted(kWindows, options);
    ASSERT_EQ(run.windows.size(), static_cast<size_t>(kWindows));
    for (int k = 0; k < kWindows; ++k) {
      EXPECT_EQ(run.windows[k].input_height, k % 2 == 0 ? kH : kFbH) << "window " << k;
    }
    EXPECT_EQ(run.result.fallback_entries, kWindows / 2);
    EXPECT_EQ(run.result.frames_at_fallback_size, kWindows / 2);
    EXPECT_EQ(run.InferAfterFirstWindow(), 0) << run.Table();
  }
}

}  // namespace
}  // namespace sfrt::pipeline
