#include "sfrt/pipeline/pipeline.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <span>
#include <thread>
#include <utility>

#include "clock.h"
#include "sfrt/camera/rectifier.h"
#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/log.h"
#include "sfrt/pipeline/output_sinks.h"
#include "sfrt/pipeline/profiler.h"
#include "sfrt/pipeline/queued_sink.h"
#include "sfrt/pipeline/sink.h"
#include "sfrt/pipeline/visualize.h"
#include "sfrt/session.h"

namespace sfrt::pipeline {
namespace {

using nlohmann::json;

using config::kStageNames;  // "source", "preprocess", "infer", "output"

using detail::NowNs;

double Ms(int64_t ns) { return static_cast<double>(ns) / 1e6; }

using profiling::FormatFixed;

// The latest 65,536 latencies of one kind (stats.h): percentiles in the summary describe these
// latest windows, in a constant resident size.
using LatencyWindow = profiling::LatestValues;

struct InputItem {
  FrameMeta meta;
  cv::Mat left_vis;               // rectified left image at t, model size (for the visualisation)
  std::vector<float> input;       // height x width x 12, or empty on the uint8 input path
  std::vector<uint8_t> input_u8;  // the uint8 input path's (PipelineOptions::quantized_input)
};

struct FlowItem {
  FrameMeta meta;
  cv::Mat left_vis;
  std::vector<float> flow;       // height x width x output channels
  std::vector<int64_t> step_ns;  // --profile: Session::Run's step end times (steps + 1)
};

// --profile: each written window's stage and step times into the profiler's ring.
class ProfilerSink final : public FlowSink {
 public:
  explicit ProfilerSink(FrameProfiler* profiler) : profiler_(profiler) {}
  std::string name() const override { return "profiler"; }
  Status Write(const FlowFrame&) override { return Status::Ok(); }
  Status Completed(const WindowRecord& record) override {
    profiler_->Record(*record.meta, record.step_ns, record.miss);
    return Status::Ok();
  }

 private:
  FrameProfiler* profiler_;
};

class Runner {
 public:
  Runner(std::shared_ptr<const Model> model, FrameSource* source, const PipelineOptions& options)
      : model_(std::move(model)),
        source_(source),
        options_(options),
        log_(options.log != nullptr ? *options.log : DefaultLog()) {}

  PipelineResult Run();

 private:
  Status Setup();
  Status SetupInputSize();
  Status SetupRectifier();
  void WarnOfCameraChange();
  Status SetupSession();
  Status CheckOutputShapes();
  Status SetupRun();
  void SourceStage();
  void PreprocessStage();
  void InferStage();
  void OutputStage();
  void Fail(const Status& status, bool discard);
  Status StartSinks();
  Status DeliverToSinks(const FlowItem& f, std::span<const float> flow);
  bool CompleteSinks(const WindowRecord& record, const std::string& stem);
  Status StopSinks();
  Status SetupFallback();
  // Windows arrive at the source's own rate (a live source, or a replay at source_fps): its end
  // to end is a latency, and pictures must not hold back the flow.
  bool Paced() const { return source_->live() || options_.source_fps > 0; }
  void UpdateFallback(const FrameMeta& m, bool miss);
  void Progress(bool final);
  // Builds the summary and hands it to every sink's Finished() (the caller's, then the file's).
  Status FinishSinks(PipelineResult* result);
  json SamplesJson() const;  // PipelineOptions::summary_samples
  void AddEventsJson(json* out) const;
  void AddLatencyJson(const PipelineResult& result, json* out) const;
  WindowItem MakeWindow() const;
  InputItem MakeInput() const;
  // The window's network input into `in` at `pre`'s size (its start when smaller): float32, or
  // uint8 on the uint8 input path.
  camera::Status Preprocess(const camera::Preprocessor& pre, const cv::Mat& l0, const cv::Mat& r0,
                            const cv::Mat& l1, const cv::Mat& r1, InputItem& in) const;
  FlowItem MakeFlow() const;

  std::shared_ptr<const Model> model_;
  FrameSource* source_;
  PipelineOptions options_;
  LogSink& log_;

  cv::Size source_size_;
  int height_ = 0;
  int width_ = 0;
  std::string size_reason_;   // why the input size is height_ x width_ (ChooseInputSize)
  std::string size_note_;     // the console's note when it is not the frames' size
  bool usage_error_ = false;  // setup refused an option against the source
  int out_channels_ = 0;
  std::unique_ptr<Session> session_;
  std::optional<camera::Preprocessor> preprocessor_;
  // The uint8 input path (PipelineOptions::quantized_input, where the session takes it): the
  // quantised value of each value preprocessing feeds (the fallback size's preprocessor has the
  // same parameters, so the same table).
  bool quantized_input_ = false;
  camera::Preprocessor::QuantizedTable input_table_{};
  std::optional<camera::StereoRectifier> rectifier_;
  // latency.on_miss: smaller-input (fallback_ = on): the fallback size's rectifier and
  // preprocessor, made at setup; use_fallback_ is set and cleared by the output stage and read
  // by the preprocess stage at the start of each window.
  bool fallback_ = false;
  int fb_height_ = 0;
  int fb_width_ = 0;
  std::optional<camera::Preprocessor> fb_preprocessor_;
  std::optional<camera::StereoRectifier> fb_rectifier_;
  std::atomic<bool> use_fallback_{false};
  QueuePolicy policy_ = QueuePolicy::kBlock;
  std::unique_ptr<LatestQueue<WindowItem>> q1_;
  std::unique_ptr<LatestQueue<InputItem>> q2_;
  std::unique_ptr<LatestQueue<FlowItem>> q3_;

