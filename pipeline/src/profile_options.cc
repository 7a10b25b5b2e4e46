// A deployment profile's settings of the run (profile_options.h).
#include "sfrt/pipeline/profile_options.h"

namespace sfrt::pipeline {

ProfileRun ApplyProfileToRun(const config::DeploymentProfile& p,
                             const config::ProcessCapabilities& capabilities, bool keep_on_miss,
                             PipelineOptions* options) {
  ProfileRun run;
  run.process = std::make_unique<config::ProcessSettings>(p, capabilities);
  run.process->ApplyProcessWide();
  if (run.process->has_thread_settings()) {
    config::ProcessSettings* ps = run.process.get();
    options->on_stage_start = [ps](int stage) { ps->ApplyToCurrentThread(stage); };
  }
  if (p.prefault_arena) {
    options->prefault = true;
    run.applied.push_back("memory.prefault_arena (one inference on zeros at start)");
  }
  if (keep_on_miss) return run;
  options->on_miss = p.on_miss;
  if (p.on_miss == config::MissAction::kDropNext) {
    run.applied.push_back("latency.on_miss drop-next");
  }
  if (p.on_miss == config::MissAction::kSmallerInput) {
    options->smaller_input_on_miss = {p.fallback_height, p.fallback_width};
    options->recover_after = p.recover_after_frames;
    run.applied.push_back("latency.on_miss smaller-input " + std::to_string(p.fallback_height) +
                          "x" + std::to_string(p.fallback_width) + " (full size again after " +
                          std::to_string(p.recover_after_frames) + " in-budget frames)");
  }
  return run;
}

}  // namespace sfrt::pipeline
