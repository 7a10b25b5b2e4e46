#include "eval/model_runner.h"

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "sfrt/session.h"

namespace sfrt::eval {
namespace {

std::string Fmt(double v, const char* format) {
  char buf[48];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

// The model's input and output as `sfrt eval` feeds and reads them: four 3-channel images in,
// 3 channels at the input size out.
Status CheckEvalModel(const std::string& path, const Model& model, const Session& session,
                      int height, int width) {
  const InputDesc& in = model.metadata().input;
  if (in.is_rgbd()) {
    return Status::Error(path +
                         ": the model reads two RGB-D frames, and sfrt eval feeds stereo pairs "
                         "(the Scene Flow datasets' layout); run it with sfrt infer --color0 "
                         "--depth0 --color1 --depth1");
  }
  if (in.channels != 12 || in.image_order.size() != 4) {
    return Status::Error(path + ": the model takes " + std::to_string(in.channels) +
                         " channels as " + std::to_string(in.image_order.size()) +
                         " images; sfrt eval feeds 4 images of 3 channels");
  }
  Result<TensorShape> shape = session.OutputShape(height, width);
  if (!shape.ok()) return shape.status();
  if (shape->channels != 3 || shape->height != height || shape->width != width) {
    return Status::Error(path + ": output is " + std::to_string(shape->height) + "x" +
                         std::to_string(shape->width) + "x" + std::to_string(shape->channels) +
                         " for a " + std::to_string(height) + "x" + std::to_string(width) +
                         " input; expected 3 channels at the input size");
  }
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<ModelRunner>> ModelRunner::Create(const std::string& path, int height,
                                                         int width, const EvalOptions& eval) {
  auto runner = std::unique_ptr<ModelRunner>(new ModelRunner());
  if (eval.model) {
    runner->model_ = eval.model;
  } else {
    Result<std::shared_ptr<const Model>> model = Model::LoadFile(path);
    if (!model.ok()) return model.status();
    runner->model_ = std::move(model).value();
  }
  SessionOptions options;
  options.max_height = height;
  options.max_width = width;
  options.isa = eval.isa;
  options.tuning = eval.tuning;
  Result<std::unique_ptr<Session>> session = Session::Create(runner->model_, options);
  if (!session.ok()) return session.status();
  runner->session_ = std::move(session).value();
  if (Status ok = CheckEvalModel(path, *runner->model_, *runner->session_, height, width);
      !ok.ok()) {
    return ok;
  }
  pipeline::WindowInputOptions input;
  input.height = height;
  input.width = width;
  Result<pipeline::WindowInput> window =
      pipeline::WindowInput::Create(runner->model_->metadata(), input);
  if (!window.ok()) return Status::Error(path + ": " + window.message());
  runner->window_.emplace(std::move(window).value());
  runner->height_ = height;
  runner->width_ = width;
  runner->input_.resize(runner->window_->Floats(height, width));
  runner->output_.resize(static_cast<size_t>(height) * width * 3);
  return runner;
}

Result<std::vector<float>> ModelRunner::Run(const cv::Mat* images[4]) {
  const std::array<cv::Mat, 4> window = {*images[0], *images[1], *images[2], *images[3]};
  if (Status built = window_->Build(window, height_, width_, input_); !built.ok()) return built;
  Status run = session_->Run(input_, height_, width_, output_);
  if (!run.ok()) return run;
  const int src_h = images[0]->rows;
  const int src_w = images[0]->cols;
  if (src_h == height_ && src_w == width_) return output_;
  cv::Mat small(height_, width_, CV_32FC3, output_.data());
  cv::Mat big;
  cv::resize(small, big, cv::Size(src_w, src_h), 0, 0, cv::INTER_LINEAR);
  return std::vector<float>(big.ptr<float>(0), big.ptr<float>(0) + big.total() * 3);
}

Result<std::unique_ptr<ModelRunner>> StartModelRunner(const EvalOptions& options, double focal,
                                                      double baseline, int image_width,
                                                      const std::string& source,
                                                      EvalReport* report) {
  Result<std::unique_ptr<ModelRunner>> created =
      ModelRunner::Create(options.model_path, report->model_height, report->model_width, options);
  if (!created.ok()) return created.status();
  const ModelMetadata& meta = (*created)->metadata();
  report->model_name = meta.name;
  report->model_training = meta.training;
  const double sx = static_cast<double>(report->model_width) / image_width;
  const std::string mismatch = CompareCameras(meta.camera, focal * sx, baseline,
                                              report->model_height, report->model_width, source);
  if (mismatch.empty()) return created;
  if (!options.allow_camera_mismatch) {
    return Status::Error(mismatch +
                         "; evaluate on data from the model's camera, or pass "
                         "--allow-camera-mismatch to score it anyway");
  }
  report->camera_note = mismatch + ": its predictions are in its own camera's units";
  return created;
}

std::string CompareCameras(const CameraDesc& model, double focal, double baseline, int height,
                           int width, const std::string& source) {
  auto relative = [](double a, double b) { return std::fabs(a - b) / std::fabs(b); };
  const double df = relative(focal, model.focal_px);
  const double db = relative(baseline, model.baseline);
  if (!(df > kCameraTolerance) && !(db > kCameraTolerance)) return "";
  return "camera mismatch: " + source + " gives f " + Fmt(focal, "%g") + " px at the model's " +
         std::to_string(height) + "x" + std::to_string(width) + " and baseline " +
         Fmt(baseline, "%g") + ", but the model's training camera has f " +
         Fmt(model.focal_px, "%g") + " px and baseline " + Fmt(model.baseline, "%g") + " (off by " +
         Fmt(100 * df, "%.0f") + "% and " + Fmt(100 * db, "%.0f") + "%; tolerance " +
         Fmt(100 * kCameraTolerance, "%.0f") + "%)";
}

}  // namespace sfrt::eval
