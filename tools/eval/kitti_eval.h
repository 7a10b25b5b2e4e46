// `sfrt eval` on the KITTI Scene Flow 2015 layout (eval/kitti.h: files, encodings, metrics).
//
// Every scene NNNNNN of training/ (or of the root itself) with image_2 and image_3 at _10 and _11,
// disp_occ_0, disp_occ_1, flow_occ and calib_cam_to_cam/NNNNNN.txt (obj_map optional: without
// it every pixel is background) is scored for three methods:
//   sfrt       the model's 3D flow (at the model size, resized back), projected into disparities
//              at t and t+1 and optical flow with the disparity at t of EvalOptions::depth: the
//              ground truth ("gt", an oracle depth: its D1 is 0 by construction where the ground
//              truth has a value) or the classical stereo ("stereo")
//   zero_flow  no motion, projected the same way (d1 = d0, no optical flow)
//   classical  eval/classical.h's scene flow, projected with its own stereo disparity
// Each estimate is filled as the devkit fills missing values, then D1, D2, Fl and SF are counted
// (background, foreground, all). Beside them, the EPE metrics of metrics.h against the 3D flow
// the ground truth means (KittiGroundTruthSceneFlow), in metres.
#pragma once

#include <functional>
#include <string>

#include "eval/evaluate.h"

namespace sfrt::eval {

// Whether `root` (or root/training) holds the KITTI layout (an image_2 and a disp_occ_0 folder).
bool IsKittiLayout(const std::string& root);

Result<EvalReport> RunKittiEvaluation(const EvalOptions& options,
                                      const std::function<void(const EvalProgress&)>& progress);

// The "kitti" object of one method in the JSON: d1, d2, fl and sf, each {"bg", "fg", "all"} in
// percent, and the raw counts ("pixels" and "outliers", each per map [bg, fg]).
std::string KittiJson(const KittiCounts& counts, const std::string& depth,
                      const std::string& indent);

// The table of the KITTI metrics, one row per method.
std::string FormatKittiTable(const EvalReport& report);

// What each method's projection used, as the JSON and the table name it: "gt (oracle)",
// "stereo", "stereo (its own)".
std::string DepthLabel(const EvalReport& report, int method);

}  // namespace sfrt::eval
