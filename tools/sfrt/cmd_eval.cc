// sfrt eval: scene-flow accuracy of a model against ground truth, beside two baselines (zero
// flow and a classical OpenCV pipeline). See tools/eval/evaluate.h.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "eval/evaluate.h"
#include "eval/shards.h"
#include "sfrt/commands.h"
#include "sfrt/config/limits.h"
#include "sfrt/model.h"
#include "sfrt/model_notes.h"
#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/run_shards.h"
#include "sfrt/session_environment.h"
#include "sfrt/shard_args.h"
#include "sfrt/vocabulary/names.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "eval";

struct EvalArgs {
  std::string model;
  std::string dataset;
  std::string json;
  std::string size;
  int max_frames = 0;
  bool no_classical = false;
  bool quiet = false;
  bool allow_camera_mismatch = false;
  std::string thresholds = "absolute";
  std::string depth = "gt";
  std::string submission;
  std::string shard;
  int shard_count = 0;
};

// The flags as evaluation options: a usage error's message (and *code), or "".
std::string OptionsFromArgs(const EvalArgs& args, eval::EvalOptions* options, int* code) {
  *code = kExitUsage;
  options->model_path = args.model;
  options->dataset = args.dataset;
  options->thresholds =
      args.thresholds == "relative" ? eval::Thresholds::kRelative : eval::Thresholds::kAbsolute;
  options->max_frames = args.max_frames;
  options->classical = !args.no_classical;
  options->depth = *vocabulary::FromName<eval::DepthSource>(eval::kDepthSourceNames, args.depth);
  options->submission_dir = args.submission;
  options->allow_camera_mismatch = args.allow_camera_mismatch;
  if (!args.submission.empty() && args.model.empty()) {
    return "--write-submission writes the model's predictions; it needs --model";
  }
  if (Status env = tools::ApplySessionEnvironment(options->isa, options->tuning); !env.ok()) {
    return env.message();
  }
  if (!args.size.empty()) {
    if (args.model.empty()) return "--size sets the model's input size; it needs --model";
    if (!ParseSize(args.size, &options->model_height, &options->model_width)) {
      return "--size: expected HxW with positive integers (e.g. 128x224), got '" + args.size + "'";
    }
    if (std::string problem = config::CheckSize(config::kInputSide, "--size", options->model_height,
                                                options->model_width);
        !problem.empty()) {
      return problem;
    }
  }
  if (args.max_frames < 0) {
    return "--max-frames: must be 0 (all) or more, got " + std::to_string(args.max_frames);
  }
  if (!args.shard.empty()) {
    Result<ShardSpec> shard = ParseShardFlag(args.shard, args.shard_count);
    if (!shard.ok()) return shard.message();
    options->shard = *shard;
    if (args.json.empty()) return "--shard: a shard's results are its --json file; give --json";
  }
  *code = kExitFailure;
  if (!args.json.empty()) {
    if (std::string problem = CheckOutputFile(args.json, "--json"); !problem.empty()) {
      return problem;
    }
  }
  if (args.model.empty()) return "";
  if (std::string problem = CheckInputFile(args.model, "model file"); !problem.empty()) {
    return problem;
  }
  // Without --size, as `sfrt run` chooses: the size a trained model records (its training
  // camera's focal length is for it), else the dataset's.
  if (args.size.empty()) {
    Result<std::shared_ptr<const Model>> model = Model::LoadFile(args.model);
    if (!model.ok()) return model.message();
    eval::DefaultModelSize((*model)->metadata(), &options->model_height, &options->model_width);
  }
  return "";
}

