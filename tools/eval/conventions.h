// FlyingThings3D as the scene-flow papers score it: each paper's mask (which pixels count) and
// share rules, one row of kConventions each, so that a number `sfrt eval` prints can be set beside
// the paper's. The table is the only place a convention is defined: the accumulator, the JSON's
// "definitions", the console table and `sfrt eval --help` all read it.
//
// Read from the authors' code (repository @ commit: files):
//   flownet3d   xingyul/flownet3d @b15bcb0:
//   data_preprocessing/proc_dataset_gen_point_pairs_color.py
//               (points with depth at t < 35, max_cut = 35, depth = 1050 / disparity), evaluate.py
//               scene_flow_EPE_np (ACC 0.05: EPE <= 0.05 or EPE/|gt| <= 5%; ACC 0.1: <= 0.1 or
//               <= 10%; no outlier share; each frame's means, averaged over the frames)
//   hplflownet  laoreja/HPLFlowNet @bb5284f: evaluation_utils.py evaluate_3d (EPE3D; ACC3DS:
//               EPE < 0.05 or rel < 5%; ACC3DR: < 0.1 or < 10%; Outliers3D: EPE > 0.3 or
//               rel > 10%; rel = EPE / (|gt| + 1e-4)), transforms/transforms.py (DEPTH_THRESHOLD
//               35 on the point at t and at t+1), configs/test_ours_FlyingThings3D.yaml (batch 1:
//               each frame's means, averaged). The same rules score CamLiFlow's LiDAR-only tables
//               (MCG-NJU/CamLiFlow eval_things_noc_sf.py, eval_things_occ_sf.py) and most
//               point-cloud papers' "FT3D" columns.
//   camliflow   MCG-NJU/CamLiFlow @3bf1974: preprocess_flyingthings3d_subset.py (points with depth
//               at t < 35), eval_things.py (EPE3D; 5cm: EPE < 0.05; 10cm: EPE < 0.1; absolute only,
//               no outlier share; sums over all points of all frames)
//   raft3d      princeton-vl/RAFT-3D @877eb80: scripts/evaluation.py (MAX_DEPTH 250 on the depth
//               at t, MAX_FLOW 250 px on |2D optical flow|; EPE3D; 5cm: EPE < 0.05; 10cm:
//               EPE < 0.1; absolute only, no outlier share; sums over all kept pixels) and
//               data_readers/sceneflow.py (depth = 1050 / disparity)
// Depths are f B / disparity in the dataset's scene units (FlyingThings3D: B = 1, so 1050 / d as
// the papers compute it); the depth at t+1 is the same point's, f B / (d + disparity change); a
// pixel whose disparity is not positive has no depth and is dropped by every depth bound. The
// 2D flow bound is in pixels at the dataset's resolution (FlyingThings3D: 960x540).
//
// Not reproduced, and why:
//   - The papers' occlusion masks: HPLFlowNet keeps only non-occluded points (the FlyingThings3D
//     subset's disparity_occlusions and flow_occlusions), CamLiFlow also reports non-occluded
//     numbers, FlowNet3D scores only points whose match is in view and not hidden at t+1, and
//     RAFT-3D's second table ("FlowNet3D evaluation") uses FlowNet3D's sampled points. The Scene
//     Flow layout `sfrt eval` reads has no occlusion maps, so every kept pixel counts here.
//   - Sampling 8,192 points per frame (FlowNet3D, HPLFlowNet, CamLiFlow): a uniform sample of the
//     same mask, whose expectation is the mean over all of the mask's pixels used here. FlowNet3D
//     also drops frames with fewer than 8,192 such points; here a frame counts when its mask keeps
//     at least one pixel.
// Pixels with non-finite ground truth are skipped; a non-finite prediction is an infinite error,
// as in eval/metrics.h.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "sfrt/status.h"

namespace sfrt::eval {

// The per-pixel quantities a mask may bound (each H*W doubles of one frame).
enum class MaskInput { kDepth, kNextDepth, kFlow2d };
inline constexpr int kMaskInputs = 3;
// How the masks' words and the reasons name them.
inline constexpr std::array<const char*, kMaskInputs> kMaskInputNames = {
    "depth at t", "depth at t+1", "|2D optical flow|"};
inline constexpr std::array<const char*, kMaskInputs> kMaskInputUnits = {"", "", " px"};

// One frame's mask inputs: values[i] is H*W doubles, or nullptr where the dataset has not got
// them, with missing[i] saying why ("no disparity/0000/left/0003.pfm").
struct MaskInputs {
  std::array<const double*, kMaskInputs> values{};
  std::array<std::string, kMaskInputs> missing{};
};

// A share's comparison: EPE (or the relative error) below, at most, or above the threshold.
enum class Compare { kBelow, kAtMost, kAbove };

// One share as a paper counts it. column == nullptr: the paper reports no such share (null in
// the JSON). relative == 0: the absolute condition alone; otherwise either condition is enough.
struct ShareTest {
  const char* column = nullptr;  // the paper's column name, e.g. "ACC3DS"
  Compare compare = Compare::kBelow;
  double epe = 0;       // absolute threshold, scene units
  double relative = 0;  // threshold on EPE / (|gt| + relative_epsilon); 0: none

