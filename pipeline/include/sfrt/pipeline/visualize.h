// Visualisation of one scene-flow frame as an 8-bit BGR image:
//
//   +-------------+-------------+-------------+
//   | left image  | X/Y flow    | Z flow      |   H rows (the model input size)
//   | (t)         | hue = direction, value =  | diverging: blue (-Z, towards the camera),
//   |             | |(X,Y)| / scale           | white (0), red (+Z, away from the camera)
//   +-------------+-------------+-------------+
//   | legend strip: frame label | colour wheel with +X/+Y, X/Y scale | colour bar, Z scale,
//   | units and the meaning of +Z (blocks wrap onto further rows when they do not fit)
//
// The legend strip is sized from its text, not from the image: ComputeLegendLayout() places
// every text box, the wheel and the bar so that none overlaps another or leaves the canvas, at
// any image size. The canvas is at least 3 * W wide, wider when the legend needs it (the
// panels stay at the top left). The layout is computed once, from the first frame's label and
// the widest number the scale can print, so every frame of a run has the same size (a video
// needs that); a longer label later is clipped to its box.
//
// Scales (VisScale): kFixed maps the same flow to the same colour in every frame; kFirst does
// too, with the scales taken from the first frame drawn (the 99th percentile of its finite
// |(X,Y)| and of its |Z|, so a few outliers do not wash the rest out) and kept for the run: the
// default for videos, as it fits any model's units and motion; kAuto uses each frame's largest
// finite |(X,Y)| and |Z| (1 when all zero), so colours are comparable within a frame only. Flow
// beyond the scale saturates.
// Direction: hue 0 (red) points along +X (image right), going round through +Y (image down).
// Axes are the left camera's: x right, y down, z forward (away from the camera).
//
// Render() reuses the canvas and its scratch images once they have the right size (no
// allocation in steady state apart from OpenCV's text rendering). Not thread-safe: one
// Visualizer per thread.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::pipeline {

struct VisScale {
  enum class Mode { kAuto, kFixed, kFirst };
  Mode mode = Mode::kAuto;
  double value = 0;  // kFixed: the |(X,Y)| and |Z| shown at full colour, in the model's units
};

// The percentile of the first frame's magnitudes that kFirst shows at full colour.
inline constexpr double kFirstFramePercentile = 0.99;

// VALUE as the legend and --help print it ("%.3g").
std::string FormatVisScaleValue(double value);

// "auto", "first" or "fixed:VALUE" (VALUE finite and > 0). The error names the text and the
// forms.
Result<VisScale> ParseVisScale(const std::string& text);

struct VisualizerOptions {
  VisScale scale;     // kAuto by default
  std::string units;  // the model's output units; "" prints "model units"
};

// Where everything of the canvas goes (pixels, canvas coordinates).
struct LegendLayout {
  cv::Size canvas;
  cv::Rect left, xy, z;  // the three image panels
  cv::Rect strip;        // the legend strip below them
  cv::Rect wheel;        // the X/Y colour wheel (square)
  cv::Rect bar;          // the Z colour bar
  struct TextBox {
    std::string text;  // as laid out (numbers at their widest)
    cv::Rect box;      // the text's full extent, ascent to descent
    int baseline = 0;  // y of the text baseline
  };
  // label, "+X", "+Y", the X/Y lines, "-", "+", the Z lines, in that order.
  std::vector<TextBox> texts;
};

// The legend lines for a scale and units (numbers at `xy`/`z`); used by the layout (with the
// widest numbers) and by Render (with the frame's).
struct LegendText {
  std::vector<std::string> xy_lines;
  std::vector<std::string> z_lines;
};
// `channels`: the output's channel count; other than 3, the last line says what is drawn
// (channels 0-2) instead of calling it flow.
LegendText MakeLegendText(const VisScale& scale, const std::string& units, double xy, double z,
                          int channels = 3);

// The layout for panels of `height` x `width` and the given label and legend lines.
LegendLayout ComputeLegendLayout(int height, int width, const std::string& label,
                                 const LegendText& text);

class Visualizer {
 public:
  Visualizer() = default;
  explicit Visualizer(VisualizerOptions options) : options_(std::move(options)) {}

  // left: CV_8UC3 of height x width; flow: height*width*channels floats (HWC, channels >= 3
  // uses channels 0, 1, 2 as X, Y, Z; 1 or 2 channels draw what exists). label: legend text.
  void Render(const cv::Mat& left, const float* flow, int channels, const std::string& label,
              cv::Mat* canvas);

  double last_xy_scale() const { return xy_scale_; }
  double last_z_scale() const { return z_scale_; }
  const LegendLayout& layout() const { return layout_; }

 private:
  // kFirst: the kFirstFramePercentile of the frame's finite |(X,Y)| (or |Z|); `largest` when
  // that is 0, and 1 when both are.
  double FirstFrameScale(const float* flow, size_t pixels, int channels, bool z, double largest);
  // The legend strip but the frame's label: the wheel, the bar and their texts at these scales.
  void DrawLegend(cv::Mat* canvas, double xy, double z, int channels);

  VisualizerOptions options_;
  bool first_scales_set_ = false;
  std::vector<double> magnitudes_;
  LegendLayout layout_;
  cv::Mat hsv_;
  cv::Mat wheel_;
  cv::Mat strip_cache_;  // fixed and first scales: the legend strip without the label
  double xy_scale_ = 1;
  double z_scale_ = 1;
};

// The diverging colour for t in [-1, 1] (clamped): blue -> white -> red, as BGR.
cv::Vec3b DivergingColor(double t);

}  // namespace sfrt::pipeline
