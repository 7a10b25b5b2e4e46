#include "kernels/ref/resize_ref.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace sfrt::ref {
namespace {

// The source coordinate of output position y (docs/model-format.md, "Resize"). `out` is the
// unrounded output length in * scale, as ONNX's reference uses it; [roi_start, roi_end] the
// region of interest (kTfCropAndResize).
double SourceCoordinate(ResizeCoordinates mode, int y, int in, double out, double scale,
                        double roi_start, double roi_end) {
  switch (mode) {
    case ResizeCoordinates::kHalfPixel:
      return (y + 0.5) / scale - 0.5;
    case ResizeCoordinates::kPytorchHalfPixel:
      return out > 1 ? (y + 0.5) / scale - 0.5 : 0.0;
    case ResizeCoordinates::kAlignCorners:
      return out != 1 ? y * static_cast<double>(in - 1) / (out - 1) : 0.0;
    case ResizeCoordinates::kAsymmetric:
      return y / scale;
    case ResizeCoordinates::kTfHalfPixelForNn:
      return (y + 0.5) / scale;
    case ResizeCoordinates::kTfCropAndResize:
      return out > 1 ? roi_start * (in - 1) + y * (roi_end - roi_start) * (in - 1) / (out - 1)
                     : 0.5 * (roi_start + roi_end) * (in - 1);
  }
  return 0.0;
}

int NearestIndex(NearestRounding rounding, double x) {
  switch (rounding) {
    case NearestRounding::kRoundPreferFloor:  // a half goes down
      return static_cast<int>(std::ceil(x - 0.5));
    case NearestRounding::kRoundPreferCeil:  // a half goes up
      return static_cast<int>(std::floor(x + 0.5));
    case NearestRounding::kFloor:
      return static_cast<int>(std::floor(x));
    case NearestRounding::kCeil:
      return static_cast<int>(std::ceil(x));
  }
  return 0;
}

// Keys' cubic convolution kernel with parameter a, at distance d >= 0.
double Cubic(double a, double d) {
  if (d <= 1) return ((a + 2) * d - (a + 3)) * d * d + 1;
  if (d < 2) return ((a * d - 5 * a) * d + 8 * a) * d - 4 * a;
  return 0.0;
}

}  // namespace

ResizeTaps ResizeAxisTaps(const ResizeParams& p, ResizeAxis axis, int y, int in) {
  const bool h = axis == ResizeAxis::kHeight;
  const double scale = static_cast<double>(h ? p.scale_num_h : p.scale_num_w) /
                       static_cast<double>(h ? p.scale_den_h : p.scale_den_w);
  const double x =
      SourceCoordinate(p.coordinates, y, in, in * scale, scale, h ? p.roi_start_h : p.roi_start_w,
                       h ? p.roi_end_h : p.roi_end_w);
  auto clamp = [in](long long i) { return static_cast<int>(std::clamp<long long>(i, 0, in - 1)); };
  ResizeTaps taps;
  if (p.coordinates == ResizeCoordinates::kTfCropAndResize && (x < 0 || x > in - 1)) {
    taps.outside = true;
    return taps;
  }
  if (p.mode == ResizeMode::kNearest) {
    taps.count = 1;
    taps.index[0] = clamp(NearestIndex(p.nearest, x));
    taps.weight[0] = 1.0f;
    return taps;
  }
  const double base = std::floor(x);
  const double t = x - base;  // in [0, 1)
  const auto first = static_cast<long long>(base);
  if (p.mode == ResizeMode::kLinear) {
    taps.count = 2;
    taps.index[0] = clamp(first);
    taps.index[1] = clamp(first + 1);
    taps.weight[0] = static_cast<float>(1.0 - t);
    taps.weight[1] = static_cast<float>(t);
    return taps;
  }
  taps.count = 4;
  double w[4];
  double sum = 0;
  for (int k = 0; k < 4; ++k) {
    const long long i = first - 1 + k;
    w[k] = Cubic(p.cubic_coeff_a, std::fabs(x - static_cast<double>(i)));
    if (p.exclude_outside && (i < 0 || i >= in)) w[k] = 0;
    sum += w[k];
    taps.index[k] = clamp(i);
  }
  for (int k = 0; k < 4; ++k) {
    taps.weight[k] = static_cast<float>(p.exclude_outside && sum != 0 ? w[k] / sum : w[k]);
  }
  return taps;
}

void ResizeRows(const ConstTensorView& in, const ResizeParams& p, const TensorView& out,
                int row_begin, int row_end) {
  assert(in.channels == out.channels);
  const int channels = in.channels;
  for (int y = row_begin; y < row_end; ++y) {
    const ResizeTaps rows = ResizeAxisTaps(p, ResizeAxis::kHeight, y, in.height);
    for (int x = 0; x < out.width; ++x) {
      const ResizeTaps cols = ResizeAxisTaps(p, ResizeAxis::kWidth, x, in.width);
      float* dst = out.pixel(y, x);
      if (rows.outside || cols.outside) {
        std::fill(dst, dst + channels, p.extrapolation_value);
        continue;
      }
      std::fill(dst, dst + channels, 0.0f);
      for (int r = 0; r < rows.count; ++r) {
        for (int c = 0; c < cols.count; ++c) {
          const float w = rows.weight[r] * cols.weight[c];
          const float* src = in.pixel(rows.index[r], cols.index[c]);
          for (int ch = 0; ch < channels; ++ch) dst[ch] += w * src[ch];
        }
      }
    }
  }
}

}  // namespace sfrt::ref
