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

// The colour tables Preprocessor and RgbdPreprocessor share: lut[c][v] is the value fed on channel
// c (the model's order) for 8-bit value v of BGR channel source[c].
Status CheckColourParams(ColorOrder color_order, float scale, const float mean[3],
                         const float std[3], std::array<std::array<float, 256>, 3>* lut,
                         std::array<int, 3>* source) {
  if (!std::isfinite(scale)) return Status::Error("preprocessing: scale is " + FloatText(scale));
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(mean[c])) {
      return Status::Error("preprocessing: mean[" + std::to_string(c) + "] is " +
                           FloatText(mean[c]));
    }
    if (!std::isfinite(std[c]) || std[c] == 0) {
      return Status::Error("preprocessing: std[" + std::to_string(c) + "] is " + FloatText(std[c]) +
                           "; cannot normalise");
    }
  }
  const bool rgb = color_order == ColorOrder::kRGB;
  for (int c = 0; c < 3; ++c) {
    (*source)[static_cast<size_t>(c)] = rgb ? 2 - c : c;
    for (int v = 0; v < 256; ++v) {
      (*lut)[static_cast<size_t>(c)][static_cast<size_t>(v)] =
          (static_cast<float>(v) * scale - mean[c]) / std[c];
    }
  }
  return Status::Ok();
}

}  // namespace

Result<ImageSlot> ParseImageSlot(const std::string& name) {
  if (std::optional<ImageSlot> slot = vocabulary::ImageSlotFromName(name)) return *slot;
  return Status::Error("image order entry '" + name +
                       "' is not one of left0, right0, left1, right1 (stereo pairs) or color0, "
                       "depth0, color1, depth1 (RGB-D frames)");
}

Result<std::array<ImageSlot, 4>> ParseImageOrder(const std::vector<std::string>& names) {
  if (names.size() != 4) {
    return Status::Error("image order has " + std::to_string(names.size()) +
                         " entries, expected 4 (a permutation of left0, right0, left1, right1 "
                         "or of color0, depth0, color1, depth1)");
  }
  std::array<ImageSlot, 4> order{};
  std::array<bool, vocabulary::kImageSlots> seen{};
  for (size_t i = 0; i < 4; ++i) {
    Result<ImageSlot> slot = ParseImageSlot(names[i]);
    if (!slot.ok()) return slot.status();
    const auto s = static_cast<size_t>(*slot);
    if (seen[s]) return Status::Error("image order names '" + names[i] + "' twice");
    if (i > 0 && vocabulary::IsRgbdSlot(*slot) != vocabulary::IsRgbdSlot(order[0])) {
      return Status::Error("image order mixes stereo images and RGB-D frames ('" + names[0] +
                           "', '" + names[i] + "')");
    }
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
      return Status::Error(
          "preprocessing: image_order[" + std::to_string(g) + "] is " + std::to_string(s) +
          ", not a stereo image slot" +
          (s >= 4 && s < vocabulary::kImageSlots
               ? " (" + std::string(vocabulary::ImageSlotName(static_cast<ImageSlot>(s))) +
                     ": RGB-D frames go through RgbdPreprocessor)"
               : std::string()));
    }
    if (seen[s]) {
      return Status::Error("preprocessing: image_order names " +
                           std::string(vocabulary::ImageSlotName(static_cast<ImageSlot>(s))) +
                           " twice");
    }
    seen[s] = true;
  }
  Preprocessor p;
  if (Status st = CheckColourParams(params.color_order, params.scale, params.mean, params.std,
                                    &p.lut_, &p.source_channel_);
      !st.ok()) {
    return st;
  }
  p.params_ = params;
  p.height_ = height;
  p.width_ = width;
  return p;
}

