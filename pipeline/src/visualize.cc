#include "sfrt/pipeline/visualize.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <opencv2/imgproc.hpp>

namespace sfrt::pipeline {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kFontScale = 0.4;
constexpr int kMargin = 4;      // canvas edge to legend content
constexpr int kBlockGap = 12;   // between legend blocks
constexpr int kItemGap = 4;     // between items of one block
constexpr int kLineGap = 3;     // between text lines
constexpr int kWheelSide = 27;  // colour wheel diameter (odd: it has a centre pixel)
constexpr int kBarWidth = 64;
constexpr int kBarHeight = 10;
// The widest number the legend prints ("%.3g" of a non-negative finite double).
constexpr const char* kWidestNumber = "8.88e+88";

std::string Short(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3g", v);
  return buf;
}

// Hue (OpenCV's 0..180 scale) for direction (x, y), x right and y down.
uint8_t Hue(double x, double y) {
  double angle = std::atan2(y, x);  // -pi..pi, 0 along +X
  if (angle < 0) angle += 2 * kPi;
  return static_cast<uint8_t>(std::lround(angle / (2 * kPi) * 180.0) % 180);
}

// A text's full extent (ascent + descent) with its top left at `at`; `baseline` gets its
// baseline's y.
cv::Rect TextRect(const std::string& text, cv::Point at, int* baseline) {
  int descent = 0;
  const cv::Size size = cv::getTextSize(text, kFont, kFontScale, 1, &descent);
  *baseline = at.y + size.height;
  // +1 on each axis: anti-aliasing may touch the pixel past the metrics.
  return {at.x, at.y, size.width + 1, size.height + descent + 1};
}

// A block of the legend, laid out at the origin, then moved to its place in the strip.
struct Block {
  std::vector<LegendLayout::TextBox> texts;
  cv::Rect wheel, bar;  // empty when the block has none
  cv::Size size;

  void AddText(const std::string& text, cv::Point at) {
    LegendLayout::TextBox t;
    t.text = text;
    t.box = TextRect(text, at, &t.baseline);
    texts.push_back(t);
    Grow(t.box);
  }
  void Grow(const cv::Rect& r) {
    size.width = std::max(size.width, r.x + r.width);
    size.height = std::max(size.height, r.y + r.height);
  }
  // Lines stacked from (x, 0).
  void AddLines(const std::vector<std::string>& lines, int x) {
    int y = 0;
    for (const std::string& line : lines) {
      AddText(line, {x, y});
      y = texts.back().box.y + texts.back().box.height + kLineGap;
    }
  }
  void MoveTo(cv::Point at) {
    for (auto& t : texts) {
      t.box += at;
      t.baseline += at.y;
    }
    if (!wheel.empty()) wheel += at;
    if (!bar.empty()) bar += at;
  }
};

std::string UnitsText(const std::string& units) { return units.empty() ? "model units" : units; }

}  // namespace

std::string FormatVisScaleValue(double value) { return Short(value); }

Result<VisScale> ParseVisScale(const std::string& text) {
  VisScale scale;
  if (text == "auto") return scale;
  if (text == "first") {
    scale.mode = VisScale::Mode::kFirst;
    return scale;
  }
  const std::string prefix = "fixed:";
  if (text.rfind(prefix, 0) == 0 && text.size() > prefix.size()) {
    const std::string number = text.substr(prefix.size());
    char* end = nullptr;
    const double v = std::strtod(number.c_str(), &end);
    if (end == number.c_str() + number.size() && std::isfinite(v) && v > 0) {
      scale.mode = VisScale::Mode::kFixed;
      scale.value = v;
      return scale;
    }
  }
  return Status::Error("--vis-scale '" + text +
                       "': expected 'auto', 'first' or 'fixed:VALUE' with VALUE a number > 0 in "
                       "the model's units (e.g. fixed:0.05)");
}

LegendText MakeLegendText(const VisScale& scale, const std::string& units, double xy, double z,
                          int channels) {
  LegendText t;
  const bool fixed = scale.mode != VisScale::Mode::kAuto;
  const std::string from = scale.mode == VisScale::Mode::kFirst ? " (1st frame)" : "";
  t.xy_lines = {"X/Y: hue = direction", fixed ? "full colour at |d| " + Short(xy) + from
                                              : "|d| max " + Short(xy) + " (auto)"};
  t.z_lines = {"Z: red = +Z = away from camera", "blue = -Z = towards camera",
               fixed ? "full colour at |Z| " + Short(z) + from : "|Z| max " + Short(z) + " (auto)",
               "flow in " + UnitsText(units) + ", t to t+1"};
  if (channels != 3) {  // not a 3-D flow: say what is drawn instead of calling it one
    t.z_lines.back() = "channels 0-" + std::to_string(std::min(channels, 3) - 1) + " of " +
                       std::to_string(channels) + " drawn: not 3-D flow";
  }
  return t;
}