  // The pipeline's own outputs (output_sinks.h) made from the options, then the profiler's and
  // options_.sinks: sinks_ in the order they are called; the first own_sinks_.size() are ours.
  std::optional<FlowRenderer> renderer_;
  std::vector<std::unique_ptr<FlowSink>> own_sinks_;
  std::unique_ptr<SummaryFileSink> summary_sink_;  // PipelineOptions::write_summary
  VideoSink* video_sink_ = nullptr;
  std::vector<std::unique_ptr<FlowSink>> picture_sinks_;  // PNG, video behind queued_pictures_
  QueuedSink* queued_pictures_ = nullptr;
  std::vector<FlowSink*> sinks_;
  std::vector<bool> completed_off_;  // kSkip: a sink whose Completed() failed gets no more calls
  size_t sinks_started_ = 0;         // sinks_ whose Start() succeeded
  std::atomic<bool> halt_{false};    // the source stops reading
  std::atomic<bool> max_reached_{false};
  std::mutex mu_;  // guards error_ and the counters the main thread reads while running
  Status error_ = Status::Ok();
  std::vector<std::string> warnings_;

  // Written by one stage each; read after the threads are joined.
  int64_t windows_read_ = 0;
  int64_t frames_ = 0;
  int64_t misses_ = 0;
  int64_t discarded_after_max_ = 0;
  std::atomic<bool> skip_next_{false};  // on_miss kDropNext: set by output, taken by source
  int64_t skipped_after_miss_ = 0;      // written by the source stage
  int64_t pairs_rectified_ = 0;         // written by the preprocess stage (at the model size)
  int64_t pairs_reused_ = 0;            // pairs t taken from the window before
  // smaller-input, written by the output stage:
  int64_t fallback_streak_ = 0;     // consecutive in-budget windows at the fallback size
  int64_t frames_at_fallback_ = 0;  // written windows that ran at the fallback size
  int64_t fallback_entries_ = 0;    // switches to the fallback size
  int64_t recoveries_ = 0;          // switches back to the model input size
  int64_t output_errors_ = 0;
  static constexpr size_t kMaxListedSkips = 100;        // summary.json lists at most this many
  std::vector<FrameSource::BadFrame> skipped_outputs_;  // {stem, error} under kSkip
  LatencyWindow stage_ms_[config::kStageCount];
  LatencyWindow e2e_ms_;
  LatencyWindow part_ms_[kLatencyParts];
  std::string last_stem_;
  std::string last_sequence_;
  int64_t start_ns_ = 0;
  int64_t end_ns_ = 0;
  int64_t last_progress_ns_ = 0;
  bool tty_progress_ = false;
  bool line_progress_ = false;
};

WindowItem Runner::MakeWindow() const {
  WindowItem w;
  for (cv::Mat* m : {&w.left0, &w.right0, &w.left1, &w.right1}) {
    m->create(source_size_, CV_8UC3);
  }
  return w;
}

InputItem Runner::MakeInput() const {
  InputItem in;
  in.left_vis.create(height_, width_, CV_8UC3);
  if (quantized_input_) {
    in.input_u8.resize(session_->QuantizedInputBytes(height_, width_));
  } else {
    in.input.resize(preprocessor_->output_floats());
  }
  return in;
}

camera::Status Runner::Preprocess(const camera::Preprocessor& pre, const cv::Mat& l0,
                                  const cv::Mat& r0, const cv::Mat& l1, const cv::Mat& r1,
                                  InputItem& in) const {
  if (quantized_input_) {
    return pre.RunQuantized(l0, r0, l1, r1, input_table_, in.input_u8.data(), pre.output_floats());
  }
  return pre.Run(l0, r0, l1, r1, in.input.data(), pre.output_floats());
}

FlowItem Runner::MakeFlow() const {
  FlowItem f;
  f.left_vis.create(height_, width_, CV_8UC3);
  f.flow.resize(static_cast<size_t>(height_) * width_ * out_channels_);
  if (options_.profiler) f.step_ns.resize(session_->steps().size() + 1);
  return f;
}

void Runner::Fail(const Status& status, bool discard) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (error_.ok()) error_ = status;
  }
  halt_ = true;
  if (discard) {
    q1_->Discard();
    q2_->Discard();
    q3_->Discard();
  }
}

Status Runner::Setup() {
  if (Status s = SetupInputSize(); !s.ok()) return s;
  if (Status s = SetupRectifier(); !s.ok()) return s;
  if (Status s = SetupFallback(); !s.ok()) return s;
  if (Status s = SetupSession(); !s.ok()) return s;
  if (Status s = CheckOutputShapes(); !s.ok()) return s;
  return SetupRun();
}

// Opens the source and chooses the network's input size (ChooseInputSize).
Status Runner::SetupInputSize() {
  source_->set_log(&log_);
  Result<cv::Size> size = source_->Open();
  if (!size.ok()) return size.status();
  source_size_ = *size;
  Result<InputSizeChoice> chosen =
      ChooseInputSize(options_, model_->metadata(), source_size_.height, source_size_.width);
  if (!chosen.ok()) {
    usage_error_ = true;
    return chosen.status();
  }
  height_ = chosen->height;
  width_ = chosen->width;
  size_reason_ = chosen->reason;
  if (height_ != source_size_.height || width_ != source_size_.width) {  // said once set up
    size_note_ = "input size " + std::to_string(height_) + "x" + std::to_string(width_) +
                 " (HxW): " + chosen->reason;
  }
  if (!chosen->aspect_note.empty()) warnings_.push_back(chosen->aspect_note);
  return Status::Ok();
}

// The preprocessor and the rectifier at the input size: the calibration's, warning where its
// rectified camera differs from the one the model was trained on, or a plain resize.
Status Runner::SetupRectifier() {
  Result<camera::PreprocessParams> params = PreprocessFromMetadata(model_->metadata().input);
  if (!params.ok()) return params.status();
  auto pre = camera::Preprocessor::Create(*params, height_, width_);
  if (!pre.ok()) return pre.status();
  preprocessor_.emplace(std::move(pre).value());

  const cv::Size model_size(width_, height_);
  if (options_.calibration) {
    auto rect = camera::StereoRectifier::Create(*options_.calibration, source_size_,
                                                camera::RectifyOptions{model_size});
    if (!rect.ok()) return rect.status();
    rectifier_.emplace(std::move(rect).value());
    WarnOfCameraChange();
  } else {
    auto rect = camera::StereoRectifier::CreateResizeOnly(source_size_, model_size);
    if (!rect.ok()) return rect.status();
    rectifier_.emplace(std::move(rect).value());
  }
  return Status::Ok();
}

