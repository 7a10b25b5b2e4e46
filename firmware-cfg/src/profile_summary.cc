// A deployment profile as `sfrt config check` and `sfrt run --config` show it to a person
// (FormatProfileSummary, profile.h).
#include <cstring>
#include <sstream>
#include <string>

#include "sfrt/config/profile.h"
#include "text.h"

namespace sfrt::config {

std::string FormatProfileSummary(const DeploymentProfile& p) {
  std::ostringstream s;
  auto row = [&s](const char* label, const std::string& value) {
    const size_t width = std::strlen(label);
    s << "  " << label << std::string(width < 16 ? 18 - width : 2, ' ') << value << "\n";
  };
  if (!p.name.empty()) row("name", p.name);
  std::string source = SourceKindName(p.source);
  const CameraSettings& cam = p.camera;
  switch (p.source) {
    case SourceKind::kStereoCameras:
      source += " " + cam.left_device + " + " + cam.right_device;
      break;
    case SourceKind::kSbsCamera:
      source += " " + cam.device + " (" + SbsOrderName(cam.order) + ")";
      break;
    case SourceKind::kReplayDataset:
      source += " " + p.replay.dataset;
      break;
    case SourceKind::kReplayGlobs:
      source += " " + p.replay.left + " | " + p.replay.right;
      break;
    case SourceKind::kReplayVideo:
      source += " " + p.replay.video + " (" + SbsOrderName(p.replay.video_order) + ")";
      break;
  }
  row("source", source);
  if (p.source == SourceKind::kStereoCameras || p.source == SourceKind::kSbsCamera) {
    std::string c = std::string(PixelFormatName(cam.pixel_format)) + " " +
                    std::to_string(cam.height) + "x" + std::to_string(cam.width) + " (HxW) at " +
                    FormatNumber(cam.fps) + " fps, " + std::to_string(cam.buffer_count) +
                    " buffers";
    if (p.source == SourceKind::kStereoCameras) {
      c += ", pairing within " + FormatNumber(cam.pair_tolerance_ms) + " ms";
    }
    row("capture", c);
  } else {
    row("on bad frame", std::string(camera::BadFramePolicyName(p.replay.on_bad_frame)) +
                            (p.replay.loop ? ", loop" : ""));
  }
  row("calibration", p.calibration.empty() ? "none (no rectification)" : Join(p.calibration));
  row("model", p.model_file + " at " + std::to_string(p.input_height) + "x" +
                   std::to_string(p.input_width) + " (HxW)");
  for (int i = 0; i < kStageCount; ++i) {
    const StageSettings& st = p.stages[i];
    std::string v = std::to_string(st.threads) + (st.threads == 1 ? " thread" : " threads");
    if (st.cpus.empty()) {
      v += ", any CPU";
    } else {
      std::vector<std::string> cpus;
      for (int cpu : st.cpus) cpus.push_back(std::to_string(cpu));
      v += ", CPUs " + Join(cpus, ",");
    }
    v += st.rt_priority ? ", SCHED_FIFO " + std::to_string(*st.rt_priority) : ", SCHED_OTHER";
    const std::string label = std::string("stage ") + StageName(static_cast<Stage>(i));
    row(label.c_str(), v);
  }
  row("memory", std::string("mlockall ") + (p.mlockall ? "on" : "off") + ", arena prefault " +
                    (p.prefault_arena ? "on" : "off") + ", cap " +
                    (p.memory_cap_mib ? std::to_string(*p.memory_cap_mib) + " MiB" : "none"));
  std::string latency = "p" + FormatNumber(p.budget_percentile) +
                        " <= " + FormatNumber(p.budget_ms) + " ms; on miss " +
                        MissActionName(p.on_miss);
  if (p.on_miss == MissAction::kSmallerInput) {
    latency += " " + std::to_string(p.fallback_height) + "x" + std::to_string(p.fallback_width);
  }
  row("latency", latency);
  std::string out = p.output_dir + ": flow ";
  out += p.write_flow ? FlowFormatName(p.flow_format) : "off";
  out += std::string(", visualisation ") + (p.visualisation ? "on" : "off") + ", video " +
         (p.video ? "on" : "off") + ", summary " + (p.summary ? "on" : "off");
  row("outputs", out);
  row("logging", std::string(LogLevelName(p.log_level)) + " to " +
                     (p.log_file.empty() ? "stderr" : p.log_file));
  return s.str();
}

}  // namespace sfrt::config
