#include "sfrt/camera/preprocess.h"

#include <cmath>
#include <cstdio>

namespace sfrt::camera {
namespace {

std::string FloatText(float v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", static_cast<double>(v));
  return buf;
}

}  // namespace

Result<ImageSlot> ParseImageSlot(const std::string& name) {
  if (std::optional<ImageSlot> slot = vocabulary::ImageSlotFromName(name)) return *slot;
  return Status::Error("image order entry '" + name +
                       "' is not one of left0, right0, left1, right1");
}

Result<std::array<ImageSlot, 4>> ParseImageOrder(const std::vector<std::string>& names) {
  if (names.size() != 4) {
    return Status::Error("image order has " + std::to_string(names.size()) +
                         " entries, expected 4 (a permutation of left0, right0, left1, right1)");
  }
  std::array<ImageSlot, 4> order{};
  bool seen[4] = {false, false, false, false};
  for (size_t i = 0; i < 4; ++i) {
    Result<ImageSlot> slot = ParseImageSlot(names[i]);
    if (!slot.ok()) return slot.status();
    const int s = static_cast<int>(*slot);
    if (seen[s]) return Status::Error("image order names '" + names[i] + "' twice");
    seen[s] = true;
    order[i] = *slot;
  }
  return order;
}

Result<ColorOrder> ParseColorOrder(const std::string& name) {
  if (std::optional<ColorOrder> order = vocabulary::ColorOrderFromName(name)) return *order;
  return Status::Error("color order '" + name + "' is neither BGR nor RGB");
}

Result<Preprocessor> Preprocessor::Create(const PreprocessParams& params, int height, int width) {
  if (height < 1 || width < 1 || height > 16384 || width > 16384) {
    return Status::Error("preprocessing: input size " + std::to_string(height) + "x" +
                         std::to_string(width) + " (HxW) is outside 1..16384");
  }
  bool seen[4] = {false, false, false, false};
  for (size_t g = 0; g < 4; ++g) {
    const int s = static_cast<int>(params.image_order[g]);
    if (s < 0 || s > 3) {
      return Status::Error("preprocessing: image_order[" + std::to_string(g) + "] is " +
                           std::to_string(s) + ", not a slot");
    }
    if (seen[s]) {
      return Status::Error("preprocessing: image_order names " +
                           std::string(vocabulary::ImageSlotName(static_cast<ImageSlot>(s))) +
                           " twice");
    }
    seen[s] = true;
  }
  if (!std::isfinite(params.scale)) {
    return Status::Error("preprocessing: scale is " + FloatText(params.scale));
  }
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(params.mean[c])) {
      return Status::Error("preprocessing: mean[" + std::to_string(c) + "] is " +
                           FloatText(params.mean[c]));
    }
    if (!std::isfinite(params.std[c]) || params.std[c] == 0) {
      return Status::Error("preprocessing: std[" + std::to_string(c) + "] is " +
                           FloatText(params.std[c]) + "; cannot normalise");
    }
  }
  Preprocessor p;
  p.params_ = params;
  p.height_ = height;
  p.width_ = width;
  const bool rgb = params.color_order == ColorOrder::kRGB;
  for (int c = 0; c < 3; ++c) {
    p.source_channel_[c] = rgb ? 2 - c : c;
    for (int v = 0; v < 256; ++v) {
      const float pixel = static_cast<float>(v);
      p.lut_[c][v] = (pixel * params.scale - params.mean[c]) / params.std[c];
    }
  }
  return p;
}

Status Preprocessor::Run(const cv::Mat& left0, const cv::Mat& right0, const cv::Mat& left1,
                         const cv::Mat& right1, float* dst, size_t dst_floats) const {
  const cv::Mat* images[4] = {&left0, &right0, &left1, &right1};
  for (int i = 0; i < 4; ++i) {
    const cv::Mat& m = *images[i];
    if (m.type() != CV_8UC3 || m.rows != height_ || m.cols != width_) {
      return Status::Error(
          "preprocessing: " + std::string(vocabulary::ImageSlotName(static_cast<ImageSlot>(i))) +
          " image is " + std::to_string(m.rows) + "x" + std::to_string(m.cols) + " with " +
          std::to_string(m.channels()) + " channels of depth " + std::to_string(m.depth()) +
          "; expected 8-bit BGR " + std::to_string(height_) + "x" + std::to_string(width_) +
          " (HxW)");
    }
  }
  if (dst == nullptr || dst_floats != output_floats()) {
    return Status::Error("preprocessing: destination holds " + std::to_string(dst_floats) +
                         " floats, expected " + std::to_string(output_floats()) + " (" +
                         std::to_string(height_) + " x " + std::to_string(width_) + " x 12)");
  }
  const int s0 = source_channel_[0];
  const int s1 = source_channel_[1];
  const int s2 = source_channel_[2];
  const float* lut0 = lut_[0].data();
  const float* lut1 = lut_[1].data();
  const float* lut2 = lut_[2].data();
  for (int g = 0; g < 4; ++g) {
    const cv::Mat& image = *images[static_cast<int>(params_.image_order[g])];
    for (int y = 0; y < height_; ++y) {
      const uint8_t* src = image.ptr<uint8_t>(y);
      float* out = dst + static_cast<size_t>(y) * width_ * kChannels + 3 * g;
      for (int x = 0; x < width_; ++x, src += 3, out += kChannels) {
        out[0] = lut0[src[s0]];
        out[1] = lut1[src[s1]];
        out[2] = lut2[src[s2]];
      }
    }
  }
  return Status::Ok();
}

}  // namespace sfrt::camera