// The network was trained on one camera; a different rectified camera scales its output.
void Runner::WarnOfCameraChange() {
  const CameraDesc& trained = model_->metadata().camera;
  const camera::RectifiedCamera& cam = rectifier_->camera();
  auto differs = [](double a, double b, double rel) {
    return std::fabs(a - b) > rel * std::max(std::fabs(a), std::fabs(b));
  };
  auto warn = [&](const std::string& what, double got, double want) {
    warnings_.push_back("rectified camera " + what + " " + FormatFixed(got, 4) +
                        " differs from the model's training camera (" + FormatFixed(want, 4) +
                        "); the flow's scale may be off");
  };
  if (trained.focal_px > 0 && differs(cam.fx, trained.focal_px, 0.01)) {
    warn("focal length (px)", cam.fx, trained.focal_px);
  }
  if (trained.baseline > 0 && differs(cam.baseline, trained.baseline, 0.01)) {
    warn("baseline", cam.baseline, trained.baseline);
  }
  if (trained.focal_px > 0 &&
      (std::fabs(cam.cx - trained.cx) > 2.0 || std::fabs(cam.cy - trained.cy) > 2.0)) {
    warnings_.push_back("rectified principal point (" + FormatFixed(cam.cx, 1) + ", " +
                        FormatFixed(cam.cy, 1) + ") differs from the training camera's (" +
                        FormatFixed(trained.cx, 1) + ", " + FormatFixed(trained.cy, 1) + ")");
  }
}

// The session at the input size, and the uint8 input path where the model and options take it.
Status Runner::SetupSession() {
  SessionOptions so;
  so.max_height = height_;
  so.max_width = width_;
  so.isa = options_.isa;
  so.threads = options_.threads;
  so.tuning = options_.tuning;
  Result<std::unique_ptr<Session>> session = Session::Create(model_, so);
  if (!session.ok()) {
    return Status::Error("cannot create a session for " + std::to_string(height_) + "x" +
                         std::to_string(width_) + ": " + session.message());
  }
  session_ = std::move(session).value();
  if (const std::optional<QuantParams> q = session_->InputQuantization();
      q && options_.quantized_input) {
    quantized_input_ = true;
    input_table_ = preprocessor_->Tabulate([q](float v) { return QuantizeInput(v, *q); });
  }
  return Status::Ok();
}

// The pipeline needs flow at the input size (the fallback's too), in channels the flow files
// hold.
Status Runner::CheckOutputShapes() {
  Result<TensorShape> shape = session_->OutputShape(height_, width_);
  if (!shape.ok()) return shape.status();
  out_channels_ = shape->channels;
  if (shape->height != height_ || shape->width != width_) {
    return Status::Error("the model's output is " + std::to_string(shape->height) + "x" +
                         std::to_string(shape->width) + " for an input of " +
                         std::to_string(height_) + "x" + std::to_string(width_) +
                         "; the pipeline needs flow at the input size");
  }
  if (fallback_) {
    Result<TensorShape> fb = session_->OutputShape(fb_height_, fb_width_);
    if (!fb.ok()) {
      return Status::Error("latency.on_miss smaller-input: the fallback size " +
                           std::to_string(fb_height_) + "x" + std::to_string(fb_width_) + ": " +
                           fb.message());
    }
    if (fb->height != fb_height_ || fb->width != fb_width_) {
      return Status::Error(
          "latency.on_miss smaller-input: the model's output is " + std::to_string(fb->height) +
          "x" + std::to_string(fb->width) + " for the fallback size " + std::to_string(fb_height_) +
          "x" + std::to_string(fb_width_) + "; the pipeline needs flow at the input size");
    }
  }
  if (options_.write_flow && options_.flow_format == FlowFormat::kPfm && out_channels_ != 1 &&
      out_channels_ != 3) {
    return Status::Error("the model outputs " + std::to_string(out_channels_) +
                         " channels; PFM holds 1 or 3 (use --flow-format npy)");
  }
  return Status::Ok();
}

// What runs the windows: the paged-in session, the profiler, the sinks, the queues and the
// progress display.
Status Runner::SetupRun() {
  if (options_.prefault) {  // page in the arena and packed weights before the first frame
    std::vector<float> zeros(preprocessor_->output_floats(), 0.0f);
    std::vector<float> flow(static_cast<size_t>(height_) * width_ * out_channels_);
    if (Status s = session_->Run(zeros, height_, width_, flow); !s.ok()) return s;
  }
  if (options_.profiler) options_.profiler->Prepare(*session_, height_, width_);
  policy_ =
      options_.policy.value_or(source_->live() ? QueuePolicy::kNewestWins : QueuePolicy::kBlock);
  if (Status s = StartSinks(); !s.ok()) return s;

  const size_t cap = std::max<size_t>(1, options_.queue_capacity);
  q1_ = std::make_unique<LatestQueue<WindowItem>>(cap, policy_, [this] { return MakeWindow(); });
  q2_ = std::make_unique<LatestQueue<InputItem>>(cap, policy_, [this] { return MakeInput(); });
  q3_ = std::make_unique<LatestQueue<FlowItem>>(cap, policy_, [this] { return MakeFlow(); });

  switch (options_.progress) {
    case ProgressMode::kAuto:
      tty_progress_ = log_.interactive();
      line_progress_ = !tty_progress_;
      break;
    case ProgressMode::kTty:  // at most 4 lines a second; the log decides how it shows them
      tty_progress_ = true;
      break;
    case ProgressMode::kLines:
      line_progress_ = true;
      break;
    case ProgressMode::kOff:
      break;
  }
  return Status::Ok();
}

