#include "sfrt/camera/rectifier.h"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <string>

namespace sfrt::camera {
namespace {

std::string SizeText(cv::Size s) {
  return std::to_string(s.height) + "x" + std::to_string(s.width);
}

Status CheckSizes(cv::Size input, cv::Size output) {
  if (input.width < 2 || input.height < 2) {
    return Status::Error("rectifier: input size " + SizeText(input) + " (HxW) is too small");
  }
  if (output.width < 2 || output.height < 2 || output.width > 16384 || output.height > 16384) {
    return Status::Error("rectifier: output size " + SizeText(output) +
                         " (HxW) is outside 2..16384");
  }
  return Status::Ok();
}

// Pixel-centre scaling from input to output pixels.
cv::Matx33d ScaleMatrix(cv::Size in, cv::Size out) {
  const double sx = static_cast<double>(out.width) / in.width;
  const double sy = static_cast<double>(out.height) / in.height;
  return cv::Matx33d(sx, 0, 0.5 * (sx - 1), 0, sy, 0.5 * (sy - 1), 0, 0, 1);
}

}  // namespace

Result<StereoRectifier> StereoRectifier::Create(const StereoCalibration& calibration,
                                                cv::Size input_size,
                                                const RectifyOptions& options) {
  const cv::Size output = options.output_size.area() > 0 ? options.output_size : input_size;
  if (Status s = CheckSizes(input_size, output); !s.ok()) return s;
  if (calibration.image_size.area() > 0 && calibration.image_size != input_size) {
    return Status::Error(calibration.source + ": calibrated image size " +
                         SizeText(calibration.image_size) + " differs from the frame size " +
                         SizeText(input_size) + " (HxW); recalibrate at the capture resolution");
  }
  if (!(options.alpha == -1 || (options.alpha >= 0 && options.alpha <= 1))) {
    return Status::Error("rectifier: alpha " + std::to_string(options.alpha) +
                         " is not -1 or within [0, 1]");
  }
  if (cv::norm(calibration.T) == 0) {
    return Status::Error(calibration.source + ": translation T is zero; no stereo baseline");
  }
  StereoRectifier r;
  r.input_size_ = input_size;
  r.output_size_ = output;
  r.interpolation_ = options.interpolation;
  cv::Mat R1, R2, P1, P2, Q;
  try {
    cv::stereoRectify(cv::Mat(calibration.K1), calibration.D1, cv::Mat(calibration.K2),
                      calibration.D2, input_size, cv::Mat(calibration.R), cv::Mat(calibration.T),
                      R1, R2, P1, P2, Q, cv::CALIB_ZERO_DISPARITY, options.alpha, input_size);
  } catch (const cv::Exception& e) {
    return Status::Error(calibration.source + ": cv::stereoRectify failed (" + e.err + ")");
  }
  const cv::Matx34d p1_in(reinterpret_cast<const double*>(P1.data));
  const cv::Matx34d p2_in(reinterpret_cast<const double*>(P2.data));
  r.r1_ = cv::Matx33d(reinterpret_cast<const double*>(R1.data));
  r.r2_ = cv::Matx33d(reinterpret_cast<const double*>(R2.data));
  const cv::Matx33d S = ScaleMatrix(input_size, output);
  r.p1_ = S * p1_in;
  r.p2_ = S * p2_in;
  if (!(r.p1_(0, 0) > 0) || !std::isfinite(r.p2_(0, 3))) {
    return Status::Error(calibration.source + ": rectification produced focal length " +
                         std::to_string(r.p1_(0, 0)) + "; check the calibration");
  }
  if (std::abs(p2_in(1, 3)) > 1e-9 * std::abs(p2_in(0, 3))) {
    return Status::Error(calibration.source +
                         ": the cameras are stacked vertically (rectified P2 has a y offset); "
                         "only horizontal stereo is supported");
  }
  r.camera_.size = output;
  r.camera_.fx = r.p1_(0, 0);
  r.camera_.fy = r.p1_(1, 1);
  r.camera_.cx = r.p1_(0, 2);
  r.camera_.cy = r.p1_(1, 2);
  r.camera_.baseline = std::abs(r.p2_(0, 3)) / r.p2_(0, 0);

  r.two_stage_ = output.width * 2 < input_size.width || output.height * 2 < input_size.height;
  const cv::Size map_size = r.two_stage_ ? input_size : output;
  const cv::Matx34d map_p1 = r.two_stage_ ? p1_in : r.p1_;
  const cv::Matx34d map_p2 = r.two_stage_ ? p2_in : r.p2_;
  try {
    cv::initUndistortRectifyMap(cv::Mat(calibration.K1), calibration.D1, R1, cv::Mat(map_p1),
                                map_size, CV_16SC2, r.map1_left_, r.map2_left_);
    cv::initUndistortRectifyMap(cv::Mat(calibration.K2), calibration.D2, R2, cv::Mat(map_p2),
                                map_size, CV_16SC2, r.map1_right_, r.map2_right_);
  } catch (const cv::Exception& e) {
    return Status::Error(calibration.source + ": cv::initUndistortRectifyMap failed (" + e.err +
                         ")");
  }
  if (r.two_stage_) r.full_size_.create(input_size, CV_8UC3);
  return r;
}

Result<StereoRectifier> StereoRectifier::CreateResizeOnly(cv::Size input_size,
                                                          cv::Size output_size) {
  const cv::Size output = output_size.area() > 0 ? output_size : input_size;
  if (Status s = CheckSizes(input_size, output); !s.ok()) return s;
  StereoRectifier r;
  r.resize_only_ = true;
  r.input_size_ = input_size;
  r.output_size_ = output;
  const bool shrink = output.width <= input_size.width && output.height <= input_size.height;
  r.interpolation_ = shrink ? cv::INTER_AREA : cv::INTER_LINEAR;
  r.camera_.size = output;
  return r;
}

Status StereoRectifier::ApplyOne(const cv::Mat& in, const cv::Mat& map1, const cv::Mat& map2,
                                 cv::Mat* out, const char* side) {
  if (in.type() != CV_8UC3 || in.size() != input_size_) {
    return Status::Error(std::string("rectifier: ") + side + " image is " + SizeText(in.size()) +
                         " with " + std::to_string(in.channels()) +
                         " channels; expected 8-bit BGR " + SizeText(input_size_) + " (HxW)");
  }
  out->create(output_size_, CV_8UC3);
  if (resize_only_) {
    if (input_size_ == output_size_) {
      in.copyTo(*out);
    } else {
      cv::resize(in, *out, output_size_, 0, 0, interpolation_);
    }
  } else if (two_stage_) {
    cv::remap(in, full_size_, map1, map2, interpolation_, cv::BORDER_CONSTANT);
    cv::resize(full_size_, *out, output_size_, 0, 0, cv::INTER_AREA);
  } else {
    cv::remap(in, *out, map1, map2, interpolation_, cv::BORDER_CONSTANT);
  }
  return Status::Ok();
}

Status StereoRectifier::Apply(const cv::Mat& left, const cv::Mat& right, cv::Mat* out_left,
                              cv::Mat* out_right) {
  if (out_left == nullptr || out_right == nullptr || out_left == out_right || out_left == &left ||
      out_right == &right || out_left == &right || out_right == &left) {
    return Status::Error("rectifier: outputs must be two distinct images, not the inputs");
  }
  if (Status s = ApplyOne(left, map1_left_, map2_left_, out_left, "left"); !s.ok()) return s;
  return ApplyOne(right, map1_right_, map2_right_, out_right, "right");
}

}  // namespace sfrt::camera
