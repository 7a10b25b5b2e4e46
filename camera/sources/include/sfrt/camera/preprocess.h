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
#include <cstdint>
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

// "left0" ... "right1", "color0" ... "depth1" (the model file's spelling); the errors say what
// was given.
Result<ImageSlot> ParseImageSlot(const std::string& name);
// Exactly four names: a permutation of the four stereo slots or of the four RGB-D slots.
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

  // The uint8 input path (an int8 model's first convolutions read uint8, sfrt::Session's
  // RunQuantized): `quantize` applied to each of the 3 x 256 values Run() can feed, so that
  // RunQuantized() writes quantize(what Run() would write), bit for bit. camera/ knows no
  // runtime: the caller passes the runtime's quantiser (sfrt::QuantizeInput with the session's
  // InputQuantization).
  using QuantizedTable = std::array<std::array<uint8_t, 256>, 3>;
  template <typename Quantize>
  QuantizedTable Tabulate(Quantize quantize) const {
    QuantizedTable table{};
    for (size_t c = 0; c < 3; ++c) {
      for (size_t v = 0; v < 256; ++v) table[c][v] = quantize(lut_[c][v]);
    }
    return table;
  }
  // As Run(), writing the quantised values through `table` (Tabulate) into dst: height*width*12
  // bytes, owned by the caller; dst_bytes is checked against output_floats().
  Status RunQuantized(const cv::Mat& left0, const cv::Mat& right0, const cv::Mat& left1,
                      const cv::Mat& right1, const QuantizedTable& table, uint8_t* dst,
                      size_t dst_bytes) const;

  size_t output_floats() const { return static_cast<size_t>(height_) * width_ * kChannels; }
  int height() const { return height_; }
  int width() const { return width_; }

 private:
  Preprocessor() = default;
  Status Check(const cv::Mat* const (&images)[4], size_t dst_elements, const char* unit) const;
  template <typename T>
  void Fill(const cv::Mat* const (&images)[4], const std::array<std::array<T, 256>, 3>& lut,
            T* dst) const;

  PreprocessParams params_;
  int height_ = 0;
  int width_ = 0;
  // lut_[c][v]: value fed on channel c (model order) for 8-bit pixel value v.
  std::array<std::array<float, 256>, 3> lut_{};
  std::array<int, 3> source_channel_{};  // BGR index read for fed channel c
};

// Network input from two RGB-D frames (schema 1.11): H x W x 8 float32, NHWC, the colour image
// and depth map of t and t+1 in the model's order (colour 3 channels, as Preprocessor feeds an
// image; depth 1 channel). A depth map is CV_16UC1, holding depth * depth_units_per_metre (1000:
// millimetres, as most RGB-D cameras give it; 5000: the TUM RGB-D benchmark), or CV_32FC1 in
// metres. Depth d in metres is fed as (d - depth_mean) / depth_std; a pixel without depth (0,
// negative or not finite) as depth_invalid. Create() validates and tabulates (every 16-bit value
// too); Run() allocates nothing. Thread-safety as Preprocessor.
struct RgbdPreprocessParams {
  std::array<ImageSlot, 4> order = vocabulary::kDefaultRgbdOrder;
  ColorOrder color_order = ColorOrder::kBGR;
  float scale = 1.0f;
  float mean[3] = {0, 0, 0};
  float std[3] = {1, 1, 1};
  float depth_mean = 0.0f;
  float depth_std = 1.0f;
  float depth_invalid = 0.0f;
  float depth_units_per_metre = 1000.0f;  // 16-bit depth maps only
};

class RgbdPreprocessor {
 public:
  static constexpr int kChannels = 8;

  static Result<RgbdPreprocessor> Create(const RgbdPreprocessParams& params, int height, int width);

  // Colour images: CV_8UC3 BGR; depth maps: CV_16UC1 or CV_32FC1; all height x width (any row
  // stride). dst: height*width*8 floats, owned by the caller; dst_floats is checked against it.
  Status Run(const cv::Mat& color0, const cv::Mat& depth0, const cv::Mat& color1,
             const cv::Mat& depth1, float* dst, size_t dst_floats) const;

  size_t output_floats() const { return static_cast<size_t>(height_) * width_ * kChannels; }
  int height() const { return height_; }
  int width() const { return width_; }

 private:
  RgbdPreprocessor() = default;

  RgbdPreprocessParams params_;
  int height_ = 0;
  int width_ = 0;
  std::array<std::array<float, 256>, 3> lut_{};  // as Preprocessor's
  std::array<int, 3> source_channel_{};
  std::vector<float> depth_lut_;  // fed value of each 16-bit depth
};

}  // namespace sfrt::camera