Status Runner::SetupFallback() {
  if (options_.on_miss != config::MissAction::kSmallerInput) return Status::Ok();
  const PipelineOptions::Size2& fb = options_.smaller_input_on_miss;
  const std::string fb_text = std::to_string(fb.height) + "x" + std::to_string(fb.width);
  const std::string size_text = std::to_string(height_) + "x" + std::to_string(width_);
  if (fb.height <= 0 || fb.width <= 0 || fb.height > height_ || fb.width > width_ ||
      (fb.height == height_ && fb.width == width_)) {
    return Status::Error("latency.on_miss smaller-input: the fallback size " + fb_text +
                         " must be positive, at most the model input size " + size_text +
                         " and smaller in at least one dimension");
  }
  if (options_.recover_after < 1) {
    return Status::Error("latency.on_miss smaller-input: recover_after is " +
                         std::to_string(options_.recover_after) + "; it must be >= 1");
  }
  fallback_ = true;
  fb_height_ = fb.height;
  fb_width_ = fb.width;
  Result<camera::PreprocessParams> params = PreprocessFromMetadata(model_->metadata().input);
  if (!params.ok()) return params.status();
  auto pre = camera::Preprocessor::Create(*params, fb_height_, fb_width_);
  if (!pre.ok()) return pre.status();
  fb_preprocessor_.emplace(std::move(pre).value());
  const cv::Size fb_size(fb_width_, fb_height_);
  auto rect = options_.calibration
                  ? camera::StereoRectifier::Create(*options_.calibration, source_size_,
                                                    camera::RectifyOptions{fb_size})
                  : camera::StereoRectifier::CreateResizeOnly(source_size_, fb_size);
  if (!rect.ok()) return rect.status();
  fb_rectifier_.emplace(std::move(rect).value());
  if (options_.budget_ms <= 0 && !options_.miss_verdict) {
    warnings_.push_back("latency.on_miss smaller-input " + fb_text +
                        " without a budget (--budget-ms): no window misses, the size never "
                        "changes");
  }
  return Status::Ok();
}

// The smaller-input state machine, on the output stage's thread: a miss switches to the fallback
// size (a miss at the fallback size restarts the count); recover_after consecutive in-budget
// windows that ran at the fallback size switch back. Windows already in flight at the old size
// when the size changes neither count towards recovery nor switch again.
void Runner::UpdateFallback(const FrameMeta& m, bool miss) {
  const bool at_fallback = m.input_height != height_ || m.input_width != width_;
  if (at_fallback) ++frames_at_fallback_;
  if (miss) {
    fallback_streak_ = 0;
    if (!use_fallback_.load()) {
      use_fallback_ = true;
      ++fallback_entries_;
    }
  } else if (at_fallback && use_fallback_.load()) {
    if (++fallback_streak_ >= options_.recover_after) {
      use_fallback_ = false;
      fallback_streak_ = 0;
      ++recoveries_;
    }
  }
}

void Runner::SourceStage() {
  if (options_.on_stage_start) options_.on_stage_start(config::StageIndex(config::Stage::kSource));
  WindowItem item = MakeWindow();
  const auto period =
      options_.source_fps > 0
          ? std::chrono::nanoseconds(static_cast<int64_t>(1e9 / options_.source_fps))
          : std::chrono::nanoseconds(0);
  auto due = std::chrono::steady_clock::now();
  while (!halt_.load()) {
    if (period.count() > 0) {
      // Paced like a camera: wait for this window's slot; a late window moves the schedule on
      // instead of letting the next ones arrive in a burst.
      std::this_thread::sleep_until(due);
      due = std::max(due, std::chrono::steady_clock::now()) + period;
    }
    Result<Fetch> next = source_->Next(&item, halt_);
    if (!next.ok()) {
      Fail(next.status(), /*discard=*/false);  // windows already read are still written
      break;
    }
    if (*next == Fetch::kEnd) break;
    if (skip_next_.exchange(false)) {  // latency.on_miss: drop-next
      ++skipped_after_miss_;
      ++windows_read_;
      continue;
    }
    item.meta.window = windows_read_++;
    item.meta.end_ns(config::Stage::kSource) = NowNs();
    if (!q1_->Push(&item)) break;
  }
  q1_->Close();
}

void Runner::PreprocessStage() {
  if (options_.on_stage_start)
    options_.on_stage_start(config::StageIndex(config::Stage::kPreprocess));
  WindowItem w = MakeWindow();
  InputItem in = MakeInput();
  cv::Mat l0, r0, l1, r1;  // rectified, model size
  for (cv::Mat* m : {&l0, &r0, &l1, &r1}) m->create(height_, width_, CV_8UC3);
  // The window whose pair t+1 is in l1/r1 (-1: none): a window that continues it (FrameMeta::
  // continues) takes that pair as its pair t and rectifies only its own pair t+1.
  int64_t rectified_window = -1;
  cv::Mat fl0, fr0, fl1, fr1;  // rectified, fallback size (smaller-input)
  if (fallback_) {
    for (cv::Mat* m : {&fl0, &fr0, &fl1, &fr1}) m->create(fb_height_, fb_width_, CV_8UC3);
  }
  while (q1_->Pop(&w)) {
    w.meta.start_ns(config::Stage::kPreprocess) = NowNs();
    const bool small = fallback_ && use_fallback_.load();
    const cv::Size size = w.left0.size();
    if (w.left1.size() != size) {
      Fail(Status::Error("window at '" + w.meta.left0_path +
                         "': the images at t and t+1 differ in size"),
           true);
      break;
    }
    if (size != rectifier_->input_size()) {
      if (options_.calibration) {
        Fail(Status::Error("frame size changed to " + std::to_string(size.height) + "x" +
                           std::to_string(size.width) + " (HxW) but the calibration is for " +
                           std::to_string(rectifier_->input_size().height) + "x" +
                           std::to_string(rectifier_->input_size().width)),
             true);
        break;
      }
      auto rect = camera::StereoRectifier::CreateResizeOnly(size, cv::Size(width_, height_));
      if (!rect.ok()) {
        Fail(Status::Error(rect.message()), true);
        break;
      }
      rectifier_.emplace(std::move(rect).value());
      rectified_window = -1;
      if (fallback_) {
        auto fb = camera::StereoRectifier::CreateResizeOnly(size, cv::Size(fb_width_, fb_height_));
        if (!fb.ok()) {
          Fail(Status::Error(fb.message()), true);
          break;
        }
        fb_rectifier_.emplace(std::move(fb).value());
      }
    }
    camera::Status s = camera::Status::Ok();
    if (small) {
      // The input buffer is sized for the model input size; the fallback input fills its start.
      s = fb_rectifier_->Apply(w.left0, w.right0, &fl0, &fr0);
      if (s.ok()) s = fb_rectifier_->Apply(w.left1, w.right1, &fl1, &fr1);
      if (s.ok()) s = Preprocess(*fb_preprocessor_, fl0, fr0, fl1, fr1, in);
    } else {
      const bool reuse =
          w.meta.continues && rectified_window >= 0 && w.meta.window == rectified_window + 1;
      if (reuse) {  // the last window's pair t+1 is this one's pair t
        std::swap(l0, l1);
        std::swap(r0, r1);
        ++pairs_reused_;
      } else {
        s = rectifier_->Apply(w.left0, w.right0, &l0, &r0);
        ++pairs_rectified_;
      }
      if (s.ok()) s = rectifier_->Apply(w.left1, w.right1, &l1, &r1);
      ++pairs_rectified_;
      if (s.ok()) s = Preprocess(*preprocessor_, l0, r0, l1, r1, in);
    }
    rectified_window = s.ok() && !small ? w.meta.window : -1;
    if (!s.ok()) {
      Fail(Status::Error(s.message()), true);
      break;
    }
    if (small) {  // the visualisation keeps the model input size (into the existing buffer)
      cv::resize(fl0, in.left_vis, in.left_vis.size(), 0, 0, cv::INTER_LINEAR);
    } else {
      l0.copyTo(in.left_vis);
    }
    w.meta.input_height = small ? fb_height_ : height_;
    w.meta.input_width = small ? fb_width_ : width_;
    std::swap(in.meta, w.meta);
    in.meta.end_ns(config::Stage::kPreprocess) = NowNs();
    if (!q2_->Push(&in)) break;
  }
  q2_->Close();
}