LegendLayout ComputeLegendLayout(int height, int width, const std::string& label,
                                 const LegendText& text) {
  std::vector<Block> blocks(3);
  blocks[0].AddText(label, {0, 0});

  Block& xy = blocks[1];
  xy.wheel = {0, 0, kWheelSide, kWheelSide};
  xy.Grow(xy.wheel);
  int unused = 0;
  const cv::Rect x_size = TextRect("+X", {0, 0}, &unused);
  xy.AddText("+X", {kWheelSide + kItemGap, std::max(0, (kWheelSide - x_size.height) / 2)});
  const cv::Rect y_size = TextRect("+Y", {0, 0}, &unused);
  xy.AddText("+Y", {std::max(0, (kWheelSide - y_size.width) / 2), kWheelSide + kItemGap});
  xy.AddLines(text.xy_lines, xy.size.width + kBlockGap);

  Block& z = blocks[2];
  z.bar = {0, 0, kBarWidth, kBarHeight};
  z.Grow(z.bar);
  z.AddText("-", {0, kBarHeight + kItemGap});
  const cv::Rect plus_size = TextRect("+", {0, 0}, &unused);
  z.AddText("+", {kBarWidth - plus_size.width, kBarHeight + kItemGap});
  z.AddLines(text.z_lines, z.size.width + kBlockGap);

  LegendLayout layout;
  int widest = 0;
  for (const Block& b : blocks) widest = std::max(widest, b.size.width);
  const int canvas_w = std::max(3 * width, widest + 2 * kMargin);
  // Blocks left to right, wrapping onto a new row when the next one does not fit.
  int x = kMargin, y = height + kMargin, row_h = 0;
  for (Block& b : blocks) {
    if (x > kMargin && x + b.size.width > canvas_w - kMargin) {
      x = kMargin;
      y += row_h + kItemGap;
      row_h = 0;
    }
    b.MoveTo({x, y});
    x += b.size.width + kBlockGap;
    row_h = std::max(row_h, b.size.height);
    for (auto& t : b.texts) layout.texts.push_back(std::move(t));
    if (!b.wheel.empty()) layout.wheel = b.wheel;
    if (!b.bar.empty()) layout.bar = b.bar;
  }
  const int canvas_h = y + row_h + kMargin;
  layout.canvas = {canvas_w, canvas_h};
  layout.left = {0, 0, width, height};
  layout.xy = {width, 0, width, height};
  layout.z = {2 * width, 0, width, height};
  layout.strip = {0, height, canvas_w, canvas_h - height};
  return layout;
}

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

double Visualizer::FirstFrameScale(const float* flow, size_t pixels, int channels, bool z,
                                   double largest) {
  std::vector<double>& m = magnitudes_;  // made once: kFirst runs this on one frame only
  m.clear();
  const size_t c = static_cast<size_t>(channels);
  for (size_t i = 0; i < pixels; ++i) {
    const float* p = flow + i * c;
    const double v = z ? std::fabs(double{p[2]}) : std::hypot(p[0], channels > 1 ? p[1] : 0.0f);
    if (std::isfinite(v)) m.push_back(v);
  }
  if (m.empty()) return 1.0;
  const size_t k = std::min(m.size() - 1, static_cast<size_t>(kFirstFramePercentile * m.size()));
  std::nth_element(m.begin(), m.begin() + static_cast<std::ptrdiff_t>(k), m.end());
  const double scale = m[k] > 0 ? m[k] : largest;
  return scale > 0 ? scale : 1.0;
}

