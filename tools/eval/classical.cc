#include "eval/classical.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

namespace sfrt::eval {
namespace {

cv::Mat Grey(const cv::Mat& bgr) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  return grey;
}

// Fills pixels <= 0 of each row with the smaller of the nearest positive values to the left
// and right (or the one that exists).
void FillRows(cv::Mat& disparity) {
  const int cols = disparity.cols;
  std::vector<float> left_valid(static_cast<size_t>(cols));
  for (int y = 0; y < disparity.rows; ++y) {
    float* row = disparity.ptr<float>(y);
    float last = -1;
    for (int x = 0; x < cols; ++x) {
      if (row[x] > 0) last = row[x];
      left_valid[static_cast<size_t>(x)] = last;
    }
    last = -1;
    for (int x = cols - 1; x >= 0; --x) {
      if (row[x] > 0) {
        last = row[x];
        continue;
      }
      const float a = left_valid[static_cast<size_t>(x)];
      if (a > 0 && last > 0) {
        row[x] = std::min(a, last);
      } else {
        row[x] = a > 0 ? a : last;
      }
    }
  }
}

float Bilinear(const cv::Mat& image, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x));
  const int y0 = static_cast<int>(std::floor(y));
  const int x1 = std::min(x0 + 1, image.cols - 1);
  const int y1 = std::min(y0 + 1, image.rows - 1);
  const double fx = x - x0;
  const double fy = y - y0;
  const double a = image.at<float>(y0, x0);
  const double b = image.at<float>(y0, x1);
  const double c = image.at<float>(y1, x0);
  const double d = image.at<float>(y1, x1);
  return static_cast<float>((a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy);
}

}  // namespace

cv::Mat ClassicalDisparity(const cv::Mat& left_bgr, const cv::Mat& right_bgr) {
  const int num_disparities = std::clamp((left_bgr.cols / 4 + 15) / 16 * 16, 16, 256);
  constexpr int kBlock = 5;
  cv::Ptr<cv::StereoSGBM> sgbm =
      cv::StereoSGBM::create(0, num_disparities, kBlock, 8 * 3 * kBlock * kBlock,
                             32 * 3 * kBlock * kBlock, 1, 0, 10, 100, 2, cv::StereoSGBM::MODE_SGBM);
  cv::Mat fixed;  // CV_16S, disparity * 16, negative where invalid
  sgbm->compute(Grey(left_bgr), Grey(right_bgr), fixed);
  cv::Mat disparity;
  fixed.convertTo(disparity, CV_32F, 1.0 / 16.0);
  FillRows(disparity);
  return disparity;
}

cv::Mat ClassicalOpticalFlow(const cv::Mat& from_bgr, const cv::Mat& to_bgr) {
  cv::Ptr<cv::DISOpticalFlow> dis = cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM);
  cv::Mat flow;
  dis->calc(Grey(from_bgr), Grey(to_bgr), flow);
  return flow;
}

std::vector<float> SceneFlowFromStereoAndFlow(const cv::Mat& disparity0, const cv::Mat& disparity1,
                                              const cv::Mat& flow, const PinholeStereo& camera) {
  const int rows = disparity0.rows;
  const int cols = disparity0.cols;
  std::vector<float> out(static_cast<size_t>(rows) * cols * 3, 0.0f);
  const double fb = camera.focal * camera.baseline;
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x) {
      const double d0 = disparity0.at<float>(y, x);
      const cv::Vec2f uv = flow.at<cv::Vec2f>(y, x);
      const double x1 = x + static_cast<double>(uv[0]);
      const double y1 = y + static_cast<double>(uv[1]);
      double d1 = d0;
      if (x1 >= 0 && y1 >= 0 && x1 <= cols - 1 && y1 <= rows - 1) {
        d1 = Bilinear(disparity1, x1, y1);
      }
      if (!(d0 > 0) || !(d1 > 0) || !std::isfinite(x1) || !std::isfinite(y1)) continue;
      const double z0 = fb / d0;
      const double z1 = fb / d1;
      float* o = out.data() + (static_cast<size_t>(y) * cols + x) * 3;
      o[0] = static_cast<float>((x1 - camera.cx) * z1 / camera.focal -
                                (x - camera.cx) * z0 / camera.focal);
      o[1] = static_cast<float>((y1 - camera.cy) * z1 / camera.focal -
                                (y - camera.cy) * z0 / camera.focal);
      o[2] = static_cast<float>(z1 - z0);
    }
  }
  return out;
}

std::vector<float> ClassicalSceneFlow(const cv::Mat& left0, const cv::Mat& right0,
                                      const cv::Mat& left1, const cv::Mat& right1,
                                      const PinholeStereo& camera) {
  const cv::Mat d0 = ClassicalDisparity(left0, right0);
  const cv::Mat d1 = ClassicalDisparity(left1, right1);
  const cv::Mat flow = ClassicalOpticalFlow(left0, left1);
  return SceneFlowFromStereoAndFlow(d0, d1, flow, camera);
}

}  // namespace sfrt::eval
