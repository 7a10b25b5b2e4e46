// `sfrt eval`: scene-flow accuracy of a model and two baselines over a dataset tree with ground
// truth, in the layout of the Scene Flow datasets (tools/synth/dataset.h):
//
//   DIR/camera.json                                    focal, baseline, cx, cy (sfrt synth)
//   DIR/frames_cleanpass/<seq>/{left,right}/NNNN.png   a frame is evaluated when NNNN+1 exists
//   DIR/scene_flow/<seq>/into_future/left/NNNN.pfm     ground truth (dX, dY, dZ), or else built
//       from disparity/, disparity_change/ and optical_flow/ with the spec's formula
//       (synth::ComputeSceneFlow, ConventionKind::kFormula)
//
// Methods, all scored against the same ground truth with eval/metrics.h:
//   sfrt       the model, fed the four images as its metadata prescribes (image order, colour
//              order, scale/mean/std); with a model size other than the dataset's, the images
//              are resized (INTER_AREA shrinking, else INTER_LINEAR) and the predicted flow is
//              resized back bilinearly (its values are 3D displacements: not rescaled)
//   zero_flow  (0, 0, 0) everywhere: its mean EPE is the mean ground-truth magnitude
//   classical  eval/classical.h at the dataset's resolution, with the dataset's camera
//
// Beside the metrics over every pixel, each method is scored under the FlyingThings3D papers'
// conventions (eval/conventions.h: their masks of depth and 2D flow magnitude, their share rules),
// from the dataset's disparity/, disparity_change/ and optical_flow/ where it has them; a
// convention whose mask needs a file the dataset lacks is reported unavailable, with the reason.
#pragma once

#include <array>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "eval/conventions.h"
#include "eval/kitti.h"
#include "eval/metrics.h"
#include "eval/shard_spec.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/session.h"
#include "sfrt/status.h"