// The report as `sfrt eval` prints it (also `sfrt merge`): the data set, camera and model, the
// table, the note on the thresholds' scale.
void PrintReport(const eval::EvalReport& report) {
  char camera[200];
  std::snprintf(camera, sizeof(camera), "f %g px, baseline %g, cx %g, cy %g", report.focal,
                report.baseline, report.cx, report.cy);
  std::cout << "dataset   " << report.dataset << " (" << report.frames << " frames, "
            << report.height << "x" << report.width << ")\n"
            << "camera    " << camera
            << (report.kitti ? " (calib_cam_to_cam of the first scene); metrics in metres, "
                               "pixels and percent\n"
                             : " (camera.json); metrics in its scene units\n");
  if (report.has_model) {
    std::cout << "model     " << report.model_path << " (" << report.model_name << ") at "
              << report.model_height << "x" << report.model_width << "\n";
    if (std::string notice = UntrainedNotice(report.model_path, report.model_training);
        !notice.empty()) {
      std::cout << notice << "\n";
    }
  }
  if (!report.camera_note.empty()) std::cout << "warning   " << report.camera_note << "\n";
  std::cout << "\n" << eval::FormatTable(report) << "\n";
  // FlowNet3D's absolute thresholds are for FlyingThings3D's scale: on slower data every
  // prediction, zero flow too, is within them. Said, not changed (the definitions stay).
  const double median = report.overall[1].Metrics().gt_median;
  if (report.thresholds == eval::Thresholds::kAbsolute && median < eval::kAcc05.epe_threshold) {
    std::cout << "note      the ground truth's median motion is " << FormatFloat(median)
              << " scene units per frame, below the absolute thresholds (ACC.05 "
              << FormatFloat(eval::kAcc05.epe_threshold) << ", ACC.10 "
              << FormatFloat(eval::kAcc10.epe_threshold) << ", outliers "
              << FormatFloat(eval::kOutliers.epe_threshold)
              << ") made for FlyingThings3D's scale: zero flow passes ACC.05 and ACC.10 on most "
                 "pixels whatever its error; --thresholds relative scores against |gt| only\n";
  }
}

Status WriteJson(const std::string& path, const eval::EvalReport& report) {
  const std::string json = eval::FormatJson(report);
  return io::WriteFileAtomically(
      path, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(json.data()), json.size()));
}

int RunEval(const EvalArgs& args) {
  eval::EvalOptions options;
  int code = kExitOk;
  if (std::string problem = OptionsFromArgs(args, &options, &code); !problem.empty()) {
    return ReportError(kName, problem, code);
  }
  ShardProgress progress(
      options.shard ? ShardName(options.shard->index, options.shard->count) : std::string(),
      args.quiet, args.json.empty() || !options.shard ? "" : args.json + ".status");
  Result<eval::EvalReport> report = eval::RunEvaluation(options, [&](const eval::EvalProgress& p) {
    progress.Update(p.done, p.total, p.frame ? p.frame->sequence + " frame " + p.frame->frame : "");
  });
  if (!report.ok()) {
    progress.Failed(report.message());
    return ReportError(kName, report.message(), kExitFailure);
  }
  PrintReport(*report);
  char done[96];
  std::snprintf(done, sizeof(done), "evaluated %d frames in %.1f s", report->frames,
                progress.seconds());
  std::cout << done << "\n";
  if (!args.json.empty()) {
    if (Status written = WriteJson(args.json, *report); !written.ok()) {
      return ReportError(kName, written.message(), kExitFailure);
    }
    std::cout << "wrote     " << args.json << "\n";
  }
  progress.Done(report->frames);
  return kExitOk;
}

struct MergeArgs {
  std::vector<std::string> inputs;
  std::string json;
};

// One shard's --json file or summary.json, parsed; errors name the file.
Result<eval::ShardFile> ReadShardFile(const std::string& path) {
  if (std::string problem = CheckInputFile(path, "shard result"); !problem.empty()) {
    return Status::Error(problem +
                         " (sfrt merge reads the --json files of sfrt eval --shard, and the "
                         "summary.json of sfrt run --shard or the --out folder holding them)");
  }
  std::ifstream in(path);
  eval::ShardFile shard{path, nlohmann::json::parse(in, nullptr, false)};
  if (shard.json.is_discarded()) return Status::Error(path + ": not a JSON file");
  return shard;
}

