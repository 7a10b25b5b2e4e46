#include "sfrt/run_config.h"

#include <fcntl.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <thread>

#include "sfrt/commands.h"
#include "sfrt/config/capabilities.h"
#include "sfrt/pipeline/profile_options.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "run";

const char* Fourcc(config::PixelFormat f) {
  switch (f) {
    case config::PixelFormat::kYuyv:
      return "YUYV";
    case config::PixelFormat::kMjpeg:
      return "MJPG";
    case config::PixelFormat::kGrey:
      return "GREY";
    case config::PixelFormat::kNv12:
      return "NV12";
    case config::PixelFormat::kBgr24:
      return "BGR3";
    case config::PixelFormat::kRgb24:
      return "RGB3";
  }
  return "YUYV";
}

// The capability snapshot; SFRT_TEST_CAPABILITIES=none drops every privilege from it (the
// test seam: a root test run then sees what an unprivileged deployment sees).
config::ProcessCapabilities Capabilities() {
  config::ProcessCapabilities caps = config::QueryProcessCapabilities();
  const char* test = std::getenv("SFRT_TEST_CAPABILITIES");
  if (test && std::string(test) == "none") {
    caps.cap_sys_nice = false;
    caps.cap_ipc_lock = false;
    caps.rlimit_rtprio = 0;
    caps.rlimit_memlock = 0;
  }
  return caps;
}

struct Mapping {
  std::string key;   // profile key path
  std::string flag;  // sfrt run option
  std::string value;
};

}  // namespace

void AddRunConfigOptions(CLI::App* cmd, RunConfigState* state) {
  cmd->add_option("--config", state->config_path,
                  "Deployment profile (firmware-cfg/*.yaml, keys in firmware-cfg/README.md), "
                  "checked as `sfrt config check` does before any camera or file is opened "
                  "(invalid: every error as file:line:column, exit 2). It sets every option "
                  "here it has a key for; an option given on the command line overrides the "
                  "profile (e.g. --replay DIR for frames elsewhere). Settings without an option "
                  "(stage CPUs and SCHED_FIFO priority, mlockall, memory cap, arena prefault, "
                  "on_miss incl. smaller-input, log file) come only from the profile; those the "
                  "process may not "
                  "apply are warnings naming the fix, and the run goes on");
  cmd->add_option("--profile", state->profile_dir,
                  "Record per-frame, per-stage and per-layer timestamps (CLOCK_MONOTONIC) into a "
                  "preallocated ring and write DIR/profile.json, frames.csv, trace.json (Chrome "
                  "trace: Perfetto, chrome://tracing), latency_hist.png and latency_series.png. "
                  "DIR defaults to <out>/profile")
      ->expected(0, 1);
  cmd->add_option("--profile-frames", state->profile_frames,
                  "Frames the profile ring holds (the last N are reported)")
      ->capture_default_str();
  cmd->add_flag("--profile-overhead", state->profile_overhead,
                "Replays: also run the same input twice without profiling (before and after) "
                "in this process and report the median difference (implies --profile)");
}

// --config: the profile read and checked (its errors printed, its warnings too). kExitOk, or
// kExitUsage after reporting.
int LoadRunProfile(RunConfigState* state) {
  config::ValidationReport report;
  Result<config::DeploymentProfile> loaded = config::LoadProfile(state->config_path, &report);
  if (!loaded.ok()) {
    config::PrintErrors(report.errors, std::cerr);
    const size_t n = report.errors.size();
    std::cerr << "sfrt run: --config " << state->config_path << ": " << n
              << (n == 1 ? " error" : " errors") << "; nothing was opened" << std::endl;
    return kExitUsage;
  }
  for (const config::Diagnostic& d : report.warnings) {
    config::Diagnostic w = d;
    w.key = "warning: " + w.key;
    std::cerr << w.ToString() << "\n";
  }
  state->cfg = std::move(loaded).value();

  return kExitOk;
}