void Visualizer::DrawLegend(cv::Mat* canvas, double xy, double z, int channels) {
  if (wheel_.empty()) {
    const int radius = layout_.wheel.width / 2;
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
  wheel_.copyTo((*canvas)(cv::Rect(layout_.wheel.tl(), wheel_.size())));
  const cv::Rect& bar = layout_.bar;
  for (int i = 0; i < bar.width; ++i) {
    const cv::Vec3b colour = DivergingColor(2.0 * i / std::max(1, bar.width - 1) - 1.0);
    for (int r = bar.y; r < bar.y + bar.height; ++r) canvas->at<cv::Vec3b>(r, bar.x + i) = colour;
  }
  const LegendText now = MakeLegendText(options_.scale, options_.units, xy, z, channels);
  std::vector<std::string> strings = {"+X", "+Y"};  // the label (texts[0]) is drawn by Render
  strings.insert(strings.end(), now.xy_lines.begin(), now.xy_lines.end());
  strings.push_back("-");
  strings.push_back("+");
  strings.insert(strings.end(), now.z_lines.begin(), now.z_lines.end());
  for (size_t i = 1; i < layout_.texts.size() && i - 1 < strings.size(); ++i) {
    const LegendLayout::TextBox& t = layout_.texts[i];
    cv::Mat box = (*canvas)(t.box);  // drawing into the box clips to it
    cv::putText(box, strings[i - 1], {0, t.baseline - t.box.y}, kFont, kFontScale,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
}

void Visualizer::Render(const cv::Mat& left, const float* flow, int channels,
                        const std::string& label, cv::Mat* canvas) {
  const int h = left.rows;
  const int w = left.cols;
  const size_t pixels = static_cast<size_t>(h) * w;
  const size_t c = static_cast<size_t>(channels);
  double xy_max = 0;
  double z_max = 0;
  for (size_t i = 0; i < pixels; ++i) {
    const float* p = flow + i * c;
    const double x = p[0];
    const double y = channels > 1 ? p[1] : 0.0;
    const double m = std::sqrt(x * x + y * y);  // floats squared in double: hypot not needed
    if (std::isfinite(m)) xy_max = std::max(xy_max, m);
    if (channels > 2 && std::isfinite(p[2])) z_max = std::max(z_max, std::fabs(double{p[2]}));
  }
  if (options_.scale.mode == VisScale::Mode::kFixed) {
    xy_scale_ = z_scale_ = options_.scale.value;
  } else if (options_.scale.mode == VisScale::Mode::kFirst) {
    if (!first_scales_set_) {  // once, from the first frame; kept for the run
      xy_scale_ = FirstFrameScale(flow, pixels, channels, false, xy_max);
      z_scale_ = channels > 2 ? FirstFrameScale(flow, pixels, channels, true, z_max) : 1.0;
      first_scales_set_ = true;
    }
  } else {
    xy_scale_ = xy_max > 0 ? xy_max : 1.0;
    z_scale_ = z_max > 0 ? z_max : 1.0;
  }
  const bool fixed = options_.scale.mode != VisScale::Mode::kAuto;
  if (layout_.left.height != h || layout_.left.width != w) {  // once per size
    const bool given = options_.scale.mode == VisScale::Mode::kFixed;
    const double widest = given ? options_.scale.value : std::strtod(kWidestNumber, nullptr);
    layout_ = ComputeLegendLayout(h, w, label,
                                  MakeLegendText(options_.scale, options_.units, widest, widest));
    wheel_.release();
    strip_cache_.release();
  }
  canvas->create(layout_.canvas, CV_8UC3);
  canvas->setTo(cv::Scalar(0, 0, 0));
  left.copyTo((*canvas)(layout_.left));

  // X/Y: HSV with full saturation, value = magnitude / scale.
  hsv_.create(h, w, CV_8UC3);
  for (int r = 0; r < h; ++r) {
    cv::Vec3b* dst = hsv_.ptr<cv::Vec3b>(r);
    const float* p = flow + static_cast<size_t>(r) * w * c;
    for (int col = 0; col < w; ++col, p += c) {
      const double x = p[0];
      const double y = channels > 1 ? p[1] : 0.0;
      const double m = std::sqrt(x * x + y * y);  // floats squared in double: hypot not needed
      if (!std::isfinite(m)) {
        dst[col] = {0, 0, 0};
        continue;
      }
      dst[col] = {Hue(x, y), 255,
                  static_cast<uint8_t>(std::lround(std::min(1.0, m / xy_scale_) * 255.0))};
    }
  }
  cv::Mat xy_panel = (*canvas)(layout_.xy);
  cv::cvtColor(hsv_, xy_panel, cv::COLOR_HSV2BGR);

  // Z: diverging map.
  for (int r = 0; r < h; ++r) {
    cv::Vec3b* dst = canvas->ptr<cv::Vec3b>(r) + 2 * w;
    const float* p = flow + static_cast<size_t>(r) * w * c;
    for (int col = 0; col < w; ++col, p += c) {
      dst[col] = channels > 2 ? DivergingColor(p[2] / z_scale_) : cv::Vec3b(0, 0, 0);
    }
  }

  // Legend: the colour wheel (made once), the colour bar, then each text clipped to its box.
  // With a scale that does not change (fixed, first) only the frame's label differs from frame
  // to frame: the rest of the strip is drawn once, kept, and copied.
  cv::Mat strip = (*canvas)(layout_.strip);
  if (fixed && !strip_cache_.empty() && strip_cache_.size() == strip.size()) {
    strip_cache_.copyTo(strip);
  } else {
    DrawLegend(canvas, fixed ? xy_scale_ : xy_max, fixed ? z_scale_ : z_max, channels);
    if (fixed) strip.copyTo(strip_cache_);
  }
  if (!layout_.texts.empty()) {
    const LegendLayout::TextBox& t = layout_.texts.front();  // the label
    cv::Mat box = (*canvas)(t.box);                          // drawing into the box clips to it
    cv::putText(box, label, {0, t.baseline - t.box.y}, kFont, kFontScale, cv::Scalar(255, 255, 255),
                1, cv::LINE_AA);
  }
}

}  // namespace sfrt::pipeline
