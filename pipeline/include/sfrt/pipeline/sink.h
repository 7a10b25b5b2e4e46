// Where the pipeline's flow goes: sinks, called by the output stage for every window (issue #13).
//
// A robot program receives flow in-process through a CallbackSink (or its own FlowSink) given
// in PipelineOptions::sinks; `sfrt run` adds none and writes files.
//
//   sfrt::pipeline::CallbackSink sink([](const sfrt::pipeline::FlowFrame& f) {
//     planner.Update(f.flow.data(), f.height, f.width, f.meta.capture_ns[1]);
//     return sfrt::Status::Ok();
//   });
//   options.sinks.push_back(&sink);
//   sfrt::pipeline::RunPipeline(model, source.get(), options);
//
// Order: per window the output stage calls Write() of the pipeline's own outputs (the flow
// files, PNG and video that PipelineOptions asks for, output_sinks.h), then of each sink of
// PipelineOptions::sinks in order; then it records the window's latency (end to end = the end of
// the last Write() - the capture of pair t+1) and calls every sink's Completed() with the final
// times (the latency log writes its line there). Sink time is output stage time, so a sink that
// needs longer than a frame period should hand the flow to its own thread (copying it) and return.
//
// Threads: Write(), Retract() and Completed() come from the output stage's thread, one call at a
// time, so a sink needs no lock for its own state. Start() is called on RunPipeline()'s thread
// before the stages start (an error there ends the run before the first frame), Stop() on that
// thread after they have been joined (after the end of the source, a stop request or an error
// alike); an error from Stop() (a video that could not be finished) fails the run.
//
// Errors: a Write() that fails is a failed output of that window, handled as a failed file write
// (PipelineOptions::on_output_error: kStop ends the run with the message, kSkip drops the window
// and goes on). The sinks before it are told through Retract() (the file sinks remove the
// window's files), so a window is delivered everywhere or nowhere (except a frame already added
// to the video, which cannot be taken out). A Completed() that fails ends the run under kStop;
// under kSkip the run warns and that sink gets no more Completed() calls (a CSV log would be
// unreadable with a line missing).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>

#include "sfrt/pipeline/pipeline.h"
#include "sfrt/status.h"

namespace sfrt::pipeline {

// One window's flow as a sink sees it: views into the output stage's buffers, no copy.
// Lifetime: every view (flow, left_image, step_ns) and `meta` are valid only until Write()
// returns; the buffers are reused for later windows. A sink that keeps the flow copies it.
struct FlowFrame {
  const FrameMeta* meta = nullptr;  // window and frame numbers (the camera's sequence numbers for
                                    // live sources), capture times of both pairs, stage times
                                    // (the output stage's start is set; its end is not yet)
  std::span<const float> flow;      // height x width x channels floats, row-major (HWC): per
                                    // pixel dX, dY, dZ in the model's output units (metres for
                                    // the default model), camera frame of the left camera at t
  int height = 0;                   // the size this window ran at: the model input size, or the
  int width = 0;                    // smaller-input fallback size after a deadline miss
  int channels = 0;
  // The rectified left image at t, BGR8, at the model input size (not the fallback size).
  const cv::Mat* left_image = nullptr;
  // Milliseconds from the capture of pair t+1 to this call, and whether that is already over
  // PipelineOptions::budget_ms (false without a budget). The window's final end-to-end latency
  // and deadline verdict (in the summary) also count the sinks after this one.
  double latency_ms = 0;
  bool over_budget = false;
};

// A window every sink has written, with its final times, for sinks that log timing.
struct WindowRecord {
  const FrameMeta* meta = nullptr;  // every stage's start and end set
  double end_to_end_ms = 0;         // end of the output stage - capture of pair t+1
  bool miss = false;                // over PipelineOptions::budget_ms (or the test's verdict)
  // Session::Run's step end times (steps + 1, CLOCK_MONOTONIC ns) when PipelineOptions::profiler
  // is set; empty otherwise.
  std::span<const int64_t> step_ns;
};

class FlowSink {
 public:
  virtual ~FlowSink() = default;
  // Names the sink in error messages and the summary, e.g. "callback".
  virtual std::string name() const = 0;
  // Before the stages start: e.g. to allocate buffers, so Write() need not.
  virtual Status Start() { return Status::Ok(); }
  // One window. All or nothing: an error means this sink delivered nothing of this window.
  virtual Status Write(const FlowFrame& frame) = 0;
  // A sink after this one failed on the window this sink last wrote: undo it if it can.
  virtual void Retract() {}
  // After every sink has written the window (the window's record is valid until it returns).
  virtual Status Completed(const WindowRecord& /*record*/) { return Status::Ok(); }
  // After the last window (end of source, max frames, stop request or error), if Start()
  // succeeded: finish and flush. An error fails the run.
  virtual Status Stop() { return Status::Ok(); }
  // Facts for summary.json's "sinks" entry of this sink (after Stop()), e.g. queued_sink.h's
  // encoder times; nothing by default.
  virtual void ToJson(nlohmann::json* /*out*/) const {}
  // The run's summary, the document summary.json holds (every sink's ToJson() in it), once at the
  // very end of every RunPipeline(), on its thread: after Stop(), or after a setup that failed
  // (then Start() may not have run; the summary says why the run never started). E.g. the
  // summary file (output_sinks.h: SummaryFileSink) or a robot program's own report. An error
  // fails a run that had none (otherwise it is a warning).
  virtual Status Finished(const nlohmann::json& /*summary*/) { return Status::Ok(); }
};

// Hands each window to a function. The function runs on the output stage's thread; what it
// returns is the sink's Write() result.
class CallbackSink final : public FlowSink {
 public:
  using Callback = std::function<Status(const FlowFrame&)>;
  explicit CallbackSink(Callback callback, std::string name = "callback")
      : callback_(std::move(callback)), name_(std::move(name)) {}
  std::string name() const override { return name_; }
  Status Write(const FlowFrame& frame) override { return callback_(frame); }

 private:
  Callback callback_;
  std::string name_;
};

}  // namespace sfrt::pipeline
