// sfrt synth: synthetic stereo sequences with exact scene-flow ground truth, written in the
// Scene Flow datasets' layout (see tools/synth/dataset.h).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <thread>

#include "eval/kitti_layout.h"
#include "sfrt/commands.h"
#include "sfrt/config/limits.h"
#include "synth/dataset.h"
#include "synth/texture.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "synth";

struct SynthArgs {
  std::string out;
  std::string layout = "scene-flow";
  unsigned long long seed = 1;
  int frames = 10;
  std::string size = "540x960";
  int sequences = 1;
  double focal = 0;
  double baseline = 1;
  double cx = 0;
  double cy = 0;
  int objects = 8;
  std::string scene = "room";
  std::string textures;
  double noise = 0;
  double blur = 0;
  double pitch_rate = 0.004;
  double max_speed = 0.10;
  int threads = 0;
  bool force = false;
  CLI::Option* focal_opt = nullptr;
  CLI::Option* cx_opt = nullptr;
  CLI::Option* cy_opt = nullptr;
  CLI::Option* pitch_rate_opt = nullptr;
  CLI::Option* max_speed_opt = nullptr;
};

// --layout kitti: the scenes as KITTI Scene Flow 2015's training folder (eval/kitti_layout.h).
template <typename Seconds>
int WriteKitti(const synth::DatasetOptions& options, const SynthArgs& args, Seconds seconds) {
  if (args.force) {
    return ReportError(kName,
                       "--force replaces a Scene Flow layout sfrt synth wrote; the KITTI "
                       "layout is written to a new or empty --out only",
                       kExitUsage);
  }
  Status status = eval::WriteKittiLayout(options, args.out, [&](int done, int total) {
    if (done % std::max(1, total / 20) != 0 && done != total) return;
    std::cout << "scene     " << done << "/" << total << "\n" << std::flush;
  });
  if (!status.ok()) return ReportError(kName, status.message(), kExitFailure);
  char line[200];
  std::snprintf(line, sizeof(line), "wrote     %d KITTI scenes to %s/training in %.1f s",
                args.sequences * (args.frames - 1), args.out.c_str(), seconds());
  std::cout << line << "\n";
  return kExitOk;
}

// The flags' values that are not the output directory's, each checked: 0, or the exit code after
// reporting the first that is wrong.
int CheckSynthArgs(const SynthArgs& args, const synth::Camera& camera) {
  if (std::string problem =
          config::CheckSize(config::kFrameSide, "--size", camera.height, camera.width);
      !problem.empty()) {
    return ReportError(kName, problem, kExitUsage);
  }
  if (std::string problem = config::CheckRange(config::kThreads, "--threads", args.threads);
      !problem.empty()) {
    return ReportError(kName, problem, kExitUsage);
  }
  auto range = [](const char* flag, double value, double lo, double hi) -> std::string {
    if (std::isfinite(value) && value >= lo && value <= hi) return "";
    return std::string(flag) + ": must be from " + FormatFloat(lo) + " to " + FormatFloat(hi) +
           ", got " + FormatFloat(value);
  };
  for (const std::string& problem :
       {range("--frames", args.frames, 1, 9999), range("--sequences", args.sequences, 1, 9999),
        range("--objects", args.objects, 0, 200), range("--focal", camera.focal, 1e-3, 1e7),
        range("--baseline", args.baseline, 1e-6, 1e6), range("--cx", camera.cx, -1e6, 1e6),
        range("--cy", camera.cy, -1e6, 1e6), range("--noise", args.noise, 0, 255),
        range("--blur", args.blur, 0, 50), range("--pitch-rate", args.pitch_rate, 0, 0.2),
        range("--max-speed", args.max_speed, 0, 1)}) {
    if (!problem.empty()) return ReportError(kName, problem, kExitUsage);
  }
  return 0;
}

// The output directory: new, empty, or (--force) a data set sfrt synth wrote earlier. 0, or the
// exit code after reporting why not.
int CheckDestination(const SynthArgs& args) {
  switch (synth::ClassifyDestination(args.out)) {
    case synth::Destination::kAbsent:
    case synth::Destination::kEmptyDirectory:
      return 0;
    case synth::Destination::kSynthDataset:
      if (args.force) return 0;
      return ReportError(kName,
                         "--out '" + args.out +
                             "' is not empty (use --force to replace the data set in it once "
                             "the new one is complete)",
                         kExitFailure);
    case synth::Destination::kOtherDirectory:
      return ReportError(kName,
                         "--out '" + args.out +
                             "' is not empty and holds no data set sfrt synth wrote (no "
                             "camera.json with \"generator\": \"sfrt synth\"); even --force "
                             "replaces only those: give a new or empty directory",
                         kExitFailure);
    case synth::Destination::kNotADirectory:
      return ReportError(kName, "--out '" + args.out + "' exists and is not a directory",
                         kExitFailure);
  }
  return 0;
}