// The profile's source as flags; none when the command line names a source (then each is
// listed as overridden).
std::vector<Mapping> SourceAsFlags(const config::DeploymentProfile& p, CLI::App* cmd,
                                   RunConfigState* state) {
  std::vector<Mapping> maps;
  const bool cli_source = cmd->count("--camera") + cmd->count("--sbs-camera") +
                              cmd->count("--replay") + cmd->count("--replay-left") +
                              cmd->count("--replay-right") + cmd->count("--replay-video") >
                          0;
  std::vector<Mapping> source_maps;
  switch (p.source) {
    case config::SourceKind::kStereoCameras:
      source_maps.push_back({"camera.left_device/right_device", "--camera",
                             p.camera.left_device + "," + p.camera.right_device});
      break;
    case config::SourceKind::kSbsCamera:
      source_maps.push_back({"camera.device", "--sbs-camera", p.camera.device});
      break;
    case config::SourceKind::kReplayDataset:
      source_maps.push_back({"replay.dataset", "--replay", p.replay.dataset});
      break;
    case config::SourceKind::kReplayGlobs:
      source_maps.push_back({"replay.left", "--replay-left", p.replay.left});
      source_maps.push_back({"replay.right", "--replay-right", p.replay.right});
      break;
    case config::SourceKind::kReplayVideo:
      source_maps.push_back({"replay.video", "--replay-video", p.replay.video});
      break;
  }
  if (cli_source) {
    for (const Mapping& m : source_maps) {
      state->overridden.push_back(m.key + " (source given on the command line)");
    }
  } else {
    maps.insert(maps.end(), source_maps.begin(), source_maps.end());
  }
  return maps;
}

// The rest of the profile as `sfrt run` flags: the camera or replay settings, calibration,
// model, size, threads, budget, outputs, logging.
std::vector<Mapping> SettingsAsFlags(const config::DeploymentProfile& p, CLI::App* cmd,
                                     RunConfigState* state) {
  std::vector<Mapping> maps;
  const bool camera =
      p.source == config::SourceKind::kStereoCameras || p.source == config::SourceKind::kSbsCamera;
  if (camera) {
    const bool sbs = p.source == config::SourceKind::kSbsCamera;
    maps.push_back({"camera.pixel_format", "--format", Fourcc(p.camera.pixel_format)});
    maps.push_back({"camera.width/height", "--camera-size",
                    std::to_string(p.camera.height) + "x" +
                        std::to_string(sbs ? p.camera.width / 2 : p.camera.width)});
    maps.push_back({"camera.fps", "--fps", FormatFloat(p.camera.fps)});
    maps.push_back({"camera.buffer_count", "--buffers", std::to_string(p.camera.buffer_count)});
    if (p.camera.pair_tolerance_ms > 0) {
      maps.push_back({"camera.pair_tolerance_ms", "--pair-tolerance-ms",
                      FormatFloat(p.camera.pair_tolerance_ms)});
    }
    if (sbs && p.camera.order == config::SbsOrder::kRightLeft) {
      maps.push_back({"camera.order", "--right-first", "true"});
    }
  } else {
    maps.push_back({"replay.on_bad_frame", "--on-bad-frame",
                    camera::BadFramePolicyName(p.replay.on_bad_frame)});
    if (p.replay.loop) {
      if (cmd->get_option_no_throw("--loop") != nullptr) {
        maps.push_back({"replay.loop", "--loop", "1000000"});
      } else {
        state->not_applied.push_back("replay.loop: true: this build has no --loop");
      }
    }
    if (p.source == config::SourceKind::kReplayVideo &&
        p.replay.video_order == config::SbsOrder::kRightLeft) {
      maps.push_back({"replay.order", "--right-first", "true"});
    }
  }
  if (!p.calibration.empty()) {
    maps.push_back({"calibration", "--calibration", Join(p.calibration, ",")});
  }
  maps.push_back({"model.file", "--model", p.model_file});
  maps.push_back({"model.input_height/input_width", "--size",
                  std::to_string(p.input_height) + "x" + std::to_string(p.input_width)});
  maps.push_back({"stages.infer.threads", "--threads",
                  std::to_string(p.stage(config::Stage::kInfer).threads)});
  maps.push_back({"latency.budget_ms", "--budget-ms", FormatFloat(p.budget_ms)});
  maps.push_back({"outputs.dir", "--out", p.output_dir});
  if (!p.write_flow) {
    maps.push_back({"outputs.flow", "--flow-format", "none"});
  } else {
    maps.push_back({"outputs.flow_format", "--flow-format", config::FlowFormatName(p.flow_format)});
  }
  if (!p.visualisation) maps.push_back({"outputs.visualisation", "--no-png", "true"});
  if (!p.summary) maps.push_back({"outputs.summary", "--no-summary", "true"});
  switch (p.log_level) {
    case config::LogLevel::kError:
    case config::LogLevel::kWarn:
      maps.push_back({"logging.level", "--progress", "off"});
      break;
    case config::LogLevel::kDebug:
      maps.push_back({"logging.level", "--progress", "lines"});
      maps.push_back({"logging.level", "--progress-every", "1"});
      break;
    case config::LogLevel::kInfo:
      break;
  }

  return maps;
}