// sfrt merge of sfrt run --shard summaries: the single run's console summary and summary.json.
int MergeRuns(const std::vector<eval::ShardFile>& shards, const std::string& json_path) {
  Result<nlohmann::json> merged = MergeRunShards(shards);
  if (!merged.ok()) return ReportError("merge", merged.message(), kExitFailure);
  PrintRunResult((*merged)["source"].value("description", ""), ResultFromSummary(*merged));
  std::cout << "merged      " << shards.size()
            << " shard(s): " << (*merged)["frames"]["written"].get<int64_t>() << " frames of "
            << (*merged)["merged"]["units"].size() << " units, list "
            << (*merged)["merged"]["list_sha256"].get<std::string>().substr(0, 12) << "\n";
  if (!json_path.empty()) {
    const std::string text = merged->dump(2) + "\n";
    if (Status written = io::WriteFileAtomically(
            json_path,
            std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
        !written.ok()) {
      return ReportError("merge", written.message(), kExitFailure);
    }
    std::cout << "wrote       " << json_path << "\n";
  }
  return kExitOk;
}

int RunMerge(const MergeArgs& args) {
  if (!args.json.empty()) {
    if (std::string problem = CheckOutputFile(args.json, "--json"); !problem.empty()) {
      return ReportError("merge", problem, kExitFailure);
    }
  }
  std::vector<eval::ShardFile> shards;
  for (const std::string& input : args.inputs) {
    const std::vector<std::string> files = FindRunShardSummaries(input);
    if (files.empty()) {
      return ReportError("merge",
                         input + ": a folder without summary.json or shard-I-of-N/summary.json",
                         kExitFailure);
    }
    for (const std::string& path : files) {
      Result<eval::ShardFile> shard = ReadShardFile(path);
      if (!shard.ok()) return ReportError("merge", shard.message(), kExitFailure);
      shards.push_back(std::move(shard).value());
    }
  }
  const size_t runs = static_cast<size_t>(std::count_if(
      shards.begin(), shards.end(), [](const eval::ShardFile& s) { return IsRunSummary(s.json); }));
  if (runs > 0 && runs < shards.size()) {
    return ReportError("merge",
                       "the files mix sfrt run shards' summaries with sfrt eval shards' --json",
                       kExitFailure);
  }
  if (runs > 0) return MergeRuns(shards, args.json);
  Result<eval::EvalReport> merged = eval::MergeShards(shards);
  if (!merged.ok()) return ReportError("merge", merged.message(), kExitFailure);
  PrintReport(*merged);
  std::cout << "merged    " << shards.size() << " shard(s): " << merged->frames << " frames of "
            << merged->list.units.size() << " unit(s), list " << merged->list.sha256.substr(0, 12)
            << "\n";
  if (!args.json.empty()) {
    if (Status written = WriteJson(args.json, *merged); !written.ok()) {
      return ReportError("merge", written.message(), kExitFailure);
    }
    std::cout << "wrote     " << args.json << "\n";
  }
  return kExitOk;
}

// The FlyingThings3D conventions' lines of the help, from their table (eval/conventions.h).
std::string ConventionsHelp() {
  std::string conventions;
  for (const eval::Convention& c : eval::kConventions) {
    conventions +=
        "  " + std::string(c.key) + ": " + c.name + "\n      pixels with " + c.MaskWords() + ";";
    for (int s = 0; s < eval::kConventionShares; ++s) {
      conventions += std::string(s == 0 ? "" : ";") + "\n      " + eval::kShareRules[s].key +
                     " = " + c.shares[static_cast<size_t>(s)].Definition(c.relative_epsilon);
    }
    conventions += c.averaging == eval::Averaging::kPerFrame
                       ? ";\n      each frame's means averaged over the frames\n"
                       : ";\n      means over all kept pixels\n";
  }
  return conventions;
}

}  // namespace

