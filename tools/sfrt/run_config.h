// `sfrt run --config FILE` and `sfrt run --profile [DIR]` (issue #6), kept apart from
// cmd_run.cc, which calls in at four points:
//
//   AddRunConfigOptions(cmd, state)  registers --config, --profile, --profile-frames and
//                                    --profile-overhead;
//   ApplyRunConfig(cmd, state)       after parsing, before anything is opened: loads and
//                                    validates the profile (an invalid one prints every error as
//                                    `sfrt config check` does, file:line:column, and exits 2) and
//                                    gives every `sfrt run` option the command line did not set
//                                    its value from the profile (explicit flags win);
//   ConfigurePipeline(state, opts)   the settings without a flag: stage affinity and SCHED_FIFO
//                                    (through config::ProcessSettings), mlockall, memory cap,
//                                    arena prefault, on_miss (drop-next, smaller-input), log
//                                    file; the profiler; prints the start banner;
//   RunConfiguredPipeline(...)       runs the pipeline on a thread that carries the infer stage's
//                                    settings (so the runtime's pool inherits them), first
//                                    without profiling when --profile-overhead asks for the A/B,
//                                    and writes the profile reports (profile_report.h);
//   PrintRunConfigReport(state, os)  settings applied / not applied, and the profile table.
#pragma once

#include <functional>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sfrt/config/process_settings.h"
#include "sfrt/config/profile.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/profile_report.h"
#include "sfrt/pipeline/profiler.h"

namespace CLI {
class App;
}  // namespace CLI

namespace sfrt::tools {

struct RunConfigState {
  // flags
  std::string config_path;
  std::string profile_dir;  // "" with --profile: <out>/profile
  bool profile = false;
  int64_t profile_frames = 10000;
  bool profile_overhead = false;

  // from the profile
  std::optional<config::DeploymentProfile> cfg;
  std::vector<std::string> from_profile;  // "--budget-ms 1000 (latency.budget_ms)"
  std::vector<std::string> overridden;    // "latency.budget_ms (--budget-ms on the command line)"
  std::vector<std::string> not_applied;   // settings this build or process does not apply
  std::vector<std::string> applied;       // settings without a flag that were applied
  std::unique_ptr<config::ProcessSettings> process;

  // profiling
  std::unique_ptr<pipeline::FrameProfiler> profiler;
  std::optional<pipeline::ProfileReportFiles> report_files;
  std::string profile_table;
  std::string profile_error;
  bool profile_write_failed = false;  // the reports could not be written (the run exits 1)
};

void AddRunConfigOptions(CLI::App* cmd, RunConfigState* state);

// kExitOk to go on; otherwise the exit code (the errors are printed).
int ApplyRunConfig(CLI::App* cmd, RunConfigState* state);

// Fills `options` (hooks, prefault, drop-next, profiler) and prints the start banner to stdout.
// Returns kExitOk, or an exit code after printing the error (e.g. --profile DIR not creatable).
int ConfigurePipeline(RunConfigState* state, pipeline::PipelineOptions* options);

// baseline_source: a fresh copy of the source for the A/B overhead run (--profile-overhead);
// null when the source cannot be replayed twice (cameras).
pipeline::PipelineResult RunConfiguredPipeline(
    RunConfigState* state, std::shared_ptr<const Model> model, pipeline::FrameSource* source,
    const pipeline::PipelineOptions& options,
    const std::function<std::unique_ptr<pipeline::FrameSource>()>& baseline_source);

void PrintRunConfigReport(const RunConfigState& state, const pipeline::PipelineResult& result,
                          std::ostream& out);

}  // namespace sfrt::tools
