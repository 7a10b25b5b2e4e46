#include "pipeline/visualize.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

namespace sfrt::pipeline {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string Short(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3g", v);
  return buf;
}

void PutText(cv::Mat* canvas, const std::string& text, cv::Point at) {
  cv::putText(*canvas, text, at, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
}

// Hue (OpenCV's 0..180 scale) for direction (x, y), x right and y down.
uint8_t Hue(double x, double y) {
  double angle = std::atan2(y, x);  // -pi..pi, 0 along +X
  if (angle < 0) angle += 2 * kPi;
  return static_cast<uint8_t>(std::lround(angle / (2 * kPi) * 180.0) % 180);
}

}  // namespace

cv::Vec3b DivergingColor(double t) {
  t = std::clamp(std::isfinite(t) ? t : 0.0, -1.0, 1.0);
  const auto mix = [](double a, double b, double f) {
    return static_cast<uint8_t>(std::lround(a + (b - a) * f));
  };
  if (t < 0) {  // white -> blue (59, 76, 192 in RGB: the cool end of a cool-warm map)
    const double f = -t;
    return {mix(255, 192, f), mix(255, 76, f), mix(255, 59, f)};
  }
  // white -> red (180, 4, 38 in RGB)
  return {mix(255, 38, t), mix(255, 4, t), mix(255, 180, t)};
}

void Visualizer::Render(const cv::Mat& left, const float* flow, int channels,
                        const std::string& label, cv::Mat* canvas) {
  const int h = left.rows;
  const int w = left.cols;
  canvas->create(h + kLegendRows, 3 * w, CV_8UC3);
  canvas->setTo(cv::Scalar(0, 0, 0));
  left.copyTo((*canvas)(cv::Rect(0, 0, w, h)));

  const size_t pixels = static_cast<size_t>(h) * w;
  const size_t c = static_cast<size_t>(channels);
  double xy_max = 0;
  double z_max = 0;
  for (size_t i = 0; i < pixels; ++i) {
    const float* p = flow + i * c;
    const double x = p[0];
    const double y = channels > 1 ? p[1] : 0.0;
    const double m = std::hypot(x, y);
    if (std::isfinite(m)) xy_max = std::max(xy_max, m);
    if (channels > 2 && std::isfinite(p[2])) z_max = std::max(z_max, std::fabs(double{p[2]}));
  }
  xy_scale_ = xy_max > 0 ? xy_max : 1.0;
  z_scale_ = z_max > 0 ? z_max : 1.0;

  // X/Y: HSV with full saturation, value = magnitude / scale.
  hsv_.create(h, w, CV_8UC3);
  for (int r = 0; r < h; ++r) {
    cv::Vec3b* dst = hsv_.ptr<cv::Vec3b>(r);
    const float* p = flow + static_cast<size_t>(r) * w * c;
    for (int col = 0; col < w; ++col, p += c) {
      const double x = p[0];
      const double y = channels > 1 ? p[1] : 0.0;
      const double m = std::hypot(x, y);
      if (!std::isfinite(m)) {
        dst[col] = {0, 0, 0};
        continue;
      }
      dst[col] = {Hue(x, y), 255,
                  static_cast<uint8_t>(std::lround(std::min(1.0, m / xy_scale_) * 255.0))};
    }
  }
  cv::Mat xy_panel = (*canvas)(cv::Rect(w, 0, w, h));
  cv::cvtColor(hsv_, xy_panel, cv::COLOR_HSV2BGR);

  // Z: diverging map.
  for (int r = 0; r < h; ++r) {
    cv::Vec3b* dst = canvas->ptr<cv::Vec3b>(r) + 2 * w;
    const float* p = flow + static_cast<size_t>(r) * w * c;
    for (int col = 0; col < w; ++col, p += c) {
      dst[col] = channels > 2 ? DivergingColor(p[2] / z_scale_) : cv::Vec3b(0, 0, 0);
    }
  }

  // Legend: label under the image; a colour wheel and the X/Y scale; a colour bar and Z's scale.
  const int base = h + kLegendRows - 8;
  PutText(canvas, label, {4, base});
  const int radius = kLegendRows / 2 - 3;
  const cv::Point centre(w + 4 + radius, h + kLegendRows / 2);
  if (wheel_.empty()) {  // the colour wheel, made once
    const int side = 2 * radius + 1;
    cv::Mat hsv(side, side, CV_8UC3, cv::Scalar(0, 0, 0));
    for (int dy = -radius; dy <= radius; ++dy) {
      for (int dx = -radius; dx <= radius; ++dx) {
        const double m = std::hypot(dx, dy) / radius;
        if (m <= 1.0) {
          hsv.at<cv::Vec3b>(dy + radius, dx + radius) = {
              Hue(dx, dy), 255, static_cast<uint8_t>(std::lround(m * 255.0))};
        }
      }
    }
    cv::cvtColor(hsv, wheel_, cv::COLOR_HSV2BGR);
  }
  if (centre.x + radius < canvas->cols) {
    wheel_.copyTo(
        (*canvas)(cv::Rect(centre.x - radius, centre.y - radius, wheel_.cols, wheel_.rows)));
  }
  PutText(canvas, "XY |d| max " + Short(xy_max), {w + 10 + 2 * radius, base});
  const int bar_w = std::max(8, std::min(w / 3, 100));
  const int bar_x = 2 * w + 4;
  for (int i = 0; i < bar_w && bar_x + i < canvas->cols; ++i) {
    const cv::Vec3b colour = DivergingColor(2.0 * i / std::max(1, bar_w - 1) - 1.0);
    for (int r = h + 6; r < h + kLegendRows - 6; ++r) canvas->at<cv::Vec3b>(r, bar_x + i) = colour;
  }
  PutText(canvas, "Z -/+ " + Short(z_max), {bar_x + bar_w + 6, base});
}

}  // namespace sfrt::pipeline