Command AddMergeCommand(CLI::App& parent) {
  auto args = std::make_shared<MergeArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "merge", "Reduce the shards of a sharded sfrt eval or sfrt run to the single run's results");
  cmd->add_option("shards", args->inputs,
                  "Each shard's --json file (sfrt eval --shard I/N); or each shard's summary.json "
                  "or folder, or the --out holding the shard-I-of-N folders (sfrt run --shard)")
      ->required();
  cmd->add_option("--json", args->json,
                  "Also write the merged results as JSON: the keys and values of a single run's "
                  "--json or summary.json (replaced atomically)");
  cmd->footer(
      "Checks that all N shards of one work list are there, none twice, with one model (its\n"
      "SHA-256), sfrt version, ISA and option set (a refusal names the shard's file and the\n"
      "field), then merges each unit's raw sums and counts in the list's order, as a single run\n"
      "merges its sequences: every metric, count and median equals the single run's, and the\n"
      "tables are those sfrt eval prints.\n"
      "Shards of sfrt run: counters are summed, bad frames and skipped outputs listed in the\n"
      "dataset's order, and every percentile is computed again from all shards' latency samples\n"
      "(the percentiles of all their windows); wall_s is the shards' wall times summed and fps\n"
      "the frames over it, and \"merged\" lists each shard's folder, frames and wall time.\n"
      "Exit codes: 0 success, 1 failure (a refusal included), 2 usage error.");
  return Command{cmd, [args] { return RunMerge(*args); }};
}