Status Preprocessor::Check(const cv::Mat* const (&images)[4], size_t dst_elements,
                           const char* unit) const {
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
  if (dst_elements != output_floats()) {
    return Status::Error("preprocessing: destination holds " + std::to_string(dst_elements) + " " +
                         unit + ", expected " + std::to_string(output_floats()) + " (" +
                         std::to_string(height_) + " x " + std::to_string(width_) + " x 12)");
  }
  return Status::Ok();
}

// Every image into its 3 channels of dst through the per-channel tables: the only per-pixel work.
template <typename T>
void Preprocessor::Fill(const cv::Mat* const (&images)[4],
                        const std::array<std::array<T, 256>, 3>& lut, T* dst) const {
  const int s0 = source_channel_[0];
  const int s1 = source_channel_[1];
  const int s2 = source_channel_[2];
  const T* lut0 = lut[0].data();
  const T* lut1 = lut[1].data();
  const T* lut2 = lut[2].data();
  for (int g = 0; g < 4; ++g) {
    const cv::Mat& image = *images[static_cast<int>(params_.image_order[g])];
    for (int y = 0; y < height_; ++y) {
      const uint8_t* src = image.ptr<uint8_t>(y);
      T* out = dst + static_cast<size_t>(y) * width_ * kChannels + 3 * g;
      for (int x = 0; x < width_; ++x, src += 3, out += kChannels) {
        out[0] = lut0[src[s0]];
        out[1] = lut1[src[s1]];
        out[2] = lut2[src[s2]];
      }
    }
  }
}

Status Preprocessor::Run(const cv::Mat& left0, const cv::Mat& right0, const cv::Mat& left1,
                         const cv::Mat& right1, float* dst, size_t dst_floats) const {
  const cv::Mat* const images[4] = {&left0, &right0, &left1, &right1};
  if (Status s = Check(images, dst == nullptr ? 0 : dst_floats, "floats"); !s.ok()) return s;
  Fill(images, lut_, dst);
  return Status::Ok();
}

Status Preprocessor::RunQuantized(const cv::Mat& left0, const cv::Mat& right0, const cv::Mat& left1,
                                  const cv::Mat& right1, const QuantizedTable& table, uint8_t* dst,
                                  size_t dst_bytes) const {
  const cv::Mat* const images[4] = {&left0, &right0, &left1, &right1};
  if (Status s = Check(images, dst == nullptr ? 0 : dst_bytes, "bytes"); !s.ok()) return s;
  Fill(images, table, dst);
  return Status::Ok();
}

Result<RgbdPreprocessor> RgbdPreprocessor::Create(const RgbdPreprocessParams& params, int height,
                                                  int width) {
  if (height < 1 || width < 1 || height > 16384 || width > 16384) {
    return Status::Error("preprocessing: input size " + std::to_string(height) + "x" +
                         std::to_string(width) + " (HxW) is outside 1..16384");
  }
  std::array<bool, vocabulary::kImageSlots> seen{};
  for (size_t g = 0; g < 4; ++g) {
    const int s = static_cast<int>(params.order[g]);
    if (s < 4 || s >= vocabulary::kImageSlots) {
      return Status::Error("preprocessing: RGB-D order[" + std::to_string(g) + "] is " +
                           std::to_string(s) + ", not color0, depth0, color1 or depth1");
    }
    if (seen[static_cast<size_t>(s)]) {
      return Status::Error("preprocessing: RGB-D order names " +
                           std::string(vocabulary::ImageSlotName(params.order[g])) + " twice");
    }
    seen[static_cast<size_t>(s)] = true;
  }
  RgbdPreprocessor p;
  if (Status st = CheckColourParams(params.color_order, params.scale, params.mean, params.std,
                                    &p.lut_, &p.source_channel_);
      !st.ok()) {
    return st;
  }
  if (!std::isfinite(params.depth_mean) || !std::isfinite(params.depth_invalid)) {
    return Status::Error("preprocessing: depth_mean " + FloatText(params.depth_mean) +
                         " and depth_invalid " + FloatText(params.depth_invalid) +
                         " must be finite");
  }
  if (!std::isfinite(params.depth_std) || params.depth_std == 0) {
    return Status::Error("preprocessing: depth_std is " + FloatText(params.depth_std) +
                         "; cannot normalise");
  }
  if (!(params.depth_units_per_metre > 0) || !std::isfinite(params.depth_units_per_metre)) {
    return Status::Error("preprocessing: depth_units_per_metre is " +
                         FloatText(params.depth_units_per_metre) + "; must be positive");
  }
  p.params_ = params;
  p.height_ = height;
  p.width_ = width;
  p.depth_lut_.resize(65536);
  p.depth_lut_[0] = params.depth_invalid;
  for (size_t v = 1; v < p.depth_lut_.size(); ++v) {
    const float metres = static_cast<float>(v) / params.depth_units_per_metre;
    p.depth_lut_[v] = (metres - params.depth_mean) / params.depth_std;
  }
  return p;
}

