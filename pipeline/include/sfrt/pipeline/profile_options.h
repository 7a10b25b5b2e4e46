// What a deployment profile (firmware-cfg/) sets in the pipeline's options, in one place for every
// program that runs the pipeline from a profile: `sfrt run --config` and both ROS nodes.
//
// ApplyProfileToRun sets the run's own settings:
//   - the process settings: memory (mlockall, cap) applied now, each stage's CPUs and priority on
//     the stage's thread (PipelineOptions::on_stage_start);
//   - memory.prefault_arena (PipelineOptions::prefault);
//   - latency.on_miss with its fallback size and recover_after, unless the caller keeps its own
//     (a node's on_miss parameter wins over the profile).
// The model, input size, inference threads and budget are the caller's to take from the profile,
// because a command-line flag or a node parameter given for one of them wins over the profile.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "sfrt/config/capabilities.h"
#include "sfrt/config/process_settings.h"
#include "sfrt/config/profile.h"
#include "sfrt/pipeline/pipeline.h"

namespace sfrt::pipeline {

struct ProfileRun {
  // The process settings; on_stage_start calls into them, so they must outlive the run.
  std::unique_ptr<config::ProcessSettings> process;
  // What was set, as the profile names it: "memory.prefault_arena (...)", "latency.on_miss ...".
  std::vector<std::string> applied;
};

ProfileRun ApplyProfileToRun(const config::DeploymentProfile& profile,
                             const config::ProcessCapabilities& capabilities, bool keep_on_miss,
                             PipelineOptions* options);

}  // namespace sfrt::pipeline
