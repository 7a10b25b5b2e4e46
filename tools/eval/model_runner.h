// The model as `sfrt eval` runs it on a window of four BGR images of any size: the network input
// built as `sfrt infer` and the pipeline build it (pipeline::WindowInput: the resize to the model
// size, the model's preprocessing), one Session, and the flow resized back bilinearly to the
// images' size (its values are 3D displacements: not rescaled). Also the camera check every
// evaluation makes against the model's training camera.
#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "eval/evaluate.h"
#include "sfrt/pipeline/window_input.h"
#include "sfrt/session.h"

namespace sfrt::eval {

class ModelRunner {
 public:
  // The model of `eval` (its `model`, else loaded from `path`) planned at height x width.
  static Result<std::unique_ptr<ModelRunner>> Create(const std::string& path, int height, int width,
                                                     const EvalOptions& eval);
  const ModelMetadata& metadata() const { return model_->metadata(); }
  Isa isa() const { return session_->isa(); }
  // Flow (rows * cols * 3 floats) at the images' size for left0, right0, left1, right1.
  Result<std::vector<float>> Run(const cv::Mat* images[4]);

 private:
  ModelRunner() = default;
  std::shared_ptr<const Model> model_;
  std::unique_ptr<Session> session_;
  std::optional<pipeline::WindowInput> window_;
  int height_ = 0, width_ = 0;
  std::vector<float> input_;
  std::vector<float> output_;
};

// Empty when the dataset's camera (focal already scaled to the model's input size) is within
// kCameraTolerance of the model's training camera; else a message naming both and `source` (the
// file the dataset's camera came from).
std::string CompareCameras(const CameraDesc& model, double focal, double baseline, int height,
                           int width, const std::string& source);

// The model's runner at the report's model size (every evaluation's first frame makes it), with
// the camera check: the dataset's camera (`focal` px at `image_width`, `baseline`, read from
// `source`) scaled to the model's width against the model's training camera (CompareCameras). A
// mismatch is an error naming both, or with options.allow_camera_mismatch report->camera_note.
// Sets the report's model_name and model_training.
Result<std::unique_ptr<ModelRunner>> StartModelRunner(const EvalOptions& options, double focal,
                                                      double baseline, int image_width,
                                                      const std::string& source,
                                                      EvalReport* report);

}  // namespace sfrt::eval