// Each mapping given to its option, unless the command line set it (then it is listed as
// overridden) or this build lacks the option (not applied). kExitOk, or kExitUsage after
// reporting a value the option refuses.
int ApplyMappings(const std::vector<Mapping>& maps, CLI::App* cmd, RunConfigState* state) {
  for (const Mapping& m : maps) {
    CLI::Option* opt = cmd->get_option_no_throw(m.flag);
    if (opt == nullptr) {
      state->not_applied.push_back(m.key + ": this build's `sfrt run` has no " + m.flag);
      continue;
    }
    if (opt->count() > 0) {
      state->overridden.push_back(m.key + " (" + m.flag + " on the command line)");
      continue;
    }
    try {
      opt->add_result(m.value);
      opt->run_callback();
    } catch (const CLI::Error& e) {
      return ReportError(
          kName,
          state->config_path + ": " + m.key + " as " + m.flag + " '" + m.value + "': " + e.what(),
          kExitUsage);
    }
    state->from_profile.push_back(m.flag + (m.value == "true" ? "" : " " + m.value) + "  (" +
                                  m.key + ")");
  }
  return kExitOk;
}

// outputs.video: the video goes into the output directory actually used.
void ApplyProfileVideo(const config::DeploymentProfile& p, CLI::App* cmd, RunConfigState* state) {
  if (!p.video) return;
  {
    CLI::Option* video = cmd->get_option_no_throw("--video");
    CLI::Option* out = cmd->get_option_no_throw("--out");
    if (video && video->count() > 0) {
      state->overridden.push_back("outputs.video (--video on the command line)");
    } else if (video && out && !out->results().empty()) {
      const std::string path =
          (std::filesystem::path(out->results().back()) / "visualisation.avi").string();
      video->add_result(path);
      video->run_callback();
      state->from_profile.push_back("--video " + path + "  (outputs.video)");
    }
  }
}

// Stages other than infer run on one thread: more in the profile is not applied.
void NoteStageThreads(const config::DeploymentProfile& p, RunConfigState* state) {
  for (int i = 0; i < config::kStageCount; ++i) {
    const auto stage = static_cast<config::Stage>(i);
    if (stage != config::Stage::kInfer && p.stage(stage).threads > 1) {
      state->not_applied.push_back(std::string("stages.") + config::StageName(stage) +
                                   ".threads: " + std::to_string(p.stage(stage).threads) +
                                   ": this stage runs on one thread (only infer has a pool)");
    }
  }
}

int ApplyRunConfig(CLI::App* cmd, RunConfigState* state) {
  state->profile = cmd->count("--profile") > 0 || state->profile_overhead;
  if (state->profile_frames < 1) {
    return ReportError(
        kName, "--profile-frames must be >= 1, got " + std::to_string(state->profile_frames),
        kExitUsage);
  }
  if (state->config_path.empty()) return kExitOk;

  if (int code = LoadRunProfile(state); code != kExitOk) return code;
  const config::DeploymentProfile& p = *state->cfg;

  // ---- the profile as `sfrt run` options
  std::vector<Mapping> maps = SourceAsFlags(p, cmd, state);
  const std::vector<Mapping> settings = SettingsAsFlags(p, cmd, state);
  maps.insert(maps.end(), settings.begin(), settings.end());
  if (int code = ApplyMappings(maps, cmd, state); code != kExitOk) return code;
  ApplyProfileVideo(p, cmd, state);
  NoteStageThreads(p, state);
  return kExitOk;
}