namespace sfrt::eval {

inline constexpr const char* kMethodNames[] = {"sfrt", "zero_flow", "classical"};
inline constexpr int kMethodCount = 3;

// How far the dataset's camera may be from the model's training camera (focal length at the
// model's input size, and baseline; relative) before RunEvaluation refuses the pair.
inline constexpr double kCameraTolerance = 0.05;

// Where the disparity at t comes from when a 3D flow is scored on KITTI (its metrics are in
// disparities and pixels: eval/kitti.h): the dataset's ground truth (an oracle depth, named so in
// every result) or sfrt's classical stereo (eval/classical.h).
enum class DepthSource { kGroundTruth, kStereo };
inline constexpr std::array<const char*, 2> kDepthSourceNames = {"gt", "stereo"};

// The units of a dataset (sequences, KITTI scenes), sorted, and the SHA-256 of their names.
struct WorkList {
  std::vector<std::string> units;
  std::string sha256;
};

struct EvalOptions {
  std::string model_path;  // .sfrt; empty: baselines only (unless `model` is set)
  // A model already loaded (the Python package's); model_path then only names it in the report.
  std::shared_ptr<const Model> model;
  std::string dataset;
  int model_height = 0;  // 0: the dataset's size
  int model_width = 0;
  int max_frames = 0;  // 0: all
  bool classical = true;
  Isa isa = Isa::kAuto;  // the model's session
  KernelTuning tuning{};
  // A dataset camera more than kCameraTolerance from the model's training camera: false fails
  // (naming both cameras), true evaluates anyway with EvalReport::camera_note saying so.
  bool allow_camera_mismatch = false;
  // The share metrics' conditions (metrics.h): FlowNet3D's (absolute or relative) or relative only.
  Thresholds thresholds = Thresholds::kAbsolute;
  // KITTI layout only: the depth the model's and zero flow's 3D flow is projected with, and a
  // folder to write the model's predictions to in the devkit's encodings (disp_0/, disp_1/,
  // flow/; "" = none).
  DepthSource depth = DepthSource::kGroundTruth;
  std::string submission_dir;
  // Evaluate only this shard's units and add the partial results (eval/shards.h) to the report.
  std::optional<ShardSpec> shard;
};

// The model input size without --size, as `sfrt run` chooses it: the size a trained model
// records (its training camera's focal length is for that size) into *height, *width; nothing
// changes otherwise (0 x 0: the dataset's size).
void DefaultModelSize(const ModelMetadata& meta, int* height, int* width);

struct FrameRef {
  std::string sequence;
  std::string frame;       // "NNNN"
  std::string next_frame;  // "NNNN+1"
};

struct SequenceResult {
  std::string name;
  int frames = 0;
  MetricsAccumulator methods[kMethodCount];
  KittiCounts kitti[kMethodCount];  // the KITTI layout's counts (a sequence is one scene there)
  ConventionSet conventions[kMethodCount];  // the Scene Flow layout's (eval/conventions.h)
};

struct EvalReport {
  std::string dataset;
  std::string model_path;
  std::string model_name;
  double focal = 0, baseline = 0, cx = 0, cy = 0;  // the dataset's camera
  std::string camera_note;  // with allow_camera_mismatch: why the cameras differ, else empty
  TrainingState model_training = TrainingState::kUnknown;
  int height = 0, width = 0;              // the dataset's image size
  int model_height = 0, model_width = 0;  // what the model ran at
  int frames = 0;
  bool has_model = false;
  bool has_classical = false;
  std::vector<SequenceResult> sequences;
  Thresholds thresholds = Thresholds::kAbsolute;
  MetricsAccumulator overall[kMethodCount];
  ConventionSet conventions[kMethodCount];  // overall, per method (not for the KITTI layout)
  // The KITTI layout (eval/kitti_eval.h): its outlier counts per method, and the depth the model's
  // and zero flow's 3D flow was projected with (the classical baseline uses its own stereo).
  bool kitti = false;
  DepthSource depth = DepthSource::kGroundTruth;
  KittiCounts kitti_counts[kMethodCount];
  // A sharded evaluation (eval/shards.h): the whole list, this shard, and what the numbers
  // depend on.
  WorkList list;
  std::optional<ShardSpec> shard;
  std::string model_sha256;
  std::string isa;      // the session's ISA; "" when no frame ran
  std::string options;  // JSON object of the options that change the numbers
};

struct EvalProgress {
  int done = 0;
  int total = 0;
  const FrameRef* frame = nullptr;
};

// Frames of `root` that have both images at t and t+1 and ground truth (or its inputs) at t,
// sorted by sequence and frame. Fails when there are none (naming what is missing).
Result<std::vector<FrameRef>> ListEvalFrames(const std::string& root);

// Ground-truth scene flow of one frame (H*W*3), from scene_flow/ or computed.
Result<std::vector<float>> LoadGroundTruth(const std::string& root, const FrameRef& frame,
                                           double focal, double baseline, double cx, double cy,
                                           int* height, int* width);

// The conventions' mask inputs of one frame (eval/conventions.h), H*W doubles each: the depth at
// t, f B / d from disparity/<seq>/left/NNNN.pfm (+infinity where d <= 0); the same point's depth
// at t+1, f B / (d + change) with disparity_change/; |(u, v)| from optical_flow/. An input whose
// file is not there is left empty with `missing` naming the file (relative to the root); a file
// that is there but unreadable, or not height x width, fails.
struct FrameMasks {
  std::array<std::vector<double>, kMaskInputs> values;
  std::array<std::string, kMaskInputs> missing;
  MaskInputs View() const;
};
Result<FrameMasks> LoadMaskInputs(const std::string& root, const FrameRef& frame, double focal,
                                  double baseline, int height, int width);

// A report with what the options set, before any frame (every evaluation starts from it).
EvalReport NewReport(const EvalOptions& options);
// The overall results: the sequences' accumulators and KITTI counts merged in their order (as
// a single run and sfrt merge both do, so the sums are the same bit for bit).
void MergeSequences(EvalReport* report);

Result<EvalReport> RunEvaluation(const EvalOptions& options,
                                 const std::function<void(const EvalProgress&)>& progress = {});

// The report as a table (per sequence and overall, one row per method), and for the Scene Flow
// layout a second one: each convention's metrics per method (or why it is unavailable).
std::string FormatTable(const EvalReport& report);

// The report as JSON: top-level keys "sfrt" (only with a model), "zero_flow", "classical"
// (unless disabled), each {"epe3d", "epe_x", "epe_y", "epe_z", "acc05", "acc10", "outliers",
// "valid_pixels", "frames", "sequences": {"<seq>": {the same metrics}}}, plus "dataset",
// "model", "camera", "image_size", "model_size", "frames", "units", "definitions", "thresholds"
// ("absolute" or "relative") and "gt_median_motion" (the ground truth's median |g|).
// The Scene Flow layout adds, per method, "conventions": {"<key>": {"name", "mask" (words),
// "available", "reason" (only when unavailable), "epe3d", "acc05", "acc10", "outliers" (null
// where the paper reports no such share, all null when unavailable), "valid_pixels", "frames"}}
// (overall only), and "definitions"."conventions": {"<key>": the definition in words}.
std::string FormatJson(const EvalReport& report);

}  // namespace sfrt::eval