Command AddEvalCommand(CLI::App& parent) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "eval", "Score scene flow against ground truth: a model, zero flow and a classical baseline");
  cmd->add_option("--model", args->model, "Model file (.sfrt); without it, baselines only");
  cmd->add_option("--dataset", args->dataset,
                  "Dataset root in the Scene Flow layout with camera.json (as sfrt synth "
                  "writes; one sfrt synth did not finish, without \"complete\": true, is refused), "
                  "or in KITTI Scene Flow 2015's (ROOT/training/image_2, disp_occ_0, ...; "
                  "detected)")
      ->required();
  cmd->add_option("--depth", args->depth,
                  "KITTI: the disparity at t the model's (and zero flow's) 3D flow is projected "
                  "with: gt (the dataset's, an oracle depth, so named in every result) or stereo "
                  "(the classical baseline's SGBM)")
      ->capture_default_str()
      ->check(CLI::IsMember({"gt", "stereo"}));
  cmd->add_option("--shard", args->shard,
                  "Evaluate shard I of N (I/N, 0-based) of the dataset's sorted units (sequences, "
                  "KITTI scenes; unit k to shard k mod N), or auto: the scheduler's index "
                  "(SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN of SLURM_ARRAY_TASK_COUNT, or "
                  "JOB_COMPLETION_INDEX of --shard-count). Needs --json: the shard's partial "
                  "results, which sfrt merge reduces to the single run's; progress also in "
                  "JSON.status");
  cmd->add_option("--shard-count", args->shard_count,
                  "--shard auto with JOB_COMPLETION_INDEX (Kubernetes Indexed Jobs set no count)");
  cmd->add_option("--write-submission", args->submission,
                  "KITTI: also write the model's predictions in the devkit's encodings to "
                  "DIR/disp_0, DIR/disp_1, DIR/flow (NNNNNN_10.png, 16-bit)");
  cmd->add_option("--json", args->json,
                  "Also write the results as JSON to this file (replaced atomically; a device "
                  "or FIFO such as /dev/stdout is written in place)");
  cmd->add_option("--size", args->size,
                  "Run the model at HxW (images resized, flow resized back; default: the size "
                  "a trained model records, as sfrt run chooses it, else the dataset's size)");
  cmd->add_option("--max-frames", args->max_frames, "Evaluate at most N frames (default: all)");
  cmd->add_flag("--no-classical", args->no_classical, "Skip the classical OpenCV baseline");
  cmd->add_flag("--quiet", args->quiet, "No progress lines");
  cmd->add_flag("--allow-camera-mismatch", args->allow_camera_mismatch,
                "Score a model on a dataset whose camera differs from its training camera "
                "(otherwise refused, exit 1); the output then carries a warning");
  cmd->add_option("--thresholds", args->thresholds,
                  "ACC.05, ACC.10 and outliers: 'absolute' (FlowNet3D's definitions below, for "
                  "FlyingThings3D's scale) or 'relative' (only the EPE/|gt| condition, whatever "
                  "the scene's scale; a robot's metres per frame are far below 0.05)")
      ->capture_default_str()
      ->check(CLI::IsMember({"absolute", "relative"}));
  // The share metrics' lines come from the table the metric itself applies (eval/metrics.h).
  std::string share_metrics;
  for (const eval::ShareRule& rule : eval::kShareRules) {
    char line[128];
    std::snprintf(line, sizeof(line), "  %-9s %s\n", rule.label, rule.Definition().c_str());
    share_metrics += line;
  }
  const std::string conventions = ConventionsHelp();
  cmd->footer(
      "Frames: DIR/frames_cleanpass/<seq>/{left,right}/NNNN.png with frame NNNN+1 present;\n"
      "ground truth DIR/scene_flow/<seq>/into_future/left/NNNN.pfm, or else computed from\n"
      "disparity, disparity_change and optical_flow with the spec's formula. Camera (f, B,\n"
      "cx, cy) from DIR/camera.json. Methods: sfrt (the model), zero_flow, classical\n"
      "(StereoSGBM disparity at t and t+1, DIS optical flow on the left images, d1 read\n"
      "bilinearly where the pixel moved, then Z = f B / d etc.).\n"
      "Camera check: the model sees the dataset's camera scaled to its input size (--size).\n"
      "When that focal length or the baseline differs from the model's training camera\n"
      "(stored in the model file) by more than " +
      std::to_string(static_cast<int>(eval::kCameraTolerance * 100 + 0.5)) +
      "%, eval refuses, exit 1, naming both, since\n"
      "the model's predictions would be in another camera's geometry and units; with\n"
      "--allow-camera-mismatch it runs and prints a warning.\n"
      "Metrics over pixels with finite ground truth, in the dataset's scene units:\n"
      "  EPE3D     mean |pred - gt|;  EPE_X/Y/Z mean |pred_c - gt_c|\n" +
      share_metrics +
      "(one of the two conditions is enough, as FlowNet3D's ACC and HPLFlowNet's outliers;\n"
      "with --thresholds relative only the EPE/|gt| one). When the ground truth's median motion\n"
      "is below 0.05 a note says the absolute thresholds do not suit the data's scale.\n"
      "Per sequence and overall. JSON: keys sfrt, zero_flow, classical, each with epe3d,\n"
      "epe_x, epe_y, epe_z, acc05, acc10, outliers, valid_pixels, frames and sequences;\n"
      "thresholds and gt_median_motion.\n"
      "FlyingThings3D conventions (Scene Flow layout; not changed by --thresholds): each method\n"
      "is also scored as these papers' code scores FlyingThings3D, over the pixels their mask\n"
      "keeps (depth = f B / disparity in scene units, from disparity/ and disparity_change/;\n"
      "2D flow from optical_flow/, px), overall, in a second table and in each method's JSON\n"
      "\"conventions\" (name, mask, available, epe3d, acc05, acc10, outliers: null where the\n"
      "paper has no such share, valid_pixels, frames); definitions.conventions words them:\n" +
      conventions +
      "A convention whose mask needs a file the dataset lacks is reported unavailable, naming\n"
      "the file. Not reproduced: the papers' occlusion masks (this layout has no occlusion\n"
      "maps) and their 8192-point samples (the mean over every kept pixel is their expectation).\n"
      "KITTI Scene Flow 2015 layout (detected): each scene's 3D flow is projected into\n"
      "disparities at t and t+1 and optical flow with the --depth disparity at t, filled as\n"
      "the devkit fills missing values, and scored as the devkit scores it: D1, D2, Fl and SF\n"
      "outliers (> 3 px and > 5%; SF: any of the three) on background, foreground and all\n"
      "pixels with ground truth, counts summed over the scenes; the classical baseline is\n"
      "projected with its own stereo. JSON: each method's \"kitti\" with d1, d2, fl, sf as\n"
      "{bg, fg, all} percent, the depth used and the raw counts; EPE3D etc. against the 3D flow\n"
      "the ground truth means (metres).\n"
      "Exit codes: 0 success, 1 runtime or input failure, 2 usage error.");
  return Command{cmd, [args] { return RunEval(*args); }};
}

}  // namespace sfrt::tools
