#include "sfrt/pipeline/node.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "clock.h"
#include "sfrt/config/capabilities.h"
#include "sfrt/config/limits.h"
#include "sfrt/config/process_settings.h"
#include "sfrt/config/profile.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/log.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/profile_options.h"
#include "sfrt/pipeline/queued_sink.h"
#include "sfrt/pipeline/topic_sink.h"
#include "sfrt/pipeline/topic_source.h"
#include "sfrt/vocabulary/names.h"

namespace sfrt::pipeline {
namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

// The pipeline's log through the middleware's (rosconsole, stderr).
class NodeLog final : public LogSink {
 public:
  explicit NodeLog(NodeIo* io) : io_(io) {}
  void Write(LogLevel level, std::string_view tag, std::string_view text) override {
    NodeLogLevel l = NodeLogLevel::kInfo;
    if (level == LogLevel::kError) l = NodeLogLevel::kError;
    if (level == LogLevel::kWarn) l = NodeLogLevel::kWarn;
    if (level == LogLevel::kDebug) l = NodeLogLevel::kDebug;
    io_->Log(l, std::string(tag) + ": " + std::string(text));
  }
  void Progress(std::string_view line, bool /*final*/) override {
    io_->Log(NodeLogLevel::kDebug, std::string(line));
  }

 private:
  NodeIo* io_;
};

struct NodeSettings {
  std::string model;
  std::string config;
  int threads = 1;
  std::string isa = "auto";
  double budget_ms = 0;
  config::MissAction on_miss = config::MissAction::kCountOnly;
  std::string fallback_size;
  int recover_after = 30;
  std::string size;
  bool allow_aspect_change = false;
  std::string transport = "raw";
  double slop_ms = 8;
  int queue_size = 5;
  double frame_interval_ms = 16;
  int input_queue = 1;
  std::string queue_policy = "newest-wins";
  bool publish_vis = false;
  std::string frame_id;
  bool camera_info = true;
  double diagnostics_period = 1;
  std::string out;
};

int Fail(NodeIo& io, int code, const std::string& message) {
  io.Log(NodeLogLevel::kFatal, message);
  return code;
}

// Reads every parameter; "" or the first error.
std::string ReadParams(const NodeIo& io, NodeSettings* s) {
  std::string e;
  auto get = [&](const char* name, auto* value) {
    if (e.empty()) e = io.GetParam(name, value);
  };
  get("model", &s->model);
  get("config", &s->config);
  get("threads", &s->threads);
  get("isa", &s->isa);
  get("budget_ms", &s->budget_ms);
  std::string on_miss = config::MissActionName(s->on_miss);
  get("on_miss", &on_miss);
  if (const std::optional<config::MissAction> action = config::MissActionFromName(on_miss)) {
    s->on_miss = *action;
  } else if (e.empty()) {
    e = io.ParamName("on_miss") + " '" + on_miss + "' is not one of " +
        vocabulary::NameList(config::kMissActionNames);
  }
  get("fallback_size", &s->fallback_size);
  get("recover_after", &s->recover_after);
  get("size", &s->size);
  get("allow_aspect_change", &s->allow_aspect_change);
  get("transport", &s->transport);
  get("slop_ms", &s->slop_ms);
  get("queue_size", &s->queue_size);
  get("frame_interval_ms", &s->frame_interval_ms);
  get("input_queue", &s->input_queue);
  get("queue_policy", &s->queue_policy);
  get("publish_vis", &s->publish_vis);
  get("frame_id", &s->frame_id);
  get("camera_info", &s->camera_info);
  get("diagnostics_period", &s->diagnostics_period);
  get("out", &s->out);
  return e;
}

bool ParseHxW(const std::string& text, int* h, int* w) {
  char x = 0;
  char rest = 0;
  return std::sscanf(text.c_str(), "%d%c%d%c", h, &x, w, &rest) == 3 && (x == 'x' || x == 'X') &&
         *h > 0 && *w > 0;
}

using profiling::FormatFixed;

// Checks camera_info against the model's training camera once both sides have arrived: the left
// focal length scaled to the model's input width, and the baseline from the right projection
// (Tx = -fx' * B). Warns once, naming both values; spinner thread only.
class CameraInfoCheck {
 public:
  CameraInfoCheck(CameraDesc trained, int input_width, NodeIo* io)
      : trained_(trained), input_width_(input_width), io_(io) {}
  void OnInfo(int side, const CameraInfoView& info) {
    if (done_) return;
    info_[side] = info;
    seen_[side] = true;
    if (!seen_[0] || !seen_[1]) return;
    done_ = true;
    const CameraInfoView& l = info_[0];
    const CameraInfoView& r = info_[1];
    if (l.width == 0 || l.p[0] <= 0) {
      io_->Log(NodeLogLevel::kWarn,
               "camera_info: the left projection matrix is empty; the "
               "camera is not checked against the model's");
      return;
    }
    const double width = input_width_ > 0 ? input_width_ : l.width;
    const double scale = width / l.width;
    const double fx = l.p[0] * scale;
    const double baseline = r.p[0] > 0 ? -r.p[3] / r.p[0] : 0;
    auto differs = [](double a, double b) {
      return std::fabs(a - b) > 0.01 * std::max(std::fabs(a), std::fabs(b));
    };
    bool agree = true;
    if (trained_.focal_px > 0 && differs(fx, trained_.focal_px)) {
      agree = false;
      io_->Log(NodeLogLevel::kWarn,
               "camera_info: focal length " + FormatFixed(fx, 2) + " px (P[0] " +
                   FormatFixed(l.p[0], 2) + " at " + std::to_string(l.width) +
                   " px wide, scaled to the model's " + FormatFixed(width, 0) +
                   " px input) differs from the model's training camera (" +
                   FormatFixed(trained_.focal_px, 2) + " px); the flow's scale may be off");
    }
    if (trained_.baseline > 0 && baseline > 0 && differs(baseline, trained_.baseline)) {
      agree = false;
      io_->Log(NodeLogLevel::kWarn,
               "camera_info: baseline " + FormatFixed(baseline, 4) +
                   " (from the right projection matrix) differs from the model's training "
                   "camera (" +
                   FormatFixed(trained_.baseline, 4) + "); the flow's scale may be off");
    }
    if (agree) {
      io_->Log(NodeLogLevel::kInfo, "camera_info: focal length " + FormatFixed(fx, 2) +
                                        " px and baseline " + FormatFixed(baseline, 4) +
                                        " match the model's training camera");
    }
  }