Status RgbdPreprocessor::Run(const cv::Mat& color0, const cv::Mat& depth0, const cv::Mat& color1,
                             const cv::Mat& depth1, float* dst, size_t dst_floats) const {
  // Indexed by slot - 4: color0, depth0, color1, depth1.
  const cv::Mat* images[4] = {&color0, &depth0, &color1, &depth1};
  for (int i = 0; i < 4; ++i) {
    const cv::Mat& m = *images[i];
    const bool depth = i % 2 == 1;
    const bool type_ok =
        depth ? (m.type() == CV_16UC1 || m.type() == CV_32FC1) : m.type() == CV_8UC3;
    if (!type_ok || m.rows != height_ || m.cols != width_) {
      return Status::Error("preprocessing: " +
                           std::string(vocabulary::ImageSlotName(static_cast<ImageSlot>(i + 4))) +
                           " is " + std::to_string(m.rows) + "x" + std::to_string(m.cols) +
                           " with " + std::to_string(m.channels()) + " channels of depth " +
                           std::to_string(m.depth()) + "; expected " +
                           (depth ? "16-bit or float32 single-channel" : "8-bit BGR") + " " +
                           std::to_string(height_) + "x" + std::to_string(width_) + " (HxW)");
    }
  }
  if (dst == nullptr || dst_floats != output_floats()) {
    return Status::Error("preprocessing: destination holds " + std::to_string(dst_floats) +
                         " floats, expected " + std::to_string(output_floats()) + " (" +
                         std::to_string(height_) + " x " + std::to_string(width_) + " x 8)");
  }
  int channel = 0;
  for (ImageSlot slot : params_.order) {
    const cv::Mat& image = *images[static_cast<int>(slot) - 4];
    for (int y = 0; y < height_; ++y) {
      float* out = dst + static_cast<size_t>(y) * width_ * kChannels + channel;
      if (!vocabulary::IsDepthSlot(slot)) {
        const uint8_t* src = image.ptr<uint8_t>(y);
        for (int x = 0; x < width_; ++x, src += 3, out += kChannels) {
          out[0] = lut_[0][src[source_channel_[0]]];
          out[1] = lut_[1][src[source_channel_[1]]];
          out[2] = lut_[2][src[source_channel_[2]]];
        }
      } else if (image.type() == CV_16UC1) {
        const uint16_t* src = image.ptr<uint16_t>(y);
        for (int x = 0; x < width_; ++x, out += kChannels) out[0] = depth_lut_[src[x]];
      } else {
        const float* src = image.ptr<float>(y);
        for (int x = 0; x < width_; ++x, out += kChannels) {
          const float d = src[x];
          out[0] = std::isfinite(d) && d > 0 ? (d - params_.depth_mean) / params_.depth_std
                                             : params_.depth_invalid;
        }
      }
    }
    channel += vocabulary::SlotChannels(slot);
  }
  return Status::Ok();
}

}  // namespace sfrt::camera
