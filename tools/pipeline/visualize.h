// Visualisation of one scene-flow frame as an 8-bit BGR image:
//
//   +-------------+-------------+-------------+
//   | left image  | X/Y flow    | Z flow      |   H rows (the model input size)
//   | (t)         | hue = direction, value =  | diverging: blue (negative), white (0),
//   |             | |(X,Y)| / scale           | red (positive), |Z| / scale
//   +-------------+-------------+-------------+
//   | legend: frame name | colour wheel + "|XY| max" | colour bar + "Z +-max" |  kLegendRows rows
//
// Scales are per frame: the largest finite |(X,Y)| and |Z| (1 when the flow is all zero), printed
// in the legend, so colours are comparable within a frame, not across frames.
// Direction: hue 0 (red) points along +X, going round through +Y (image down); X right, Y down.
//
// Render() reuses the canvas and its scratch images once they have the right size (no
// allocation in steady state apart from OpenCV's text rendering). Not thread-safe: one
// Visualizer per thread.
#pragma once

#include <opencv2/core.hpp>
#include <string>

namespace sfrt::pipeline {

class Visualizer {
 public:
  static constexpr int kLegendRows = 36;

  // left: CV_8UC3 of height x width; flow: height*width*channels floats (HWC, channels >= 3
  // uses channels 0, 1, 2 as X, Y, Z; 1 or 2 channels draw what exists). label: legend text.
  void Render(const cv::Mat& left, const float* flow, int channels, const std::string& label,
              cv::Mat* canvas);

  double last_xy_scale() const { return xy_scale_; }
  double last_z_scale() const { return z_scale_; }

 private:
  cv::Mat hsv_;
  cv::Mat wheel_;
  double xy_scale_ = 1;
  double z_scale_ = 1;
};

// The diverging colour for t in [-1, 1] (clamped): blue -> white -> red, as BGR.
cv::Vec3b DivergingColor(double t);

}  // namespace sfrt::pipeline