void Runner::InferStage() {
  if (options_.on_stage_start) options_.on_stage_start(config::StageIndex(config::Stage::kInfer));
  // Both items are allocated here, before the first frame; the loop only swaps and runs.
  InputItem in = MakeInput();
  FlowItem out = MakeFlow();
  while (q2_->Pop(&in)) {
    in.meta.start_ns(config::Stage::kInfer) = NowNs();
    const int h = in.meta.input_height, w = in.meta.input_width;  // the size it was prepared at
    Status s = quantized_input_ ? session_->RunQuantized(in.input_u8, h, w, out.flow, out.step_ns)
               : out.step_ns.empty() ? session_->Run(in.input, h, w, out.flow)
                                     : session_->Run(in.input, h, w, out.flow, out.step_ns);
    if (!s.ok()) {
      Fail(s, true);
      break;
    }
    std::swap(out.meta, in.meta);
    std::swap(out.left_vis, in.left_vis);
    out.meta.end_ns(config::Stage::kInfer) = NowNs();
    if (!q3_->Push(&out)) break;
  }
  q3_->Close();
}

// The pipeline's own outputs from the options, in the order they are written, then the
// profiler's sink and the caller's; each started in turn. An error names the caller's sink (ours
// name their file).
Status Runner::StartSinks() {
  const std::string& dir = options_.out_dir;
  if (options_.write_flow) {
    own_sinks_.push_back(std::make_unique<FlowFileSink>(dir, options_.flow_format));
  }
  if (options_.write_png || !options_.video_path.empty()) {
    renderer_.emplace(VisualizerOptions{options_.vis_scale, model_->metadata().output.units});
  }
  // The pictures: on the output stage, or behind a queue on a thread of their own.
  std::vector<std::unique_ptr<FlowSink>> pictures;
  if (options_.write_png) pictures.push_back(std::make_unique<PngSink>(dir, &*renderer_));
  if (!options_.video_path.empty()) {
    auto video = std::make_unique<VideoSink>(options_.video_path, options_.video_fps, &*renderer_);
    video_sink_ = video.get();
    pictures.push_back(std::move(video));
  }
  // Where time matters (a camera, a paced replay) pictures never hold back the flow: they go
  // behind a queue that drops (and counts) the ones the encoder cannot keep up with. An unpaced
  // replay is a throughput job: every picture is written, with its window's flow by default.
  const bool timed = Paced();
  const size_t depth = options_.picture_queue.value_or(timed ? 2 : 0);
  if (depth > 0 && !pictures.empty()) {
    std::vector<FlowSink*> inner;
    for (std::unique_ptr<FlowSink>& p : pictures) {
      inner.push_back(p.get());
      picture_sinks_.push_back(std::move(p));
    }
    const QueuePolicy picture_policy = timed ? QueuePolicy::kNewestWins : policy_;
    auto queued = std::make_unique<QueuedSink>("pictures", std::move(inner), depth, picture_policy);
    queued_pictures_ = queued.get();
    own_sinks_.push_back(std::move(queued));
  } else {
    for (std::unique_ptr<FlowSink>& p : pictures) own_sinks_.push_back(std::move(p));
  }
  if (!options_.latency_log.empty()) {
    own_sinks_.push_back(std::make_unique<LatencyLogSink>(options_.latency_log));
  }
  // Beside per-window files, which source frames each came from (their names are the source's).
  if (options_.write_flow || options_.write_png) {
    own_sinks_.push_back(std::make_unique<WindowIndexSink>(dir));
  }
  if (options_.profiler) own_sinks_.push_back(std::make_unique<ProfilerSink>(options_.profiler));
  for (const std::unique_ptr<FlowSink>& sink : own_sinks_) sinks_.push_back(sink.get());
  for (FlowSink* sink : options_.sinks) {
    if (sink == nullptr) return Status::Error("PipelineOptions::sinks holds a null sink");
    sinks_.push_back(sink);
  }
  completed_off_.assign(sinks_.size(), false);
  for (FlowSink* sink : sinks_) {
    Status started = sink->Start();
    if (!started.ok()) {
      if (sinks_started_ < own_sinks_.size()) return started;
      return Status::Error("sink '" + sink->name() + "': " + started.message());
    }
    ++sinks_started_;
  }
  return Status::Ok();
}

