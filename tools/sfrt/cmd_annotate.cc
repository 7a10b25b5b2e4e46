// sfrt annotate: ground-truth scene flow for a Scene Flow dataset tree (FlyingThings3D,
// Driving, Monkaa, or `sfrt synth` output), per tools/synth/annotate.h.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "sfrt/commands.h"
#include "synth/annotate.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "annotate";

struct AnnotateArgs {
  std::string root;
  std::string out;
  double focal = 0;
  double baseline = 1;
  double cx = 0;
  double cy = 0;
  std::string subset;
  std::string convention = "formula";
  CLI::Option* focal_opt = nullptr;
  CLI::Option* baseline_opt = nullptr;
  CLI::Option* cx_opt = nullptr;
  CLI::Option* cy_opt = nullptr;
};

// The camera the disparities were rendered with: --subset's, the flags', or the tree's
// camera.json (sfrt synth's). 0, or the exit code after reporting why there is none.
int CameraOf(const AnnotateArgs& args, synth::Intrinsics* k, std::string* camera_source) {
  const bool explicit_camera = args.focal_opt->count() > 0 || args.cx_opt->count() > 0 ||
                               args.cy_opt->count() > 0 || args.baseline_opt->count() > 0;
  if (!args.subset.empty()) {
    if (explicit_camera) {
      return ReportError(kName, "give either --subset or --focal/--baseline/--cx/--cy, not both",
                         kExitUsage);
    }
    if (!synth::SubsetIntrinsics(args.subset, k)) {
      return ReportError(kName,
                         "--subset: expected driving15mm, driving35mm, flyingthings3d or monkaa, "
                         "got '" +
                             args.subset + "'",
                         kExitUsage);
    }
    *camera_source = "--subset " + args.subset;
    return 0;
  }
  if (explicit_camera) {
    if (args.focal_opt->count() == 0 || args.cx_opt->count() == 0 || args.cy_opt->count() == 0) {
      return ReportError(kName,
                         "--focal, --cx and --cy must be given together (--baseline "
                         "defaults to 1)",
                         kExitUsage);
    }
    if (!(args.focal > 0) || !(args.baseline > 0)) {
      return ReportError(kName,
                         "--focal and --baseline must be positive, got " + FormatFloat(args.focal) +
                             " and " + FormatFloat(args.baseline),
                         kExitUsage);
    }
    *k = synth::Intrinsics{args.focal, args.baseline, args.cx, args.cy};
    *camera_source = "command line";
    return 0;
  }
  const std::string json = (std::filesystem::path(args.root) / "camera.json").string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(json, ec)) {
    return ReportError(kName,
                       "no camera: give --subset or --focal --cx --cy (there is no " + json +
                           " as `sfrt synth` writes)",
                       kExitUsage);
  }
  Result<synth::Intrinsics> read = synth::ReadCameraJson(json);
  if (!read.ok()) return ReportError(kName, read.message(), kExitFailure);
  *k = *read;
  *camera_source = json;
  return 0;
}

// What was written (an error where nothing was), and the invalid pixels and skipped frames.
int ReportAnnotated(const AnnotateArgs& args, const synth::AnnotateSummary& s) {
  if (s.frames_found == 0) {
    return ReportError(kName,
                       "no disparity file <dir>/left/NNNN.pfm under '" +
                           (std::filesystem::path(args.root) / "disparity").string() + "'",
                       kExitFailure);
  }
  if (s.frames_written == 0) {
    return ReportError(kName,
                       "none of the " + std::to_string(s.frames_found) +
                           " frames has all its inputs (first: " + s.first_skipped + ")",
                       kExitFailure);
  }
  char pct[32];
  std::snprintf(pct, sizeof(pct), "%.3f%%",
                s.pixels > 0 ? 100.0 * static_cast<double>(s.invalid_pixels) / s.pixels : 0.0);
  std::cout << "wrote     " << s.frames_written << " scene-flow files under "
            << (std::filesystem::path(args.out) / "scene_flow").string() << "\n"
            << "invalid   " << GroupDigits(s.invalid_pixels) << " of " << GroupDigits(s.pixels)
            << " pixels (" << pct << ") set to NaN (d0 <= 0 or d1 <= 0)\n";
  if (s.frames_skipped > 0) {
    std::cout << "skipped   " << s.frames_skipped
              << " frame(s) with missing inputs (first: " << s.first_skipped << ")\n";
  }
  return kExitOk;
}