// The flags that need another: the robot rig's, and --textures' folder. 0, or the exit code.
int CheckSceneArgs(const SynthArgs& args) {
  for (const CLI::Option* robot_only : {args.pitch_rate_opt, args.max_speed_opt}) {
    if (robot_only->count() > 0 && args.scene != "robot") {
      return ReportError(kName,
                         robot_only->get_name() +
                             ": only --scene robot has a driving rig (got --scene " + args.scene +
                             ")",
                         kExitUsage);
    }
  }
  if (!args.textures.empty()) {
    Result<std::vector<std::string>> files = synth::ListTextureImages(args.textures);
    if (!files.ok()) return ReportError(kName, "--textures: " + files.message(), kExitFailure);
  }
  return 0;
}

synth::DatasetOptions DatasetOptionsOf(const SynthArgs& args, const synth::Camera& camera) {
  synth::DatasetOptions options;
  options.scene.preset =
      args.scene == "robot" ? synth::ScenePreset::kRobot : synth::ScenePreset::kRoom;
  options.scene.camera = camera;
  options.scene.frames = args.frames;
  options.scene.objects = args.objects;
  options.scene.max_pitch_rate = args.pitch_rate;
  options.scene.max_speed = args.max_speed;
  options.sequences = args.sequences;
  options.seed = args.seed;
  options.texture_dir = args.textures;
  options.noise_sigma = args.noise;
  options.blur_sigma = args.blur;
  options.threads = config::ResolveThreads(args.threads);
  // Ctrl-C or SIGTERM: the writer stops between frames and removes its partial tree.
  options.stop = CatchStopSignals().stop;
  return options;
}

// The Scene Flow layout, with a progress line per 1% of the frames.
template <typename Seconds>
int WriteSceneFlow(const synth::DatasetOptions& options, const SynthArgs& args, Seconds seconds) {
  const int total = args.sequences * args.frames;
  const int every = std::max(1, total / 100);
  Status status =
      synth::WriteDataset(options, args.out, args.force, [&](const synth::DatasetProgress& p) {
        if (p.frames_done % every != 0 && p.frames_done != p.frames_total) return;
        char line[160];
        const double s = seconds();
        std::snprintf(line, sizeof(line), "frame     seq %04d frame %04d  (%d/%d, %.2f frames/s)",
                      p.sequence, p.frame, p.frames_done, p.frames_total,
                      s > 0 ? p.frames_done / s : 0.0);
        std::cout << line << "\n" << std::flush;
      });
  if (!status.ok()) return ReportError(kName, status.message(), kExitFailure);
  char line[200];
  const double s = seconds();
  std::snprintf(line, sizeof(line), "wrote     %d frames to %s in %.1f s (%.2f frames/s)", total,
                args.out.c_str(), s, s > 0 ? total / s : 0.0);
  std::cout << line << "\n";
  return kExitOk;
}

int RunSynth(const SynthArgs& args) {
  int height = 0;
  int width = 0;
  if (!ParseSize(args.size, &height, &width)) {
    return ReportError(kName, "--size: expected HxW (e.g. 540x960), got '" + args.size + "'",
                       kExitUsage);
  }
  const double focal = args.focal_opt->count() > 0 ? args.focal : 1050.0 * width / 960.0;
  const double cx = args.cx_opt->count() > 0 ? args.cx : (width - 1) / 2.0;
  const double cy = args.cy_opt->count() > 0 ? args.cy : (height - 1) / 2.0;
  const synth::Camera camera{focal, args.baseline, cx, cy, width, height};
  if (int code = CheckSynthArgs(args, camera); code != 0) return code;
  if (int code = CheckDestination(args); code != 0) return code;
  if (int code = CheckSceneArgs(args); code != 0) return code;
  const synth::DatasetOptions options = DatasetOptionsOf(args, camera);

  std::cout << "camera    f " << FormatFloat(focal) << " px, baseline "
            << FormatFloat(args.baseline) << ", cx " << FormatFloat(cx) << ", cy "
            << FormatFloat(cy) << ", " << height << "x" << width << "\n"
            << "scenes    " << args.sequences << " sequence(s) x " << args.frames
            << " frame(s), seed " << args.seed << ", scene " << args.scene << ", " << args.objects
            << " objects, textures "
            << (args.textures.empty() ? std::string("procedural") : args.textures) << "\n"
            << std::flush;
  const auto start = std::chrono::steady_clock::now();
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  if (args.layout == "kitti") return WriteKitti(options, args, seconds);
  return WriteSceneFlow(options, args, seconds);
}

}  // namespace

