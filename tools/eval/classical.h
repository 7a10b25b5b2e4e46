// The classical scene-flow baseline of `sfrt eval`: OpenCV stereo and optical flow combined with
// SceneEDNet's ground-truth geometry (docs: "Ground truth").
//
//   1. Disparity at t and at t+1: cv::StereoSGBM on the grey left/right images (block 5,
//      P1 = 8*3*5^2, P2 = 32*3*5^2, uniqueness 10, speckle window 100 / range 2, MODE_SGBM,
//      numDisparities = the width / 4 rounded up to a multiple of 16, at most 256).
//      Pixels SGBM leaves without a disparity (occlusions, the left border) are filled along
//      their row with the smaller of the nearest valid disparities to their left and right
//      (the background side: occluded pixels lie behind their neighbours).
//   2. Optical flow left(t) -> left(t+1): cv::DISOpticalFlow, PRESET_MEDIUM, on grey images.
//   3. Per pixel (col, row): d0 = D0(col, row), (u, v) = flow, d1 = D1 read bilinearly at
//      (col + u, row + v) (where the point moved). If (col + u, row + v) falls outside the image
//      d1 = d0 (no depth change assumed). Then, with the dataset's camera:
//        Z0 = f B / d0, X0 = (col - cx) Z0 / f, Y0 = (row - cy) Z0 / f
//        Z1 = f B / d1, X1 = (col + u - cx) Z1 / f, Y1 = (row + v - cy) Z1 / f
//        flow = (X1 - X0, Y1 - Y0, Z1 - Z0)
//      A pixel whose d0 or d1 is not positive (no valid disparity on its row at all) gets zero
//      flow, so the baseline is dense like the network's output.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

namespace sfrt::eval {

struct PinholeStereo {
  double focal = 1050;  // px
  double baseline = 1;  // scene units
  double cx = 479.5;
  double cy = 269.5;
};

// Dense disparity (CV_32F, px; <= 0 where none could be found on the whole row) of a rectified
// BGR pair, per step 1 above.
cv::Mat ClassicalDisparity(const cv::Mat& left_bgr, const cv::Mat& right_bgr);

// Optical flow (CV_32FC2, px) from `from_bgr` to `to_bgr`, per step 2 above.
cv::Mat ClassicalOpticalFlow(const cv::Mat& from_bgr, const cv::Mat& to_bgr);

// Scene flow (rows * cols * 3 floats, x y z interleaved) from disparity at t, disparity at t+1
// and optical flow t -> t+1, per step 3 above.
std::vector<float> SceneFlowFromStereoAndFlow(const cv::Mat& disparity0, const cv::Mat& disparity1,
                                              const cv::Mat& flow, const PinholeStereo& camera);

// Steps 1-3 on four BGR 8-bit images of the same size.
std::vector<float> ClassicalSceneFlow(const cv::Mat& left0, const cv::Mat& right0,
                                      const cv::Mat& left1, const cv::Mat& right1,
                                      const PinholeStereo& camera);

}  // namespace sfrt::eval
