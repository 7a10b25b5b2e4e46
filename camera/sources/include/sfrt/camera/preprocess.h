// Network input from two consecutive stereo pairs: H x W x 12 float32, NHWC, in the model's
// image order and colour order, with value = (pixel * scale - mean[c]) / std[c].
//
// The parameters mirror the model file's input metadata (sfrt::InputDesc) as plain values, so
// camera/ stays independent of runtime/; tools/ copies them over from sfrt::ModelMetadata.
// c indexes the channel as fed: with RGB order, c = 0 is red.
//
// Create() validates the parameters and tabulates the 3 x 256 possible output values (computed
// with exactly the formula above in float, so results are bit-identical to evaluating it per
// pixel). Run() only looks values up: no allocation, no per-frame parameter checks beyond sizes.
// Ownership: the caller owns the destination buffer. Thread-safety: Run() is const and may be
// called from several threads at once on different buffers.
#pragma once

#include <array>
#include <cstddef>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "sfrt/camera/status.h"
#include "sfrt/vocabulary/stereo_input.h"

namespace sfrt::camera {

using vocabulary::ColorOrder;  // the shared words (sfrt/vocabulary/stereo_input.h)
using vocabulary::ImageSlot;

struct PreprocessParams {
  // image_order[g] is the image written to channels 3g..3g+2.
  std::array<ImageSlot, 4> image_order = vocabulary::kDefaultImageOrder;
  ColorOrder color_order = ColorOrder::kBGR;
  float scale = 1.0f;
  float mean[3] = {0, 0, 0};
  float std[3] = {1, 1, 1};
};

// "left0" "right0" "left1" "right1" (the model file's spelling); the errors say what was given.
Result<ImageSlot> ParseImageSlot(const std::string& name);
// Exactly four names forming a permutation of the four slots.
Result<std::array<ImageSlot, 4>> ParseImageOrder(const std::vector<std::string>& names);
// "BGR" or "RGB".
Result<ColorOrder> ParseColorOrder(const std::string& name);

class Preprocessor {
 public:
  static constexpr int kChannels = 12;

  // height x width: the network input size (the images given to Run() must have it).
  static Result<Preprocessor> Create(const PreprocessParams& params, int height, int width);

  // Images: CV_8UC3 BGR of height x width (any row stride). dst: height*width*12 floats, owned by
  // the caller; dst_floats is checked against it.
  Status Run(const cv::Mat& left0, const cv::Mat& right0, const cv::Mat& left1,
             const cv::Mat& right1, float* dst, size_t dst_floats) const;

  size_t output_floats() const { return static_cast<size_t>(height_) * width_ * kChannels; }
  int height() const { return height_; }
  int width() const { return width_; }

 private:
  Preprocessor() = default;

  PreprocessParams params_;
  int height_ = 0;
  int width_ = 0;
  // lut_[c][v]: value fed on channel c (model order) for 8-bit pixel value v.
  std::array<std::array<float, 256>, 3> lut_{};
  std::array<int, 3> source_channel_{};  // BGR index read for fed channel c
};

}  // namespace sfrt::camera