// Hands the window to each sink in order (sink.h); when one fails, the ones before it retract
// it, and the error names the caller's sink (ours name their file).
Status Runner::DeliverToSinks(const FlowItem& f, std::span<const float> flow) {
  FlowFrame frame;
  frame.meta = &f.meta;
  frame.flow = flow;
  frame.height = f.meta.input_height;
  frame.width = f.meta.input_width;
  frame.channels = out_channels_;
  frame.left_image = &f.left_vis;
  for (size_t i = 0; i < sinks_.size(); ++i) {
    frame.latency_ms = Ms(NowNs() - f.meta.capture_ns[1]);
    frame.over_budget = options_.budget_ms > 0 && frame.latency_ms > options_.budget_ms;
    Status s = sinks_[i]->Write(frame);
    if (!s.ok()) {
      for (size_t j = 0; j < i; ++j) sinks_[j]->Retract();
      if (i < own_sinks_.size()) return s;
      return Status::Error("sink '" + sinks_[i]->name() + "': " + s.message());
    }
  }
  return Status::Ok();
}

// Every sink's Completed() for a written window. False: a failure under kStop ended the run.
bool Runner::CompleteSinks(const WindowRecord& record, const std::string& stem) {
  for (size_t i = 0; i < sinks_.size(); ++i) {
    if (completed_off_[i]) continue;
    Status s = sinks_[i]->Completed(record);
    if (s.ok()) continue;
    if (i >= own_sinks_.size())
      s = Status::Error("sink '" + sinks_[i]->name() + "': " + s.message());
    if (options_.on_output_error == OutputErrorPolicy::kStop) {
      Fail(s, true);
      return false;
    }
    // kSkip: the window's outputs are written; this sink stops here (a CSV log would be
    // unreadable with a line missing), and the run says so now and in the summary.
    completed_off_[i] = true;
    log_.Write(LogLevel::kWarn, "warning", s.message() + "; it gets no more windows");
    std::lock_guard<std::mutex> lock(mu_);
    warnings_.push_back(s.message() + " (from window " + stem + " on)");
  }
  return true;
}

// Stops the sinks that started, in order; the first error is returned (each is stopped anyway).
Status Runner::StopSinks() {
  Status first = Status::Ok();
  for (size_t i = 0; i < sinks_started_; ++i) {
    Status s = sinks_[i]->Stop();
    if (!s.ok() && i >= own_sinks_.size()) {
      s = Status::Error("sink '" + sinks_[i]->name() + "': " + s.message());
    }
    if (!s.ok() && first.ok()) first = s;
  }
  sinks_started_ = 0;
  return first;
}

void Runner::OutputStage() {
  if (options_.on_stage_start) options_.on_stage_start(config::StageIndex(config::Stage::kOutput));
  FlowItem f = MakeFlow();
  while (q3_->Pop(&f)) {
    if (max_reached_.load()) {
      ++discarded_after_max_;
      continue;
    }
    FrameMeta& m = f.meta;
    m.start_ns(config::Stage::kOutput) = NowNs();
    const std::string stem = OutputStem(m);
    const int h = m.input_height, w = m.input_width;  // the size the window ran at
    const std::span<const float> flow(f.flow.data(), static_cast<size_t>(h) * w * out_channels_);
    if (Status s = DeliverToSinks(f, flow); !s.ok()) {
      ++output_errors_;
      if (options_.on_output_error == OutputErrorPolicy::kStop) {
        Fail(s, true);
        break;
      }
      log_.Write(LogLevel::kWarn, "warning", "window " + stem + " skipped: " + s.message());
      if (skipped_outputs_.size() < kMaxListedSkips) {
        skipped_outputs_.push_back({stem, s.message(), m.window, m.sequence});
      }
      continue;
    }
    m.end_ns(config::Stage::kOutput) = NowNs();
    for (int st = 0; st < config::kStageCount; ++st)
      stage_ms_[st].Add(Ms(m.stage_ns[st][1] - m.stage_ns[st][0]));
    const double e2e = Ms(m.end_ns(config::Stage::kOutput) - m.capture_ns[1]);
    e2e_ms_.Add(e2e);
    double parts[kLatencyParts];
    SplitLatency(m, parts);
    for (int p = 0; p < kLatencyParts; ++p) part_ms_[p].Add(parts[p]);
    const bool over_budget = options_.budget_ms > 0 && e2e > options_.budget_ms;
    const bool miss = options_.miss_verdict ? options_.miss_verdict(m, over_budget) : over_budget;
    if (!CompleteSinks(WindowRecord{&m, e2e, miss, f.step_ns}, stem)) break;
    if (miss) {
      ++misses_;
      if (options_.on_miss == config::MissAction::kDropNext) skip_next_ = true;
    }
    if (fallback_) UpdateFallback(m, miss);
    last_stem_ = stem;
    last_sequence_ = m.sequence;
    {
      std::lock_guard<std::mutex> lock(mu_);
      ++frames_;
    }
    Progress(false);
    if (options_.max_frames > 0 && frames_ >= options_.max_frames) {
      max_reached_ = true;
      halt_ = true;
    }
    if (options_.after_window) options_.after_window(m);
  }
}

void Runner::Progress(bool final) {
  if (!tty_progress_ && !line_progress_) return;
  const int64_t now = NowNs();
  if (tty_progress_ && !final && now - last_progress_ns_ < 250'000'000) return;
  if (line_progress_ && !final &&
      (options_.progress_every <= 0 || frames_ % options_.progress_every != 0)) {
    return;
  }
  if (line_progress_ && final && options_.progress_every > 0 &&
      frames_ % options_.progress_every == 0 && frames_ > 0) {
    return;  // already printed
  }
  last_progress_ns_ = now;
  const double wall = static_cast<double>(now - start_ns_) / 1e9;
  const std::optional<int64_t> total = source_->total_windows();
  std::string line = std::to_string(frames_);
  if (total)
    line += "/" + std::to_string(options_.max_frames > 0 ? std::min(*total, options_.max_frames)
                                                         : *total);
  const double fps = wall > 0 ? static_cast<double>(frames_) / wall : 0.0;
  line += " frames, " + FormatFixed(fps, 1) + " fps, p50 " +
          FormatFixed(profiling::Summarize(e2e_ms_.Values()).p50, 1) + " ms end to end";
  if (total && !final && fps > 0) {  // replays: how long the rest takes at this rate
    const int64_t limit = options_.max_frames > 0 ? std::min(*total, options_.max_frames) : *total;
    line += ", ETA " +
            FormatFixed(static_cast<double>(std::max<int64_t>(0, limit - frames_)) / fps, 0) + " s";
  }
  log_.Progress(line, final);
}

