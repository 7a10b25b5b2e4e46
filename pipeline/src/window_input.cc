#include "sfrt/pipeline/window_input.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <opencv2/imgproc.hpp>

namespace sfrt::pipeline {
namespace {

std::string SizeText(int rows, int cols) {
  return std::to_string(rows) + "x" + std::to_string(cols);
}

camera::ColorOrder Flipped(camera::ColorOrder order) {
  return order == camera::ColorOrder::kBGR ? camera::ColorOrder::kRGB : camera::ColorOrder::kBGR;
}

// "left0,right0,left1,right1".
std::string JoinOrder(const std::vector<std::string>& slots) {
  std::string out;
  for (const std::string& s : slots) out += (out.empty() ? "" : ",") + s;
  return out;
}

// The RGB-D preprocessing the metadata prescribes (colour as a stereo model's, depth normalised).
Result<camera::RgbdPreprocessParams> RgbdParamsFromMetadata(const InputDesc& desc,
                                                            float depth_units) {
  camera::RgbdPreprocessParams params;
  auto order = camera::ParseImageOrder(desc.image_order);
  if (!order.ok()) return Status::Error("the model's image order: " + order.message());
  auto color = camera::ParseColorOrder(desc.color_order);
  if (!color.ok()) return Status::Error("the model's color order: " + color.message());
  params.order = *order;
  params.color_order = *color;
  params.scale = desc.scale;
  std::copy(desc.mean, desc.mean + 3, params.mean);
  std::copy(desc.std, desc.std + 3, params.std);
  params.depth_mean = desc.depth_mean;
  params.depth_std = desc.depth_std;
  params.depth_invalid = desc.depth_invalid;
  params.depth_units_per_metre = depth_units;
  return params;
}

}  // namespace

Result<WindowInput> WindowInput::Create(const ModelMetadata& meta,
                                        const WindowInputOptions& options) {
  const InputDesc& desc = meta.input;
  WindowInput w;
  w.meta_ = meta;
  w.options_ = options;
  w.rgbd_ = desc.is_rgbd();
  if (desc.is_tensor()) {
    return Status::Error(
        "the model takes a plain tensor (its metadata names no images); feed the tensor itself");
  }
  if (w.rgbd_) {
    if (!(options.depth_units > 0) || !std::isfinite(options.depth_units)) {
      return Status::Error("depth units: must be positive, got " +
                           std::to_string(options.depth_units));
    }
    Result<camera::RgbdPreprocessParams> params = RgbdParamsFromMetadata(desc, options.depth_units);
    if (!params.ok()) return params.status();
    w.rgbd_params_ = *params;
    if (options.given == camera::ColorOrder::kRGB) {
      w.rgbd_params_.color_order = Flipped(w.rgbd_params_.color_order);
    }
    char units[32];
    std::snprintf(units, sizeof(units), "%g", static_cast<double>(options.depth_units));
    w.description_ = "2 RGB-D frames as " + JoinOrder(desc.image_order) + ", " + desc.color_order +
                     ", 16-bit depth at " + units + " per metre";
    return w;
  }
  Result<camera::PreprocessParams> params = PreprocessFromMetadata(desc);
  if (!params.ok()) return params.status();
  w.stereo_params_ = *params;
  // Images given as RGB: the model's swap (or its absence) is the other way round. The tables
  // are per fed channel, so this is exact.
  if (options.given == camera::ColorOrder::kRGB) {
    w.stereo_params_.color_order = Flipped(w.stereo_params_.color_order);
  }
  w.description_ = "4 images as " + JoinOrder(desc.image_order) + ", " + desc.color_order;
  return w;
}

Result<InputSizeChoice> WindowInput::ChooseSize(int rows, int cols) const {
  if (!rgbd_) {
    PipelineOptions asked;
    asked.height = options_.height;
    asked.width = options_.width;
    asked.allow_aspect_change = options_.allow_aspect_change;
    return ChooseInputSize(asked, meta_, rows, cols);
  }
  InputSizeChoice c;
  const bool asked = options_.height > 0 && options_.width > 0;
  c.height = asked ? options_.height : rows;
  c.width = asked ? options_.width : cols;
  c.reason = asked ? "as asked" : "the frames' size";
  return c;
}

Status WindowInput::Check(const std::array<cv::Mat, 4>& images,
                          const std::array<std::string, 4>& names, const char* rule) const {
  for (size_t i = 0; i < 4; ++i) {
    const cv::Mat& m = images[i];
    const bool depth = rgbd_ && i % 2 == 1;
    if (depth ? (m.type() != CV_16UC1 && m.type() != CV_32FC1) : m.type() != CV_8UC3) {
      return Status::Error(names[i] + " has " + std::to_string(m.channels()) + " channel(s) of " +
                           (m.depth() == CV_8U    ? "8-bit integers"
                            : m.depth() == CV_16U ? "16-bit integers"
                            : m.depth() == CV_32F ? "32-bit floats"
                                                  : "another type") +
                           (depth
                                ? "; a depth map is one channel of 16-bit integers or 32-bit floats"
                                : "; an image is 3 channels of 8 bits"));
    }
    if (m.empty()) return Status::Error(names[i] + " is empty");
    if (i > 0 && m.size() != images[0].size()) {
      return Status::Error(names[i] + " is " + SizeText(m.rows, m.cols) + " but " + names[0] +
                           " is " + SizeText(images[0].rows, images[0].cols) + " (" + rule + ")");
    }
  }
  return Status::Ok();
}

size_t WindowInput::Floats(int height, int width) const {
  const size_t channels =
      rgbd_ ? camera::RgbdPreprocessor::kChannels : camera::Preprocessor::kChannels;
  return static_cast<size_t>(height) * static_cast<size_t>(width) * channels;
}

Status WindowInput::Build(const std::array<cv::Mat, 4>& images, int height, int width,
                          std::span<float> dst) {
  return rgbd_ ? BuildRgbd(images, height, width, dst) : BuildStereo(images, height, width, dst);
}

Status WindowInput::BuildStereo(const std::array<cv::Mat, 4>& images, int height, int width,
                                std::span<float> dst) {
  if (!stereo_ || stereo_->height() != height || stereo_->width() != width) {
    auto pre = camera::Preprocessor::Create(stereo_params_, height, width);
    if (!pre.ok()) return pre.status();
    stereo_.emplace(std::move(pre).value());
  }
  const cv::Size source = images[0].size();
  const cv::Size target(width, height);
  if (source == target) {  // read in place
    return stereo_->Run(images[0], images[1], images[2], images[3], dst.data(), dst.size());
  }
  // The same resize as the pipeline's preprocess stage (INTER_AREA when shrinking, bilinear
  // otherwise), made once per source and target size.
  if (!resizer_ || resizer_->input_size() != source || resizer_->camera().size != target) {
    auto resizer = camera::StereoRectifier::CreateResizeOnly(source, target);
    if (!resizer.ok()) return resizer.status();
    resizer_.emplace(std::move(resizer).value());
  }
  for (size_t i = 0; i < 4; i += 2) {
    if (Status r = resizer_->Apply(images[i], images[i + 1], &resized_[i], &resized_[i + 1]);
        !r.ok()) {
      return r;
    }
  }
  return stereo_->Run(resized_[0], resized_[1], resized_[2], resized_[3], dst.data(), dst.size());
}

Status WindowInput::BuildRgbd(const std::array<cv::Mat, 4>& images, int height, int width,
                              std::span<float> dst) {
  if (!rgbd_pre_ || rgbd_pre_->height() != height || rgbd_pre_->width() != width) {
    auto pre = camera::RgbdPreprocessor::Create(rgbd_params_, height, width);
    if (!pre.ok()) return pre.status();
    rgbd_pre_.emplace(std::move(pre).value());
  }
  const cv::Size source = images[0].size();
  if (source == cv::Size(width, height)) {
    return rgbd_pre_->Run(images[0], images[1], images[2], images[3], dst.data(), dst.size());
  }
  const bool shrink = height < source.height || width < source.width;
  for (size_t i = 0; i < 4; ++i) {
    // Depth by the nearest sample: averaging would invent depths between surfaces (and mix in
    // the missing ones).
    const bool depth = i % 2 == 1;
    cv::resize(images[i], resized_[i], cv::Size(width, height), 0, 0,
               depth ? cv::INTER_NEAREST : (shrink ? cv::INTER_AREA : cv::INTER_LINEAR));
  }
  return rgbd_pre_->Run(resized_[0], resized_[1], resized_[2], resized_[3], dst.data(), dst.size());
}

Status CheckFiniteTensor(std::span<const float> data, int width, int channels,
                         const std::string& what) {
  // Fast path, for every call: adding 1 to an exponent field of all ones (NaN or infinity) carries
  // into the sign bit; an OR over every element of that carry is one vectorised pass. The element
  // is located only when there is one.
  uint32_t carry = 0;
  for (const float v : data) carry |= (std::bit_cast<uint32_t>(v) & 0x7f800000u) + 0x00800000u;
  if ((carry & 0x80000000u) == 0) return Status::Ok();
  const size_t c_count = static_cast<size_t>(channels);
  const size_t w_count = static_cast<size_t>(width);
  for (size_t i = 0; i < data.size(); ++i) {
    const float v = data[i];
    if (std::isfinite(v)) continue;
    const size_t c = i % c_count;
    const size_t x = i / c_count % w_count;
    const size_t y = i / c_count / w_count;
    return Status::Error(what + ": element [" + std::to_string(y) + ", " + std::to_string(x) +
                         ", " + std::to_string(c) + "] (flat index " + std::to_string(i) + ") is " +
                         (std::isnan(v) ? "NaN" : "infinite") + "; the input must be finite");
  }
  return Status::Ok();
}

}  // namespace sfrt::pipeline