  bool Counts(double epe_value, double relative_value) const;
  // "EPE < 0.05 or EPE/(|gt|+0.0001) < 5%"; "not reported" without a column.
  std::string Definition(double relative_epsilon) const;
};

// Means over all kept pixels of all frames, or each frame's means averaged over the frames.
enum class Averaging { kPerPixel, kPerFrame };

// The shares in the order of eval/metrics.h's kShareRules (keys acc05, acc10, outliers).
inline constexpr int kConventionShares = 3;

struct Convention {
  const char* key;     // JSON key
  const char* name;    // who defined it
  const char* source;  // where the definition was read
  // A pixel is kept when each bounded input is finite and below its bound (0: not bounded).
  std::array<double, kMaskInputs> below;
  double relative_epsilon;  // relative error = EPE / (|gt| + relative_epsilon)
  Averaging averaging;
  std::array<ShareTest, kConventionShares> shares;

  bool Needs(MaskInput input) const { return below[static_cast<int>(input)] > 0; }
  // "depth at t < 35 and depth at t+1 < 35" ("every pixel" without a bound).
  std::string MaskWords() const;
  // The whole definition in words: the mask, each share with its paper's column, the averaging,
  // the source.
  std::string Definition() const;
};

inline constexpr Convention kConventions[] = {
    {"flownet3d",
     "FlowNet3D (Liu et al., CVPR 2019)",
     "xingyul/flownet3d evaluate.py, data_preprocessing/proc_dataset_gen_point_pairs_color.py",
     {35, 0, 0},
     0.0,
     Averaging::kPerFrame,
     {{{"ACC(0.05)", Compare::kAtMost, 0.05, 0.05}, {"ACC(0.1)", Compare::kAtMost, 0.1, 0.1}, {}}}},
    {"hplflownet",
     "HPLFlowNet (Gu et al., CVPR 2019; also CamLiFlow's LiDAR-only tables)",
     "laoreja/HPLFlowNet evaluation_utils.py, transforms/transforms.py",
     {35, 35, 0},
     1e-4,
     Averaging::kPerFrame,
     {{{"ACC3DS", Compare::kBelow, 0.05, 0.05},
       {"ACC3DR", Compare::kBelow, 0.1, 0.1},
       {"Outliers3D", Compare::kAbove, 0.3, 0.1}}}},
    {"camliflow",
     "CamLiFlow / CamLiRAFT (Liu et al., CVPR 2022, TPAMI 2023)",
     "MCG-NJU/CamLiFlow eval_things.py, preprocess_flyingthings3d_subset.py",
     {35, 0, 0},
     0.0,
     Averaging::kPerPixel,
     {{{"ACC(5cm)", Compare::kBelow, 0.05, 0}, {"ACC(10cm)", Compare::kBelow, 0.1, 0}, {}}}},
    {"raft3d",
     "RAFT-3D (Teed and Deng, CVPR 2021)",
     "princeton-vl/RAFT-3D scripts/evaluation.py",
     {250, 0, 250},
     0.0,
     Averaging::kPerPixel,
     {{{"ACC(5cm)", Compare::kBelow, 0.05, 0}, {"ACC(10cm)", Compare::kBelow, 0.1, 0}, {}}}},
};
inline constexpr int kConventionCount = static_cast<int>(std::size(kConventions));

// One convention's results. available == false: the dataset lacks an input its mask needs
// (`unavailable` says which file); the numbers are then meaningless (0).
struct ConventionMetrics {
  bool available = true;
  std::string unavailable;
  double epe3d = 0;
  std::array<double, kConventionShares> shares{};  // acc05, acc10, outliers
  uint64_t valid_pixels = 0;                       // pixels the mask kept, with finite ground truth
  uint64_t frames = 0;                             // frames in which it kept at least one
};

// One convention's sums over any number of frames: Add() once per frame.
class ConventionAccumulator {
 public:
  ConventionAccumulator() = default;
  explicit ConventionAccumulator(int convention) : convention_(convention) {}
  const Convention& convention() const { return kConventions[convention_]; }
  // pred, truth: pixels * 3 floats; pred == nullptr means zero flow. A missing input the mask
  // needs makes the convention unavailable (for good: a number over some frames would not
  // compare with the paper's).
  void Add(const float* pred, const float* truth, const MaskInputs& inputs, size_t pixels);
  void MarkUnavailable(const std::string& reason);
  // The first unavailable reason wins (merged in list order, as every run merges).
  void Merge(const ConventionAccumulator& other);
  ConventionMetrics Metrics() const;
  // Raw sums and counts for a shard's partial result (doubles as hexadecimal floats), or
  // {"unavailable": reason}.
  nlohmann::json State() const;
  static Result<ConventionAccumulator> FromState(const nlohmann::json& state, int convention);

 private:
  bool Keeps(const MaskInputs& inputs, size_t pixel) const;

  int convention_ = 0;  // its row of kConventions
  std::string unavailable_;
  // Over all kept pixels.
  double sum_epe_ = 0;
  std::array<uint64_t, kConventionShares> counts_{};
  uint64_t pixels_ = 0;
  // Over frames: the sums of each frame's mean EPE and shares, and the frames with a kept pixel.
  double frame_epe_ = 0;
  std::array<double, kConventionShares> frame_shares_{};
  uint64_t frames_ = 0;
};

// Every convention's accumulator, in kConventions' order.
class ConventionSet {
 public:
  ConventionSet();
  void Add(const float* pred, const float* truth, const MaskInputs& inputs, size_t pixels);
  void Merge(const ConventionSet& other);
  const ConventionAccumulator& operator[](int c) const { return rows_[static_cast<size_t>(c)]; }
  // {"<key>": ConventionAccumulator::State(), ...}; FromState refuses a missing or malformed
  // row, naming it.
  nlohmann::json State() const;
  static Result<ConventionSet> FromState(const nlohmann::json& state);

 private:
  std::array<ConventionAccumulator, kConventionCount> rows_;
};

}  // namespace sfrt::eval
