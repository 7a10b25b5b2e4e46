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
// Order: per window the output stage first writes the files the options ask for (flow, PNG,
// video), then calls each sink of PipelineOptions::sinks in order, then records the window's
// latency (end to end = the end of the last sink - the capture of pair t+1). Sink time is output
// stage time, so a sink that needs longer than a frame period should hand the flow to its own
// thread (copying it) and return.
//
// Threads: Write() and Retract() come from the output stage's thread, one call at a time, so a
// sink needs no lock for its own state. Start() is called on RunPipeline()'s thread before the
// stages start (an error there ends the run before the first frame), Stop() on that thread after
// they have been joined (after the end of the source, a stop request or an error alike).
//
// Errors: a Write() that fails is a failed output of that window, handled as a failed file write
// (PipelineOptions::on_output_error: kStop ends the run with the message, kSkip drops the window
// and goes on). The window's files already written are removed and the sinks before it are told
// through Retract(), so a window is delivered everywhere or nowhere (except a frame already added
// to the --video AVI, which cannot be taken out).
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
  // After the last window (end of source, max frames, stop request or error), if Start()
  // succeeded.
  virtual void Stop() {}
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