int ConfigurePipeline(RunConfigState* state, pipeline::PipelineOptions* options) {
  if (state->cfg) {
    const config::DeploymentProfile& p = *state->cfg;
    std::cout << "config      " << p.path << (p.name.empty() ? "" : " (" + p.name + ")") << "\n";
    for (const std::string& s : state->from_profile) std::cout << "  set       " << s << "\n";
    for (const std::string& s : state->overridden) std::cout << "  override  " << s << "\n";

    // Log file first, so every later warning goes there too.
    if (!p.log_file.empty()) {
      const int fd = ::open(p.log_file.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
      if (fd < 0 || ::dup2(fd, STDERR_FILENO) < 0) {
        state->not_applied.push_back("logging.file: cannot open '" + p.log_file +
                                     "' for appending (" + std::strerror(errno) +
                                     "); logging to stderr. Fix: create its directory or make "
                                     "it writable");
      } else {
        state->applied.push_back("logging.file " + p.log_file);
      }
      if (fd >= 0) ::close(fd);
    }
    const config::ProcessCapabilities caps = Capabilities();
    pipeline::ProfileRun run =
        pipeline::ApplyProfileToRun(p, caps, /*keep_on_miss=*/false, options);
    state->process = std::move(run.process);
    for (const config::SettingOutcome& o : state->process->Outcomes()) {
      std::cout << "  "
                << (o.setting.rfind("memory.", 0) == 0 ? (o.applied ? "applied " : "refused ")
                                                       : "pending ")
                << "  " << o.setting << " " << o.value << "\n";
    }
    // Warn now about what the snapshot already refuses; failures found when a stage starts are
    // reported in the final summary.
    const std::vector<config::CapabilityWarning> refused = config::CheckCapabilities(p, caps);
    for (const config::CapabilityWarning& w : refused) {
      std::cerr << "sfrt run: warning: " << w.ToString() << std::endl;
    }
    for (const config::SettingOutcome& o : state->process->Outcomes()) {  // failed system calls
      const bool warned = std::any_of(refused.begin(), refused.end(),
                                      [&](const auto& w) { return w.setting == o.setting; });
      if (o.setting.rfind("memory.", 0) == 0 && !o.applied && !warned) {
        std::cerr << "sfrt run: warning: " << o.setting << ": " << o.note << std::endl;
      }
    }
    state->applied.insert(state->applied.end(), run.applied.begin(), run.applied.end());
    for (const std::string& s : state->not_applied) {
      std::cerr << "sfrt run: warning: " << s << std::endl;
    }
  }
  if (state->profile) {
    if (state->profile_dir.empty()) {
      state->profile_dir = (std::filesystem::path(options->out_dir) / "profile").string();
    }
    std::error_code ec;
    std::filesystem::create_directories(state->profile_dir, ec);
    if (!std::filesystem::is_directory(state->profile_dir, ec)) {
      return ReportError(kName,
                         "--profile: cannot create the directory '" + state->profile_dir + "'",
                         kExitFailure);
    }
    state->profiler =
        std::make_unique<pipeline::FrameProfiler>(static_cast<size_t>(state->profile_frames));
    options->profiler = state->profiler.get();
  }
  std::cout.flush();
  return kExitOk;
}

pipeline::PipelineResult RunConfiguredPipeline(
    RunConfigState* state, std::shared_ptr<const Model> model, pipeline::FrameSource* source,
    const pipeline::PipelineOptions& options,
    const std::function<std::unique_ptr<pipeline::FrameSource>()>& baseline_source) {
  config::ProcessSettings* ps = state->process.get();
  auto run = [&](pipeline::FrameSource* src, const pipeline::PipelineOptions& opts) {
    pipeline::PipelineResult result;
    // The infer stage's affinity and policy on the thread that creates the Session: its pool
    // inherits them; each stage thread then sets its own.
    std::thread runner([&] {
      if (ps && ps->has_thread_settings())
        ps->ApplyToCurrentThread(config::StageIndex(config::Stage::kInfer));
      result = pipeline::RunPipeline(model, src, opts);
    });
    runner.join();
    return result;
  };

  std::optional<pipeline::OverheadComparison> ab;
  std::vector<pipeline::PipelineResult> without;
  const bool do_ab = state->profile_overhead && baseline_source != nullptr;
  if (state->profile_overhead && !baseline_source) {
    std::cerr << "sfrt run: warning: --profile-overhead: the source cannot be replayed twice "
                 "(cameras); only the estimated overhead is reported"
              << std::endl;
  }
  pipeline::PipelineOptions plain = options;
  plain.profiler = nullptr;
  plain.progress = pipeline::ProgressMode::kOff;
  // The baseline runs do the same work into their own directory, so the outputs and
  // summary.json in --out are the profiled run's.
  plain.out_dir = (std::filesystem::path(state->profile_dir) / "baseline-out").string();
  if (!plain.video_path.empty()) {
    plain.video_path = (std::filesystem::path(plain.out_dir) / "visualisation.avi").string();
  }
  if (do_ab) {
    std::error_code ec;
    std::filesystem::create_directories(plain.out_dir, ec);
  }
  if (do_ab) {
    std::unique_ptr<pipeline::FrameSource> b = baseline_source();
    without.push_back(run(b.get(), plain));
  }
  pipeline::PipelineResult result = run(source, options);
  if (do_ab && result.status.ok()) {
    std::unique_ptr<pipeline::FrameSource> b = baseline_source();
    without.push_back(run(b.get(), plain));
    pipeline::OverheadComparison c;
    c.frames_with = result.frames;
    double e2e = 0, infer = 0;
    for (const pipeline::PipelineResult& r : without) {
      c.frames_without += r.frames;
      e2e += r.end_to_end.p50;
      infer += r.stage[config::StageIndex(config::Stage::kInfer)].p50;
    }
    c.e2e_p50_without_ms = e2e / static_cast<double>(without.size());
    c.infer_p50_without_ms = infer / static_cast<double>(without.size());
    c.e2e_p50_with_ms = result.end_to_end.p50;
    c.infer_p50_with_ms = result.stage[config::StageIndex(config::Stage::kInfer)].p50;
    ab = c;
  }
  if (state->profiler && state->profiler->recorded() > 0) {
    pipeline::ProfileReportInfo info;
    info.dir = state->profile_dir;
    info.budget_ms = options.budget_ms;
    info.model_path = options.model_path;
    info.precision = PrecisionSummary(model->metadata());
    info.source = source->Describe();
    info.stopped_by = result.stopped_by;
    info.ab = ab;
    Result<pipeline::ProfileReportFiles> files =
        pipeline::WriteProfileReports(*state->profiler, info, &state->profile_table);
    if (files.ok()) {
      state->report_files = *files;
    } else {
      state->profile_error = files.message();
      state->profile_write_failed = true;
    }
  } else if (state->profiler) {
    state->profile_error = "no frame was written, so no profile was recorded";
  }
  return result;
}

void PrintRunConfigReport(const RunConfigState& state, const pipeline::PipelineResult& result,
                          std::ostream& out) {
  if (state.cfg) {
    const config::DeploymentProfile& p = *state.cfg;
    std::vector<std::string> applied = state.applied;
    std::vector<std::string> not_applied = state.not_applied;
    if (state.process) {
      for (const config::SettingOutcome& o : state.process->Outcomes()) {
        if (o.applied) {
          applied.push_back(o.setting + " " + o.value);
        } else {
          not_applied.push_back(o.setting + " " + o.value + ": " + o.note);
        }
      }
    }
    out << "settings    " << state.from_profile.size() << " options from " << p.path << ", "
        << state.overridden.size() << " overridden on the command line\n";
    for (const std::string& s : applied) out << "  applied       " << s << "\n";
    for (const std::string& s : not_applied) out << "  not applied   " << s << "\n";
    // The budget check at the profile's percentile (the next reported percentile up).
    const double q = p.budget_percentile;
    const char* name = q <= 50 ? "p50" : q <= 90 ? "p90" : q <= 99 ? "p99" : "max";
    const double v = q <= 50   ? result.end_to_end.p50
                     : q <= 90 ? result.end_to_end.p90
                     : q <= 99 ? result.end_to_end.p99
                               : result.end_to_end.max;
    if (result.end_to_end.count > 0 && p.budget_ms > 0) {
      out << "budget      " << name << " " << FormatFloat(v) << " ms "
          << (v <= p.budget_ms ? "within" : "OVER") << " the budget of " << FormatFloat(p.budget_ms)
          << " ms (latency.percentile " << FormatFloat(q) << ")\n";
    }
  }
  if (state.profiler) {
    if (!state.profile_error.empty()) {
      out << "profile     not written: " << state.profile_error << "\n";
    } else {
      out << state.profile_table;
      if (state.report_files) {
        out << "profile     " << state.report_files->json << "\n"
            << "            " << state.report_files->csv << "\n"
            << "            " << state.report_files->trace << "\n"
            << "            " << state.report_files->histogram_png << "\n"
            << "            " << state.report_files->series_png << "\n";
      }
    }
  }
}

}  // namespace sfrt::tools