Command AddSynthCommand(CLI::App& parent) {
  auto args = std::make_shared<SynthArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "synth", "Generate synthetic stereo sequences with exact scene-flow ground truth");
  cmd->add_option("--layout", args->layout,
                  "scene-flow (the Scene Flow datasets' folders, FlyingThings3D's) or kitti (KITTI "
                  "Scene Flow 2015's training/ folders and encodings: frames f -> f+1 of each "
                  "sequence as scenes, dense ground truth, obj_map from the objects)")
      ->capture_default_str()
      ->check(CLI::IsMember({"scene-flow", "kitti"}));
  cmd->add_option("--out", args->out,
                  "Output directory: new or empty, or with --force a data set sfrt synth wrote")
      ->required();
  cmd->add_option("--seed", args->seed, "Random seed; the same seed gives the same data")
      ->capture_default_str();
  cmd->add_option("--frames", args->frames, "Frames per sequence (1..9999)")->capture_default_str();
  cmd->add_option("--size", args->size, "Image size HxW")->capture_default_str();
  cmd->add_option("--sequences", args->sequences, "Number of sequences (1..9999)")
      ->capture_default_str();
  args->focal_opt = cmd->add_option("--focal", args->focal,
                                    "Focal length in px (default: 1050 * W / 960, the Scene Flow "
                                    "datasets' camera scaled to the width)");
  cmd->add_option("--baseline", args->baseline, "Stereo baseline in scene units")
      ->capture_default_str();
  args->cx_opt = cmd->add_option("--cx", args->cx, "Principal point x in px (default: (W-1)/2)");
  args->cy_opt = cmd->add_option("--cy", args->cy, "Principal point y in px (default: (H-1)/2)");
  cmd->add_option("--objects", args->objects, "Moving objects per scene besides the room (0..200)")
      ->capture_default_str();
  cmd->add_option("--scene", args->scene,
                  "Scene family: room (scale-free, sizes relative to f*B, static rig) or robot "
                  "(metres: a room of a few metres, the rig driving through it, objects at "
                  "0.8-5 m; use a metric --baseline such as 0.12)")
      ->check(CLI::IsMember({"room", "robot"}))
      ->capture_default_str();
  cmd->add_option("--textures", args->textures,
                  "Folder of images to texture surfaces with (default: procedural textures)");
  cmd->add_option("--noise", args->noise,
                  "Photometric noise, standard deviation in 8-bit grey levels (default 0)");
  cmd->add_option("--blur", args->blur, "Gaussian blur of the images, sigma in px (default 0)");
  args->pitch_rate_opt =
      cmd->add_option("--pitch-rate", args->pitch_rate,
                      "--scene robot: the largest pitch rate of the rig in radians per frame, "
                      "0..0.2, drawn per sequence (it shifts the image vertically by up to "
                      "focal x rate px a frame)")
          ->capture_default_str();
  args->max_speed_opt =
      cmd->add_option("--max-speed", args->max_speed,
                      "--scene robot: the largest forward speed of the rig, scene units per "
                      "frame, 0..1 (15% of the sequences creep at up to 0.01, the others drive "
                      "at 0.01 to this)")
          ->capture_default_str();
  cmd->add_option(
      "--threads", args->threads,
      "Rendering threads, 0..256 (0, the default: one per CPU; the output does not depend on it)");
  cmd->add_flag("--force", args->force,
                "Replace the data set sfrt synth wrote at --out, once the new one is complete "
                "(other non-empty directories are refused)");
  cmd->footer(
      "Scenes: a rectified pinhole stereo rig (right camera at +baseline along x) inside a\n"
      "textured box room, and textured spheres, boxes and flat cards moving and rotating\n"
      "rigidly; occlusion by ray casting per pixel centre. --scene room: the room moves\n"
      "slightly (ego-motion). --scene robot: metric, the rig drives through the room (speed up\n"
      "to --max-speed and turns up to 1.7 degrees per frame, pitching up to --pitch-rate),\n"
      "some objects static.\n"
      "Writing: the data set is written under <out>.partial-<pid> and renamed to --out only\n"
      "when every file is written and flushed; camera.json, with \"complete\": true, comes\n"
      "last (sfrt eval refuses an sfrt synth data set without it). On a failure (e.g. a full\n"
      "disk) or on SIGINT/SIGTERM (Ctrl-C: exit 1 once the current frame is written) the\n"
      "partial tree is removed and --out is left as it was.\n"
      "Output (Scene Flow datasets' layout, <seq> and NNNN from 0000):\n"
      "  camera.json, camera_data/<seq>/camera_data.txt\n"
      "  frames_cleanpass/<seq>/{left,right}/NNNN.png\n"
      "  disparity/<seq>/left/NNNN.pfm\n"
      "  disparity_change/<seq>/into_future/left/NNNN.pfm\n"
      "  optical_flow/<seq>/into_future/left/OpticalFlowIntoFuture_NNNN_L.pfm  (u, v, 0)\n"
      "  scene_flow/<seq>/into_future/left/NNNN.pfm  (dX, dY, dZ, scene units)\n"
      "Ground truth per left pixel at t: the surface point seen there, moved rigidly to t+1;\n"
      "defined for every pixel, also where the point leaves the view (no invalid marks).\n"
      "Exit codes: 0 success, 1 runtime or input failure, 2 usage error.");
  return Command{cmd, [args] { return RunSynth(*args); }};
}

}  // namespace sfrt::tools
