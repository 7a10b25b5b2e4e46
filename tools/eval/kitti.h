// KITTI Scene Flow 2015: its files and its metrics, as the benchmark's own devkit defines them
// (devkit_scene_flow: readme.txt, io_disp.h, io_flow.h, evaluate_scene_flow.cpp).
//
// Files (training/ of the benchmark; `sfrt synth --layout kitti` writes the same layout):
//   image_2/NNNNNN_10.png, _11.png   left images at t and t+1;  image_3/: the right ones
//   disp_occ_0/NNNNNN_10.png          disparity at t, pixels of the left image at t
//   disp_occ_1/NNNNNN_10.png          disparity at t+1 of the same points, on the grid of t
//   flow_occ/NNNNNN_10.png            optical flow t -> t+1 of the left image
//   obj_map/NNNNNN_10.png             0: background, > 0: a foreground object (8-bit)
//   calib_cam_to_cam/NNNNNN.txt       P_rect_02 and P_rect_03 (3x4, row-major)
// Encodings: a disparity PNG is uint16 grey, d = v / 256, v = 0 no value; a flow PNG is 16-bit
// RGB, u = (R - 2^15) / 64, v = (G - 2^15) / 64, valid where B > 0 (OpenCV reads it as BGR).
// Camera: f = P_rect_02(0,0), cx = P_rect_02(0,2), cy = P_rect_02(1,2), baseline =
// (P_rect_02(0,3) - P_rect_03(0,3)) / f (metres).
//
// Metrics: a disparity is an outlier when |d - d_gt| > 3 px AND |d - d_gt| / |d_gt| > 5%; a flow
// vector when |f - f_gt| > 3 px AND |f - f_gt| / |f_gt| > 5%. D1 (disparity at t), D2 (at t+1)
// and Fl (flow) count the pixels where their ground truth has a value; SF counts the pixels where
// all three have one, an outlier where any of the three is. Background (obj_map 0), foreground
// (> 0) and all; the counts are summed over every scene and then divided (not averaged per
// scene). An estimate without a value at a pixel is first filled as the devkit fills it
// (InterpolateBackground).
#pragma once

#include <array>
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>
#include <string>

#include "eval/classical.h"
#include "sfrt/status.h"

namespace sfrt::eval {

// A disparity map: CV_32F, pixels; a pixel without a value holds kNoDisparity.
inline constexpr float kNoDisparity = -1.0f;
// A flow map: CV_32FC3 (u, v, valid 0 or 1).

Result<cv::Mat> ReadKittiDisparity(const std::string& path);
Status WriteKittiDisparity(const std::string& path, const cv::Mat& disparity);
Result<cv::Mat> ReadKittiFlow(const std::string& path);
Status WriteKittiFlow(const std::string& path, const cv::Mat& flow);
// CV_8U.
Result<cv::Mat> ReadKittiObjectMap(const std::string& path);
// f, cx, cy and the baseline from calib_cam_to_cam/NNNNNN.txt; errors name the file and key.
Result<PinholeStereo> ReadKittiCalibration(const std::string& path);
Status WriteKittiCalibration(const std::string& path, const PinholeStereo& camera);

// Fills the pixels without a value as the devkit does before scoring: along each row, a gap
// between two values takes the smaller of them and the row's ends the nearest value; then along
// each column, the ends the nearest value. Disparity: in place. Flow: u and v each, and the
// filled pixels become valid.
void InterpolateDisparity(cv::Mat* disparity);
void InterpolateFlow(cv::Mat* flow);

// The disparity at t and t+1 (on the grid of t) and the optical flow a 3D flow means, given the
// disparity at t: per pixel (x, y) with d0 > 0 and a finite flow,
//   Z0 = f B / d0, X0 = (x - cx) Z0 / f, Y0 = (y - cy) Z0 / f;  P1 = P0 + flow
//   d1 = f B / Z1,  u = f X1 / Z1 + cx - x,  v = f Y1 / Z1 + cy - y
// (no value where d0 <= 0, the flow is not finite, or Z1 <= 0).
struct KittiEstimate {
  cv::Mat disparity0;  // CV_32F
  cv::Mat disparity1;  // CV_32F
  cv::Mat flow;        // CV_32FC3
};
KittiEstimate ProjectSceneFlow(const cv::Mat& disparity0, const float* scene_flow,
                               const PinholeStereo& camera);
// The estimate as a submission holds it and the devkit reads it back: every value through its
// PNG encoding (disparity truncated to 1/256 px and at least 1/256, flow truncated to 1/64 px,
// both clamped to the 16-bit range). sfrt eval scores this, so its counts are the devkit's on
// the files --write-submission writes.
KittiEstimate AsSubmitted(const KittiEstimate& estimate);

// The 3D scene flow the ground truth means (for EPE3D beside the KITTI metrics): P0 from d0 at
// (x, y), P1 from d1 at (x + u, y + v); NaN where any of the three has no value.
std::vector<float> KittiGroundTruthSceneFlow(const cv::Mat& disparity0, const cv::Mat& disparity1,
                                             const cv::Mat& flow, const PinholeStereo& camera);

enum class KittiMap { kD1, kD2, kFl, kSf };
inline constexpr int kKittiMaps = 4;
inline constexpr std::array<const char*, kKittiMaps> kKittiMapNames = {"d1", "d2", "fl", "sf"};
enum class KittiRegion { kBackground, kForeground };

// Outlier and pixel counts, exact integers, so that sums over scenes (and over shards) are exact.
class KittiCounts {
 public:
  // One scene: the ground truth (disparity at t and t+1, flow, object map) and the estimate
  // (filled already, InterpolateDisparity/InterpolateFlow).
  void Add(const cv::Mat& gt_d0, const cv::Mat& gt_d1, const cv::Mat& gt_flow,
           const cv::Mat& object_map, const KittiEstimate& estimate);
  void Merge(const KittiCounts& other);
  // Percent of outliers of `map` in the background, foreground or both (0 without pixels).
  double Percent(KittiMap map, KittiRegion region) const;
  double PercentAll(KittiMap map) const;
  uint64_t pixels(KittiMap map, KittiRegion region) const;
  uint64_t outliers(KittiMap map, KittiRegion region) const;
  // The counts as {"pixels": [[bg, fg] per map], "outliers": [...]}, for a shard's partial result.
  nlohmann::json State() const;
  static Result<KittiCounts> FromState(const nlohmann::json& state);

 private:
  std::array<std::array<uint64_t, 2>, kKittiMaps> pixels_{};
  std::array<std::array<uint64_t, 2>, kKittiMaps> outliers_{};
};

// The devkit's outlier test for a disparity error and for a flow error.
bool DisparityOutlier(float estimate, float truth);
bool FlowOutlier(float du, float dv, float truth_u, float truth_v);

}  // namespace sfrt::eval