 private:
  CameraDesc trained_;
  int input_width_;
  NodeIo* io_;
  CameraInfoView info_[2];
  bool seen_[2] = {false, false};
  bool done_ = false;
};

std::atomic<bool> g_sigterm{false};
extern "C" void OnSigterm(int) { g_sigterm = true; }

// Applies the deployment profile (parameter config) where no parameter sets the same thing, and
// its process settings (CPUs, priorities, memory). 0, or the exit code after logging why.
int ApplyProfile(NodeIo& io, NodeSettings* s, PipelineOptions* opts,
                 std::vector<std::string>* notes,
                 std::unique_ptr<config::ProcessSettings>* process) {
  config::ValidationReport report;
  Result<config::DeploymentProfile> profile = config::LoadProfile(s->config, &report);
  if (!profile.ok()) {
    config::PrintErrors(report.errors, std::cerr);
    return Fail(io, kExitUsage,
                io.ParamName("config") + " '" + s->config +
                    "' is not a valid deployment profile: " + profile.message());
  }
  const config::DeploymentProfile& p = *profile;
  if (!io.HasParam("model")) s->model = p.model_file;
  if (!io.HasParam("size") && p.input_height > 0) {
    s->size = std::to_string(p.input_height) + "x" + std::to_string(p.input_width);
  }
  if (!io.HasParam("threads")) s->threads = p.stage(config::Stage::kInfer).threads;
  if (!io.HasParam("budget_ms")) s->budget_ms = p.budget_ms;
  ProfileRun run = ApplyProfileToRun(p, config::QueryProcessCapabilities(),
                                     /*keep_on_miss=*/io.HasParam("on_miss"), opts);
  *process = std::move(run.process);
  for (const std::string& w : (*process)->Warnings()) notes->push_back(w);
  notes->push_back("profile '" + s->config +
                   "': its source, calibration (the topics are rectified) and outputs are not "
                   "used by the node");
  return 0;
}

// The parameters as pipeline options, each checked. 0, or the exit code after logging why.
int ToOptions(NodeIo& io, const NodeSettings& s, PipelineOptions* opts) {
  if (s.isa != "auto" && (!ParseIsa(s.isa, &opts->isa) || opts->isa == Isa::kAuto)) {
    return Fail(io, kExitUsage,
                io.ParamName("isa") + " '" + s.isa + "' is not one of " + IsaNameList(true));
  }
  if (std::string e = config::CheckRange(config::kThreads, io.ParamName("threads"), s.threads);
      !e.empty()) {
    return Fail(io, kExitUsage, e);
  }
  opts->threads = config::ResolveThreads(s.threads);
  if (!s.size.empty()) {
    if (!ParseHxW(s.size, &opts->height, &opts->width)) {
      return Fail(io, kExitUsage,
                  io.ParamName("size") + " '" + s.size + "' is not HxW (e.g. 270x480)");
    }
    if (std::string e =
            config::CheckSize(config::kInputSide, io.ParamName("size"), opts->height, opts->width);
        !e.empty()) {
      return Fail(io, kExitUsage, e);
    }
  }
  opts->allow_aspect_change = s.allow_aspect_change;
  if (s.budget_ms < 0) {
    return Fail(io, kExitUsage,
                io.ParamName("budget_ms") + " must be >= 0, got " + FormatFixed(s.budget_ms, 3));
  }
  opts->budget_ms = s.budget_ms;
  // The parameter, or without one what the profile set (ApplyProfile).
  if (io.HasParam("on_miss") || s.config.empty()) opts->on_miss = s.on_miss;
  if (io.HasParam("on_miss") && s.on_miss == config::MissAction::kSmallerInput) {
    int h = 0, w = 0;
    if (!ParseHxW(s.fallback_size, &h, &w)) {
      return Fail(io, kExitUsage,
                  io.ParamName("on_miss") + " smaller-input needs " +
                      io.ParamName("fallback_size") + " HxW, got '" + s.fallback_size + "'");
    }
    opts->smaller_input_on_miss = {h, w};
    opts->recover_after = std::max(1, s.recover_after);
  }
  if (s.queue_policy == "block") {
    opts->policy = QueuePolicy::kBlock;
  } else if (s.queue_policy != "newest-wins") {
    return Fail(
        io, kExitUsage,
        io.ParamName("queue_policy") + " '" + s.queue_policy + "' is not newest-wins or block");
  }
  if (s.slop_ms <= 0)
    return Fail(io, kExitUsage,
                io.ParamName("slop_ms") + " must be > 0, got " + FormatFixed(s.slop_ms, 3));
  if (s.frame_interval_ms < 0) {
    return Fail(io, kExitUsage,
                io.ParamName("frame_interval_ms") + " must be >= 0, got " +
                    FormatFixed(s.frame_interval_ms, 3));
  }
  if (s.input_queue < 1 || s.queue_size < 1) {
    return Fail(
        io, kExitUsage,
        io.ParamName("input_queue") + " and " + io.ParamName("queue_size") + " must be >= 1");
  }
  if (s.diagnostics_period <= 0)
    return Fail(io, kExitUsage, io.ParamName("diagnostics_period") + " must be > 0");
  return 0;
}

// The run's last line (or its failure) through the node's log; the exit code.
int ReportResult(NodeIo& io, const NodeIdentity& identity, const PipelineResult& result,
                 bool stopped_by_signal) {
  if (!result.started && stopped_by_signal) {
    io.Log(NodeLogLevel::kInfo, identity.name + ": stopped before the first stereo pair arrived");
    return kExitOk;
  }
  if (result.usage_error) return Fail(io, kExitUsage, result.status.message());
  if (!result.status.ok()) return Fail(io, kExitFailure, result.status.message());
  io.Log(NodeLogLevel::kInfo,
         identity.name + ": " + std::to_string(result.frames) + " windows published, stopped by " +
             result.stopped_by + ", end to end p50 " + FormatFixed(result.end_to_end.p50, 2) +
             " ms, p99 " + FormatFixed(result.end_to_end.p99, 2) + " ms" +
             (result.summary_path.empty() ? std::string() : ", summary " + result.summary_path));
  return kExitOk;
}

// The flow topics' sink: its topics, frame, diagnostics and the facts its status reports.
TopicSinkOptions SinkOptionsFor(NodeIo& io, const NodeSettings& s, const ModelMetadata& md,
                                const PipelineOptions& opts, Isa isa) {
  TopicSinkOptions o;
  o.topics = {io.Resolve("flow"), io.Resolve("flow_t1"), io.Resolve("flow_vis")};
  o.frame_id = s.frame_id;
  o.diagnostics_period_s = s.diagnostics_period;
  o.hardware_id = md.name;
  o.facts = {{"isa", IsaName(isa)},
             {"precision", PrecisionSummary(md)},
             {"threads", std::to_string(opts.threads)},
             {"model", s.model},
             {"input size",
              s.size.empty() ? "the size a trained model records, else the images'" : s.size},
             {"on_miss", config::MissActionName(opts.on_miss)}};
  o.budget_ms = s.budget_ms;
  o.received = [&io](int side) { return io.received(side); };
  return o;
}

// The summary's directory, made and checked now, not found unwritable at shutdown. 0, or the
// exit code after logging why.
int PrepareOutDir(NodeIo& io, const std::string& out) {
  if (out.empty()) return 0;
  if (std::string e = io::CheckWritableDirectory(out, io.ParamName("out")); !e.empty()) {
    return Fail(io, kExitUsage, e);
  }
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (!std::filesystem::is_directory(out, ec)) {
    return Fail(io, kExitUsage,
                io.ParamName("out") + " '" + out + "': cannot create the directory" +
                    (ec ? " (" + ec.message() + ")" : std::string()));
  }
  return 0;
}

// The pipeline on its own thread until it ends, while this one turns ROS shutdown or SIGTERM
// into a stop and publishes the diagnostics when no window does.
PipelineResult RunUntilStopped(NodeIo& io, const std::shared_ptr<const Model>& model,
                               TopicSource* source, const PipelineOptions& opts,
                               FlowTopicSink& sink, std::atomic<bool>& stop,
                               std::atomic<int>& stop_signal) {
  PipelineResult result;
  std::atomic<bool> done{false};
  std::thread runner([&] {
    result = RunPipeline(model, source, opts);
    done = true;
  });
  while (!done.load()) {
    if (!stop.load() && (!io.Ok() || g_sigterm.load())) {
      stop_signal = g_sigterm.load() ? SIGTERM : SIGINT;
      stop = true;
    }
    sink.PublishIfIdle(detail::NowNs());
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  runner.join();
  return result;
}

}  // namespace

int RunNode(NodeIo& io, const NodeIdentity& identity) {
  NodeSettings s;
  if (std::string e = ReadParams(io, &s); !e.empty()) return Fail(io, kExitUsage, e);

  PipelineOptions opts;
  std::vector<std::string> notes;
  std::unique_ptr<config::ProcessSettings> process;
  if (!s.config.empty()) {
    if (int code = ApplyProfile(io, &s, &opts, &notes, &process); code != 0) return code;
  }
  if (s.model.empty()) {
    return Fail(io, kExitUsage, "set " + io.ParamName("model") + " or " + io.ParamName("config"));
  }

  Result<std::shared_ptr<const Model>> model = Model::LoadFile(s.model);
  if (!model.ok()) return Fail(io, kExitFailure, model.message());
  const ModelMetadata& md = (*model)->metadata();

  if (int code = ToOptions(io, s, &opts); code != 0) return code;

  NodeLog log(&io);
  for (const std::string& n : notes) log.Write(LogLevel::kInfo, "note", n);
  std::atomic<bool> stop{false};
  std::atomic<int> stop_signal{0};

  NodeSubscription sub;
  sub.transport = s.transport;
  sub.camera_info = s.camera_info;
  sub.slop_s = s.slop_ms / 1e3;
  sub.queue_size = s.queue_size;
  sub.frame_interval_s = s.frame_interval_ms / 1e3;
  TopicSourceOptions src_opts;
  src_opts.left_topic = io.Resolve(sub.left_topic);
  src_opts.right_topic = io.Resolve(sub.right_topic);
  src_opts.input_queue = static_cast<size_t>(s.input_queue);
  src_opts.stop = &stop;
  src_opts.log = &log;
  TopicSource source(src_opts);
  CameraInfoCheck info_check(md.camera, opts.width, &io);

  const Isa isa = opts.isa == Isa::kAuto ? BestIsa() : opts.isa;
  const TopicSinkOptions sink_opts = SinkOptionsFor(io, s, md, opts, isa);
  FlowTopicSink sink(
      sink_opts, &io, &source, [&io] { return io.NowNs(); },
      [&io](const std::vector<DiagnosticReport>& r) { io.PublishDiagnostics(r); });

  if (std::string e = io.Advertise(sink_opts.topics.flow, sink_opts.topics.t1, sink_opts.topics.vis,
                                   s.publish_vis);
      !e.empty()) {
    return Fail(io, kExitFailure, e);
  }
  if (std::string e = io.Subscribe(
          sub,
          [&source](const ImageMessage& l, const ImageMessage& r, const std::string& frame_id) {
            source.OnPair(l, r, frame_id);
          },
          [&info_check](int side, const CameraInfoView& info) { info_check.OnInfo(side, info); });
      !e.empty()) {
    return Fail(io, kExitUsage, e);
  }

  if (int code = PrepareOutDir(io, s.out); code != 0) return code;
  opts.out_dir = s.out;
  opts.write_flow = false;
  opts.write_png = false;
  opts.write_summary = !s.out.empty();
  opts.progress = ProgressMode::kOff;
  opts.model_path = s.model;
  opts.stop = &stop;
  opts.stop_signal = &stop_signal;
  opts.sinks = {&sink};
  // flow_vis behind its own queue: a picture that cannot keep up is dropped (counted in the
  // summary's sinks), never delaying a flow message. Its colour scale is set by the first
  // window's flow and kept, so colours mean the same in every picture.
  std::optional<VisTopicSink> vis_sink;
  std::optional<QueuedSink> vis_queue;
  if (s.publish_vis) {
    vis_sink.emplace(sink_opts.topics.vis,
                     VisualizerOptions{{VisScale::Mode::kFirst, 0}, md.output.units}, s.frame_id,
                     &io, &source);
    vis_queue.emplace("ros flow_vis queue", std::vector<FlowSink*>{&*vis_sink}, 2,
                      QueuePolicy::kNewestWins);
    opts.sinks.push_back(&*vis_queue);
  }
  opts.log = &log;

  std::signal(SIGTERM, OnSigterm);
  io.StartSpinner();
  io.Log(NodeLogLevel::kInfo,
         identity.name + ": model " + s.model + " (" + PrecisionSummary(md) + "), isa " +
             IsaName(isa) + ", " + std::to_string(opts.threads) + " thread(s), budget " +
             (s.budget_ms > 0 ? FormatFixed(s.budget_ms, 1) + " ms" : std::string("none")) +
             ", publishing " + sink_opts.topics.flow);

  const PipelineResult result = RunUntilStopped(io, *model, &source, opts, sink, stop, stop_signal);
  for (const std::string& w : result.warnings) log.Write(LogLevel::kWarn, "warning", w);
  const int code = ReportResult(io, identity, result, stop_signal.load() != 0);
  io.Shutdown();
  return code;
}

}  // namespace sfrt::pipeline
