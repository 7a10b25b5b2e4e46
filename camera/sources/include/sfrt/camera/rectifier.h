// Stereo rectification and resizing to the model input size, with maps built once.
//
// Create() runs cv::stereoRectify (CALIB_ZERO_DISPARITY, so both rectified cameras share cx, cy)
// and cv::initUndistortRectifyMap once. The resize to the model's input size is folded into the
// maps: the rectified projection P is pre-multiplied by the pixel-centre scaling
// S = [sx 0 (sx-1)/2; 0 sy (sy-1)/2; 0 0 1] (sx = out_w / in_w), so one cv::remap per image does
// undistortion, rectification and resizing. When the output is less than half the input in either
// direction, bilinear remap would alias, so Apply() remaps at full size into a buffer made at
// Create() and then shrinks with INTER_AREA (same S, same reported camera).
//
// camera() reports the rectified camera at the output size, for comparison with the model's
// training camera (sfrt::CameraDesc: focal_px, baseline, cx, cy).
//
// Ownership: the rectifier owns its maps (and the intermediate buffer). Apply() writes into the
// caller's images; once they have the output size and type CV_8UC3 no image is reallocated.
// Thread-safety: Apply() is const with respect to the maps but uses the intermediate buffer, so
// call one rectifier from one thread at a time (make one per thread).
// Errors: Create() and Apply() return a one-line Status naming the size or value at fault.
#pragma once

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "sfrt/camera/calibration.h"
#include "sfrt/camera/status.h"

namespace sfrt::camera {

struct RectifyOptions {
  cv::Size output_size;  // width x height fed to the model; 0x0 = keep the input size
  // cv::stereoRectify free scaling: 0 keeps only valid pixels (zooms in), 1 keeps every source
  // pixel (black borders), -1 lets OpenCV choose.
  double alpha = 0;
  int interpolation = cv::INTER_LINEAR;
};

struct RectifiedCamera {
  cv::Size size;  // output size (width x height)
  double fx = 0;  // rectified focal length in output pixels (0: unknown, resize-only)
  double fy = 0;  // differs from fx only when the resize changes the aspect ratio
  double cx = 0;  // principal point in output pixels (shared by both views)
  double cy = 0;
  double baseline = 0;  // distance between the rectified cameras, in the calibration's unit
};

class StereoRectifier {
 public:
  // input_size: the raw frame size. If the calibration names an image size, they must match.
  static Result<StereoRectifier> Create(const StereoCalibration& calibration, cv::Size input_size,
                                        const RectifyOptions& options);
  // For sources that are already rectified (the Scene Flow datasets, KITTI): resize only, with
  // INTER_AREA when shrinking and INTER_LINEAR when enlarging. camera() reports fx = fy = 0.
  static Result<StereoRectifier> CreateResizeOnly(cv::Size input_size, cv::Size output_size);

  // left, right: CV_8UC3 of input_size. Writes CV_8UC3 images of the output size.
  Status Apply(const cv::Mat& left, const cv::Mat& right, cv::Mat* out_left, cv::Mat* out_right);

  const RectifiedCamera& camera() const { return camera_; }
  cv::Size input_size() const { return input_size_; }
  // Rectified projection matrices at the output size (P2(0,3) = -fx * baseline) and the
  // rectifying rotations (raw camera -> rectified camera). Identity/zero for resize-only.
  const cv::Matx34d& P1() const { return p1_; }
  const cv::Matx34d& P2() const { return p2_; }
  const cv::Matx33d& R1() const { return r1_; }
  const cv::Matx33d& R2() const { return r2_; }

 private:
  StereoRectifier() = default;
  Status ApplyOne(const cv::Mat& in, const cv::Mat& map1, const cv::Mat& map2, cv::Mat* out,
                  const char* side);

  cv::Size input_size_;
  cv::Size output_size_;
  bool resize_only_ = false;
  bool two_stage_ = false;  // remap at input size, then INTER_AREA shrink
  int interpolation_ = cv::INTER_LINEAR;
  cv::Mat map1_left_, map2_left_, map1_right_, map2_right_;
  cv::Mat full_size_;  // two-stage intermediate
  RectifiedCamera camera_;
  cv::Matx34d p1_ = cv::Matx34d::eye();
  cv::Matx34d p2_ = cv::Matx34d::eye();
  cv::Matx33d r1_ = cv::Matx33d::eye();
  cv::Matx33d r2_ = cv::Matx33d::eye();
};

}  // namespace sfrt::camera