json Runner::SamplesJson() const {
  json stages = json::object();
  for (int st = 0; st < config::kStageCount; ++st) stages[kStageNames[st]] = stage_ms_[st].Values();
  json parts = json::object();
  for (int p = 0; p < kLatencyParts; ++p) {
    parts[LatencyPartName(static_cast<LatencyPart>(p))] = part_ms_[p].Values();
  }
  return {{"stages", stages},
          {"end_to_end", e2e_ms_.Values()},
          {"parts", parts},
          {"pictures", queued_pictures_ != nullptr ? json(queued_pictures_->write_ms_values())
                                                   : json(nullptr)}};
}

// summary.json's bad frames, window breaks, output errors and deadline events.
void Runner::AddEventsJson(json* out) const {
  json& j = *out;
  json bad = json::array();
  for (const FrameSource::BadFrame& b : source_->bad_frames()) {
    bad.push_back({{"path", b.path}, {"reason", b.reason}});
    if (!b.sequence.empty()) bad.back()["sequence"] = b.sequence;
  }
  j["bad_frames"] = bad;
  // The window rule (sfrt/camera/window_chain.h): pairs that opened no window, and why.
  const camera::ChainCounts chain = source_->chain_counts();
  j["windows"] = {{"formed", chain.windows},
                  {"broken_by_lost_frame", chain.broken_by_loss},
                  {"skipped_for_gap", chain.skipped_for_gap},
                  {"stream_restarts", chain.stream_restarts}};
  json skipped = json::array();
  for (const FrameSource::BadFrame& b : skipped_outputs_) {
    skipped.push_back({{"window", b.path}, {"error", b.reason}});
    if (!b.sequence.empty()) skipped.back()["sequence"] = b.sequence;
  }
  j["output_errors"] = {{"policy", vocabulary::FailurePolicyName(options_.on_output_error)},
                        {"count", output_errors_},
                        {"skipped", skipped}};
  j["deadline"] = {
      {"budget_ms", options_.budget_ms > 0 ? json(options_.budget_ms) : json(nullptr)},
      {"misses", misses_},
      {"on_miss", config::MissActionName(options_.on_miss)},
      {"skipped_after_miss", skipped_after_miss_},
      {"fallback_size", fallback_ ? json::array({fb_height_, fb_width_}) : json(nullptr)},
      {"recover_after_frames", fallback_ ? json(options_.recover_after) : json(nullptr)},
      {"fallback_entries", fallback_entries_},
      {"recoveries", recoveries_},
      {"frames_at_fallback_size", frames_at_fallback_}};
}

// summary.json's latencies: per stage, end to end, its parts, and whether it is a latency.
void Runner::AddLatencyJson(const PipelineResult& result, json* out) const {
  json& j = *out;
  json lat;
  for (int st = 0; st < config::kStageCount; ++st)
    lat[kStageNames[st]] = PercentilesJson(result.stage[st]);
  lat["end_to_end"] = PercentilesJson(result.end_to_end);
  j["latency_ms"] = lat;
  // Each pair is rectified once: pair t of a window that continues the one before is its pair
  // t+1, already rectified (fallback-size windows are not counted).
  j["preprocess"] = {{"pairs_rectified", pairs_rectified_}, {"pairs_reused", pairs_reused_}};
  // The end to end split into consecutive parts (LatencyPart); the per-window parts add up to
  // the window's end to end, their p50s need not add up to its p50.
  json parts = json::object();
  double p50_sum = 0;
  for (int p = 0; p < kLatencyParts; ++p) {
    parts[LatencyPartName(static_cast<LatencyPart>(p))] = PercentilesJson(result.parts[p]);
    p50_sum += result.parts[p].p50;
  }
  j["latency_attribution_ms"] = {
      {"parts", parts}, {"sum_of_p50", p50_sum}, {"end_to_end_p50", result.end_to_end.p50}};
  // An unpaced replay reads windows as fast as the pipeline takes them, so they wait in the
  // queues: its end to end includes that wait and measures throughput, not latency.
  const bool paced = Paced();
  j["timing"] = {
      {"paced", paced},
      {"end_to_end_is_latency", paced},
      {"note", paced
                   ? "windows arrive at the source's rate: end to end is capture-to-output latency"
                   : "unpaced replay: windows queue for the pipeline, so end to end includes "
                     "that wait and measures throughput (fps); pace it (--replay-fps) to "
                     "measure latency"}};
}