int RunAnnotate(const AnnotateArgs& args) {
  synth::ConventionKind convention;
  if (args.convention == "formula") {
    convention = synth::ConventionKind::kFormula;
  } else if (args.convention == "authors-published") {
    convention = synth::ConventionKind::kAuthorsPublished;
  } else {
    return ReportError(
        kName,
        "--convention: expected 'formula' or 'authors-published', got '" + args.convention + "'",
        kExitUsage);
  }
  synth::Intrinsics k;
  std::string camera_source;
  if (int code = CameraOf(args, &k, &camera_source); code != 0) return code;

  std::cout << "camera    f " << FormatFloat(k.focal) << " px, baseline " << FormatFloat(k.baseline)
            << ", cx " << FormatFloat(k.cx) << ", cy " << FormatFloat(k.cy) << " (" << camera_source
            << ")\n"
            << "formula   "
            << (convention == synth::ConventionKind::kFormula
                    ? "spec: d1 = d0 + disparity_change, (col, u) with cx, (row, v) with cy"
                    : "authors-published: d1 = disparity of frame t+1 at the same pixel, (row, "
                      "u) with cx, (col, v) with cy")
            << "\n"
            << std::flush;
  int printed_every = 0;
  Result<synth::AnnotateSummary> summary = synth::AnnotateTree(
      args.root, args.out, k, convention, [&](const synth::AnnotateFrameInfo& f) {
        if (printed_every == 0) printed_every = std::max(1, f.total / 100);
        if ((f.index + 1) % printed_every != 0 && f.index + 1 != f.total) return;
        std::cout << "frame     " << f.index + 1 << "/" << f.total << "  " << f.output << "  ("
                  << GroupDigits(f.invalid) << " invalid)\n"
                  << std::flush;
      });
  if (!summary.ok()) return ReportError(kName, summary.message(), kExitFailure);
  return ReportAnnotated(args, *summary);
}

}  // namespace

Command AddAnnotateCommand(CLI::App& parent) {
  auto args = std::make_shared<AnnotateArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "annotate", "Write ground-truth scene flow for a Scene Flow dataset tree");
  cmd->add_option("DATASET_ROOT", args->root,
                  "Dataset root holding disparity/, disparity_change/ and optical_flow/")
      ->required();
  cmd->add_option("--out", args->out, "Output root: writes <out>/scene_flow/...")->required();
  args->focal_opt = cmd->add_option("--focal", args->focal, "Focal length in px");
  args->baseline_opt =
      cmd->add_option("--baseline", args->baseline, "Baseline in scene units (default 1)");
  args->cx_opt = cmd->add_option("--cx", args->cx, "Principal point x in px");
  args->cy_opt = cmd->add_option("--cy", args->cy, "Principal point y in px");
  cmd->add_option("--subset", args->subset,
                  "Scene Flow subset camera: driving15mm (f 450), driving35mm, flyingthings3d, "
                  "monkaa (f 1050); cx 479.5, cy 269.5, B 1");
  cmd->add_option("--convention", args->convention,
                  "formula (the spec's, default) or authors-published (the ground truth "
                  "published with the authors' code)");
  cmd->footer(
      "For every DATASET_ROOT/disparity/<dir>/left/NNNN.pfm, reads\n"
      "  disparity_change/<dir>/into_future/left/NNNN.pfm and\n"
      "  optical_flow/<dir>/into_future/left/OpticalFlowIntoFuture_NNNN_L.pfm\n"
      "and writes <out>/scene_flow/<dir>/into_future/left/NNNN.pfm (3-channel PFM, dX dY dZ):\n"
      "  Z0 = f B / d0, X0 = (col - cx) Z0 / f, Y0 = (row - cy) Z0 / f, d1 = d0 + change,\n"
      "  Z1 = f B / d1, X1 = (col + u - cx) Z1 / f, Y1 = (row + v - cy) Z1 / f, flow = P1 - P0.\n"
      "Pixels with d0 <= 0 or d1 <= 0 are NaN and counted. Frames with missing inputs are\n"
      "skipped and counted. --convention authors-published instead takes d1 from\n"
      "disparity/<dir>/left/<NNNN+1>.pfm at the same pixel and pairs the row index with cx and\n"
      "u (and the column with cy and v), as the authors' published code does.\n"
      "Camera: --subset, or --focal --cx --cy [--baseline], or DATASET_ROOT/camera.json (as\n"
      "`sfrt synth` writes). Disparities must be positive (not the negated FlyingThings3D\n"
      "subset files).\n"
      "Exit codes: 0 success, 1 runtime or input failure, 2 usage error.");
  return Command{cmd, [args] { return RunAnnotate(*args); }};
}

}  // namespace sfrt::tools
