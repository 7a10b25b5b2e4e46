// The pipeline's own outputs as sinks (sink.h): the flow files, the visualisation PNGs, the
// visualisation video, the latency log and the summary. RunPipeline makes them from
// PipelineOptions (write_flow, write_png, video_path, latency_log, write_summary) and runs them
// before PipelineOptions::sinks (the summary file after them);
// a program may also make them itself and put them in PipelineOptions::sinks, in any order and
// any number (two flow formats, two directories).
//
// Every file is written to a temporary name and renamed (io/atomic_write.h), so a reader never
// sees half a file. Errors name the file and the system's reason.
//
// Threads: like every sink, used by one thread at a time: the output stage's, or the queue's
// thread when they run behind a QueuedSink (queued_sink.h).
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

#include "sfrt/config/vocabulary.h"
#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/sink.h"
#include "sfrt/pipeline/visualize.h"

namespace sfrt::pipeline {

// <dir>/<stem>.pfm or .npy for each window (OutputStem), at the size the window ran at. PFM holds
// 1 or 3 channels; Start() cannot know the channel count, so a 2-channel flow fails its first
// Write() with a message that says to use npy (RunPipeline checks this at setup).
class FlowFileSink final : public FlowSink {
 public:
  FlowFileSink(std::string dir, config::FlowFormat format);
  std::string name() const override { return "flow files"; }
  Status Write(const FlowFrame& frame) override;
  void Retract() override;  // removes the file of the last window
  Status Stop() override;   // flushes the files to disk (written with io::Flush::kLater)

 private:
  std::string dir_;
  config::FlowFormat format_;
  std::string last_path_;
  bool wrote_ = false;
};

// Draws each window's visualisation (visualize.h: the left image, the flow's X/Y and Z colour
// coding and a legend) once, for every sink that shows it (PngSink, VideoSink). A window that ran
// at a smaller input size (latency.on_miss smaller-input) has its flow upscaled (bilinear) to the
// left image's size, so every picture of a run has one size; its label says the size it ran at.
// Buffers are sized at the first window and reused.
class FlowRenderer {
 public:
  explicit FlowRenderer(VisualizerOptions options) : vis_(std::move(options)) {}
  // The canvas of this frame's window, drawn on the first call for that window (a window is known
  // by its number and its capture time).
  const cv::Mat& Render(const FlowFrame& frame);

 private:
  Visualizer vis_;
  cv::Mat canvas_;
  int64_t window_ = -1;
  int64_t capture_ns_ = 0;
  std::vector<float> upscaled_;
};

class PngEncoder;

// <dir>/<stem>.png: the renderer's canvas, encoded for speed (src/png_encoder.h: the Up filter,
// libdeflate level 1; lossless).
class PngSink final : public FlowSink {
 public:
  PngSink(std::string dir, FlowRenderer* renderer);
  ~PngSink() override;
  std::string name() const override { return "png"; }
  Status Write(const FlowFrame& frame) override;
  void Retract() override;
  Status Stop() override;  // flushes the files to disk (written with io::Flush::kLater)

 private:
  std::string dir_;
  FlowRenderer* renderer_;
  std::unique_ptr<PngEncoder> encoder_;  // its compressor and rows kept between pictures
  std::vector<uint8_t> png_;
  std::string last_path_;
  bool wrote_ = false;
};

// One MJPG AVI of the renderer's canvases at `fps`. Start() refuses a path the AVI writer cannot
// finish (ResolveVideoPath); frames go to "<path>.tmp.avi", which Stop() checks (OpenCV's writer
// reports no failed write) and renames onto the path, so an existing file is replaced only by a
// complete video. A frame cannot be taken out of the AVI: Retract() does nothing.
class VideoSink final : public FlowSink {
 public:
  VideoSink(std::string path, double fps, FlowRenderer* renderer)
      : path_(std::move(path)), fps_(fps), renderer_(renderer) {}
  std::string name() const override { return "video"; }
  Status Start() override;
  Status Write(const FlowFrame& frame) override;
  Status Stop() override;
  bool written() const { return written_; }  // a complete video replaced the path
  int64_t frames() const { return frames_; }

 private:
  std::string path_;
  double fps_;
  FlowRenderer* renderer_;
  std::string final_;  // the path after following symbolic links
  std::string tmp_;
  cv::VideoWriter writer_;
  int64_t frames_ = 0;
  bool written_ = false;
};

// A CSV file, one line per window once every sink has written it (Completed): window number,
// the four stage durations and end to end (ms), the input size it ran at and when it was done on
// CLOCK_MONOTONIC (shared by every process, so the logs of runs side by side line up; soak.sh
// compares with a concurrent twin). Streamed as the run goes (a soak's log is long), and flushed
// to disk at Stop().
class LatencyLogSink final : public FlowSink {
 public:
  explicit LatencyLogSink(std::string path) : path_(std::move(path)) {}
  std::string name() const override { return "latency log"; }
  Status Start() override;
  Status Write(const FlowFrame&) override { return Status::Ok(); }
  Status Completed(const WindowRecord& record) override;
  Status Stop() override;

 private:
  std::string path_;
  io::StreamedFile file_;
};

// <dir>/windows.csv: which source frames each written window came from, one line per window once
// every sink has written it: the file stem of its outputs (OutputStem), the sequence, the frame
// numbers of pair t and t+1 (file numbers, camera sequence numbers, a bag's message numbers) and
// their stamps in ns (0 where the source has none), and where pair t's left image came from.
// Windows are named by their source, never by a count, so a gap in the source shows here as a
// gap in frame_t. Streamed as the run goes (made at the first window), flushed at Stop().
class WindowIndexSink final : public FlowSink {
 public:
  explicit WindowIndexSink(std::string dir);
  std::string name() const override { return "window index"; }
  Status Write(const FlowFrame&) override { return Status::Ok(); }
  Status Completed(const WindowRecord& record) override;
  Status Stop() override;
  const std::string& path() const { return path_; }

 private:
  Status Open();

  std::string path_;
  bool opened_ = false;
  io::StreamedFile file_;
};

// <dir>/summary.json: the run's summary (FlowSink::Finished), written atomically (a temporary name
// renamed), pretty-printed. PipelineOptions::write_summary makes one.
class SummaryFileSink final : public FlowSink {
 public:
  explicit SummaryFileSink(std::string dir);
  std::string name() const override { return "summary"; }
  Status Write(const FlowFrame&) override { return Status::Ok(); }
  Status Finished(const nlohmann::json& summary) override;
  const std::string& path() const { return path_; }
  bool written() const { return written_; }

 private:
  std::string path_;
  bool written_ = false;
};

}  // namespace sfrt::pipeline