Status Runner::FinishSinks(PipelineResult* result) {
  json j;
  const ModelMetadata& meta = model_->metadata();
  j["model"] = {{"path", options_.model_path},
                {"name", meta.name},
                {"input_size", {height_, width_}},
                {"input_size_from", size_reason_},
                {"output_channels", out_channels_}};
  j["isa"] = session_ ? IsaName(session_->isa()) : "";
  // The network input's type: uint8 on the uint8 input path, preprocessed straight from pixels.
  j["input_type"] = quantized_input_ ? "uint8" : "float32";
  j["threads"] = session_ ? session_->threads() : options_.threads;
  json src;
  src["kind"] = source_->kind();
  src["description"] = source_->Describe();
  src["frame_size"] = {source_size_.height, source_size_.width};
  source_->ToJson(&src);
  j["source"] = src;
  const std::optional<int64_t> total = source_->total_windows();
  j["frames"] = {{"written", frames_},
                 {"read", windows_read_},
                 {"total", total ? json(*total) : json(nullptr)}};
  j["completed"] = result->stopped_by == "end of source" || result->stopped_by == "max-frames";
  j["stopped_by"] = result->stopped_by;
  j["error"] = error_.ok() ? json(nullptr) : json(error_.message());
  const uint64_t discarded = (q1_ ? q1_->discarded() : 0) + (q2_ ? q2_->discarded() : 0) +
                             (q3_ ? q3_->discarded() : 0) +
                             static_cast<uint64_t>(discarded_after_max_);
  j["queue_policy"] = policy_ == QueuePolicy::kNewestWins ? "newest-wins" : "block";
  j["drops"] = {{"source", source_->drops()},
                {"preprocess", q1_ ? q1_->drops() : 0},
                {"infer", q2_ ? q2_->drops() : 0},
                {"output", q3_ ? q3_->drops() : 0},
                {"discarded_at_stop", discarded}};
  AddEventsJson(&j);
  AddLatencyJson(*result, &j);
  j["wall_s"] = static_cast<double>(end_ns_ - start_ns_) / 1e9;
  j["fps"] = result->fps;
  j["clock"] = "CLOCK_MONOTONIC";
  j["outputs"] = {
      {"dir", options_.out_dir},
      {"flow_format", options_.write_flow ? config::FlowFormatName(options_.flow_format) : "none"},
      {"png", options_.write_png},
      {"video", video_sink_ != nullptr && video_sink_->written() ? json(options_.video_path)
                                                                 : json(nullptr)},
      {"last", last_stem_},
      {"last_sequence", last_sequence_}};
  json sinks = json::array();
  for (const FlowSink* sink : sinks_) {
    json entry = {{"name", sink->name()}};
    sink->ToJson(&entry);
    sinks.push_back(entry);
  }
  j["sinks"] = sinks;
  j["warnings"] = warnings_;
  if (options_.summary_samples) j["latency_samples_ms"] = SamplesJson();
  if (options_.annotate_summary) options_.annotate_summary(&j);
  Status first = Status::Ok();
  for (FlowSink* sink : options_.sinks) {
    if (Status s = sink->Finished(j); !s.ok() && first.ok()) {
      first = Status::Error("sink '" + sink->name() + "': " + s.message());
    }
  }
  if (summary_sink_) {
    Status s = summary_sink_->Finished(j);
    if (s.ok()) result->summary_path = summary_sink_->path();
    if (!s.ok() && first.ok()) first = s;
  }
  return first;
}

PipelineResult Runner::Run() {
  PipelineResult result;
  if (options_.write_summary) summary_sink_ = std::make_unique<SummaryFileSink>(options_.out_dir);
  start_ns_ = NowNs();
  Status setup = Setup();
  for (const std::string& w : warnings_) log_.Write(LogLevel::kWarn, "warning", w);
  if (!setup.ok()) {
    (void)StopSinks();  // the setup's error is the one to report
    result.status = setup;
    result.usage_error = usage_error_;
    result.stopped_by = "error";
    error_ = setup;
    end_ns_ = NowNs();
    std::error_code ec;
    if (!std::filesystem::is_directory(options_.out_dir, ec)) summary_sink_.reset();
    (void)FinishSinks(&result);
    return result;
  }
  result.started = true;
  if (!size_note_.empty()) log_.Write(LogLevel::kInfo, "note", size_note_);
  start_ns_ = NowNs();
  std::thread threads[config::kStageCount] = {
      std::thread([this] { SourceStage(); }), std::thread([this] { PreprocessStage(); }),
      std::thread([this] { InferStage(); }), std::thread([this] { OutputStage(); })};
  // Relay an asynchronous stop (signal) to the stages until the source has finished.
  std::atomic<bool> done{false};
  std::thread watcher([&] {
    while (!done.load()) {
      if (options_.stop && options_.stop->load()) halt_ = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  });
  for (std::thread& t : threads) t.join();
  done = true;
  watcher.join();
  if (Status stopped = StopSinks(); !stopped.ok()) {
    std::lock_guard<std::mutex> lock(mu_);
    if (error_.ok()) error_ = stopped;
  }
  end_ns_ = NowNs();
  Progress(true);

  result.frames = frames_;
  result.output_errors = output_errors_;
  result.status = error_;
  const int sig = options_.stop_signal ? options_.stop_signal->load() : 0;
  if (!error_.ok()) {
    result.stopped_by = "error";
  } else if (max_reached_) {
    result.stopped_by = "max-frames";
  } else if (options_.stop && options_.stop->load()) {
    result.stopped_by = sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "stop request";
  } else {
    result.stopped_by = "end of source";
  }
  const double wall = static_cast<double>(end_ns_ - start_ns_) / 1e9;
  result.fps = wall > 0 ? static_cast<double>(frames_) / wall : 0;
  for (int st = 0; st < config::kStageCount; ++st)
    result.stage[st] = profiling::Summarize(stage_ms_[st].Values());
  for (int p = 0; p < kLatencyParts; ++p) {
    result.parts[p] = profiling::Summarize(part_ms_[p].Values());
  }
  result.end_to_end = profiling::Summarize(e2e_ms_.Values());
  result.paced = Paced();
  result.misses = misses_;
  if (queued_pictures_ != nullptr) {
    result.pictures_queued = true;
    result.pictures_ms = queued_pictures_->write_ms();
    result.pictures_dropped = queued_pictures_->dropped();
  }
  result.chain = source_->chain_counts();
  result.frames_at_fallback_size = frames_at_fallback_;
  result.fallback_entries = fallback_entries_;
  result.warnings = warnings_;
  Status s = FinishSinks(&result);
  if (!s.ok()) {
    if (result.status.ok()) {
      result.status = s;
    } else {
      log_.Write(LogLevel::kWarn, "warning", "no summary: " + s.message());
    }
  }
  return result;
}

}  // namespace

json PercentilesJson(const profiling::Summary& p) {
  return json{{"p50", p.p50}, {"p90", p.p90}, {"p99", p.p99}, {"max", p.max}, {"count", p.count}};
}

LogSink& FrameSource::log() const { return log_ != nullptr ? *log_ : DefaultLog(); }

PipelineResult RunPipeline(std::shared_ptr<const Model> model, FrameSource* source,
                           const PipelineOptions& options) {
  Runner runner(std::move(model), source, options);
  return runner.Run();
}

}  // namespace sfrt::pipeline
