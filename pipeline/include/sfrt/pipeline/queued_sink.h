// A sink that runs other sinks on a thread of its own, so slow encoders (PNG, video) leave the
// output stage's critical path: Write() copies the window into one of `depth` preallocated
// slots and returns; the sink's thread hands each queued window to the inner sinks in order.
// End-to-end latency then ends when the window is queued; the encoders' own time is measured
// (ToJson: write_ms) and, for replays, bounds the throughput like a stage.
//
// When every slot is full, QueuePolicy decides, as between the stages: kBlock waits for a slot
// (replays: every window is encoded), kNewestWins drops the oldest window still waiting (live
// cameras: the pictures keep up with the flow; the drops are counted).
//
// What changes against the inner sinks run directly:
// - Errors: an inner Write() failure is returned by the next Write() (naming the window it
//   failed on; that window's other outputs are already delivered), or by Stop(). Under
//   OutputErrorPolicy::kStop the run still ends on it.
// - Retract() takes the window out of the queue if it is still waiting, else has the inner sinks
//   retract it once they have written it.
// - Completed() is not forwarded: give sinks that log timing to the pipeline directly.
// - Memory: a slot holds a copy of the flow, the left image and the window's metadata; the slots
//   reach their size on the first windows and are reused (no allocation once they have).
//
// Threads: Start(), Write(), Retract() and Stop() from one thread (the pipeline's), the inner
// sinks' Start() and Stop() on that thread too, their Write() and Retract() on the sink's
// thread, one call at a time.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <thread>
#include <vector>

#include "sfrt/pipeline/latest_queue.h"
#include "sfrt/pipeline/sink.h"
#include "sfrt/pipeline/stats.h"

namespace sfrt::pipeline {

class QueuedSink final : public FlowSink {
 public:
  // `inner` are not owned and must outlive this sink; depth >= 1.
  QueuedSink(std::string name, std::vector<FlowSink*> inner, size_t depth, QueuePolicy policy);
  ~QueuedSink() override;  // stops the thread if Stop() was not called (errors are lost)
  QueuedSink(const QueuedSink&) = delete;
  QueuedSink& operator=(const QueuedSink&) = delete;

  std::string name() const override { return name_; }
  Status Start() override;
  Status Write(const FlowFrame& frame) override;
  void Retract() override;
  Status Stop() override;
  // {"queued": depth, "policy", "windows" written by the inner sinks, "dropped", "write_ms"
  // (the inner sinks' time per window: p50/p90/p99/max/count)}.
  void ToJson(nlohmann::json* out) const override;

  uint64_t dropped() const;
  profiling::Summary write_ms() const;          // after Stop()
  std::vector<double> write_ms_values() const;  // the samples behind write_ms()

 private:
  struct Slot {
    FrameMeta meta;
    std::vector<float> flow;
    cv::Mat left;
    int height = 0, width = 0, channels = 0;
    double latency_ms = 0;
    bool over_budget = false;
    uint64_t seq = 0;  // the Write() it holds (1, 2, ...)
  };
  void Work();
  bool WriteInner(Slot& slot, Status* error);

  std::string name_;
  std::vector<FlowSink*> inner_;
  size_t depth_;
  QueuePolicy policy_;
  std::vector<Slot> slots_;  // depth_ waiting + 1 being written
  std::thread worker_;
  bool started_ = false;

  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<size_t> free_;   // slot indices
  std::vector<size_t> queue_;  // slot indices waiting, oldest first (at most depth_)
  uint64_t written_seq_ = 0;   // the last Write() accepted
  uint64_t done_seq_ = 0;      // the last window the worker finished (written or failed)
  uint64_t last_ok_seq_ = 0;   // the last window every inner sink wrote
  uint64_t retract_seq_ = 0;   // a window to retract once done (0: none)
  bool stopping_ = false;
  Status error_ = Status::Ok();  // the worker's first unreported failure
  uint64_t dropped_ = 0;
  uint64_t windows_ = 0;
  profiling::LatestValues write_ms_;
};

}  // namespace sfrt::pipeline
