// One window's network input from images a caller holds in memory: `sfrt infer` (images read
// from files) and the Python package (numpy arrays) build it here, with the resize and the
// preprocessing the pipeline's preprocess stage applies to a replay (the size ChooseInputSize
// picks, camera::StereoRectifier's resize-only map, camera::Preprocessor with the model's
// metadata; RGB-D frames through camera::RgbdPreprocessor), so the three agree bit for bit.
//
//   auto input = sfrt::pipeline::WindowInput::Create(model->metadata(), {});
//   cv::Mat images[4] = {left0, right0, left1, right1};        // 8-bit, 3 channels, one size
//   auto size = input->ChooseSize(left0.rows, left0.cols);     // as `sfrt run` chooses it
//   std::vector<float> x(input->Floats(size->height, size->width));
//   input->Build(images, size->height, size->width, x);
//
// Ownership: the caller keeps the images and the destination. Images of the network input size
// are read in place (any row stride); others are resized into buffers the WindowInput keeps and
// reuses while the image size stays the same. Thread-safety: Build() changes those buffers; one
// WindowInput per thread.
#pragma once

#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>

#include "sfrt/camera/preprocess.h"
#include "sfrt/camera/rectifier.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/status.h"

namespace sfrt::pipeline {

struct WindowInputOptions {
  // The asked network input size; 0: ChooseInputSize's default (the size a trained model
  // records, else the images'). RGB-D frames: the asked size, else their own.
  int height = 0;
  int width = 0;
  bool allow_aspect_change = false;  // ChooseInputSize's
  // The channel order of the colour images given: BGR as OpenCV decodes them, RGB as PIL and
  // imageio do. The model's own order (its metadata) is applied after.
  camera::ColorOrder given = camera::ColorOrder::kBGR;
  float depth_units = 1000.0f;  // RGB-D: 16-bit depth values per metre
};

class WindowInput {
 public:
  // For `meta`'s stereo or RGB-D input (a plain-tensor model takes no images: an error). Errors
  // name the metadata field and value.
  static Result<WindowInput> Create(const ModelMetadata& meta, const WindowInputOptions& options);

  // The network input size for images of rows x cols, and why (stereo: ChooseInputSize; RGB-D:
  // the asked size, else the frames').
  Result<InputSizeChoice> ChooseSize(int rows, int cols) const;

  // Checks the four images of a window before anything is built: colour images 8-bit with 3
  // channels; RGB-D depth maps one channel of 16-bit integers or 32-bit floats; all of the first
  // one's size. names[i] names image i in the messages (e.g. "--left1 image 'b.png'" or
  // "left1"); `rule` ends the size message.
  Status Check(const std::array<cv::Mat, 4>& images, const std::array<std::string, 4>& names,
               const char* rule) const;

  // Floats of the network input at height x width.
  size_t Floats(int height, int width) const;

  // Resizes the four images (checked) to height x width as the pipeline does (stereo: INTER_AREA
  // when shrinking, bilinear otherwise; RGB-D depth by the nearest sample) and preprocesses them
  // into dst (Floats(height, width) floats, height x width x channels). Images in the model's
  // slot order of the input kind: left0, right0, left1, right1 or color0, depth0, color1, depth1.
  Status Build(const std::array<cv::Mat, 4>& images, int height, int width, std::span<float> dst);

  bool rgbd() const { return rgbd_; }
  // "4 images as left0,right0,left1,right1, RGB" and the like, for reports.
  const std::string& description() const { return description_; }

 private:
  WindowInput() = default;
  Status BuildStereo(const std::array<cv::Mat, 4>& images, int height, int width,
                     std::span<float> dst);
  Status BuildRgbd(const std::array<cv::Mat, 4>& images, int height, int width,
                   std::span<float> dst);

  ModelMetadata meta_;
  WindowInputOptions options_;
  bool rgbd_ = false;
  std::string description_;
  camera::PreprocessParams stereo_params_;
  camera::RgbdPreprocessParams rgbd_params_;
  // Made for the last size asked (remade when it changes).
  std::optional<camera::Preprocessor> stereo_;
  std::optional<camera::RgbdPreprocessor> rgbd_pre_;
  std::optional<camera::StereoRectifier> resizer_;
  std::array<cv::Mat, 4> resized_;  // the resized images, reused
};

// A network input given as a tensor (rows x width x channels floats) must be finite: a NaN or
// infinity would only come out as a NaN flow. The error names the first one as
// "<what>: element [y, x, c] (flat index i) is NaN; the input must be finite".
Status CheckFiniteTensor(std::span<const float> data, int width, int channels,
                         const std::string& what);

}  // namespace sfrt::pipeline
