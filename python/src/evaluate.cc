#include "evaluate.h"

#include <optional>

#include "errors.h"
#include "eval/evaluate.h"
#include "model.h"
#include "sfrt/vocabulary/names.h"

namespace py = pybind11;

namespace sfrt::python {
namespace {

py::dict Evaluate(const std::shared_ptr<PyModel>& model, const std::string& dataset,
                  const py::object& size, int max_frames, bool classical,
                  const std::string& thresholds, bool allow_camera_mismatch, const std::string& isa,
                  const std::string& depth, const std::string& write_submission) {
  eval::EvalOptions options;
  options.dataset = dataset;
  if (model) {
    options.model = model->model;
    options.model_path = model->path;
  }
  CheckReadablePath(dataset, "dataset", true);
  if (thresholds != "absolute" && thresholds != "relative") {
    throw py::value_error("thresholds: expected 'absolute' or 'relative', got '" + thresholds +
                          "'");
  }
  options.thresholds =
      thresholds == "relative" ? eval::Thresholds::kRelative : eval::Thresholds::kAbsolute;
  if (max_frames < 0) throw py::value_error("max_frames: must be 0 (all) or more");
  options.max_frames = max_frames;
  options.classical = classical;
  options.allow_camera_mismatch = allow_camera_mismatch;
  options.isa = ParseIsaArgument(isa);
  const std::optional<eval::DepthSource> source =
      vocabulary::FromName<eval::DepthSource>(eval::kDepthSourceNames, depth);
  if (!source) throw py::value_error("depth: expected 'gt' or 'stereo', got '" + depth + "'");
  options.depth = *source;
  if (!write_submission.empty() && !model) {
    throw py::value_error("write_submission: writes the model's predictions; it needs a model");
  }
  options.submission_dir = write_submission;
  if (model && !size.is_none()) {
    SessionSize(*model, size, &options.model_height, &options.model_width);
  } else if (model) {  // as `sfrt eval` chooses without --size
    eval::DefaultModelSize(model->model->metadata(), &options.model_height, &options.model_width);
  } else if (!size.is_none()) {
    throw py::value_error("size: sets the model's input size; it needs a model");
  }
  std::string json;
  Status status;
  {
    py::gil_scoped_release released;
    Result<eval::EvalReport> report = eval::RunEvaluation(options);
    status = report.status();
    if (report.ok()) json = eval::FormatJson(*report);
  }
  ThrowIfError(status);
  return py::module_::import("json").attr("loads")(json);
}

}  // namespace

void BindEvaluate(py::module_& m) {
  m.def("evaluate", &Evaluate, py::arg("model"), py::arg("dataset"), py::kw_only(),
        py::arg("size") = py::none(), py::arg("max_frames") = 0, py::arg("classical") = true,
        py::arg("thresholds") = "absolute", py::arg("allow_camera_mismatch") = false,
        py::arg("isa") = "auto", py::arg("depth") = "gt", py::arg("write_submission") = "",
        R"doc(
Scores the model's scene flow against a dataset's ground truth beside the zero-flow and
classical baselines, as `sfrt eval` does, and returns the dict its --json writes:
keys sfrt, zero_flow, classical (each with epe3d, epe_x, epe_y, epe_z, acc05, acc10, outliers,
valid_pixels, frames and sequences), thresholds, gt_median_motion and the rest, number for number.

model:   a Model, or None for the baselines only.
dataset: a Scene Flow tree with camera.json (as `sfrt synth` writes).
size:    (H, W) the model runs at; None: the size a trained model records, else the dataset's.
classical=False skips the classical baseline; thresholds "absolute" (FlowNet3D's) or "relative";
allow_camera_mismatch scores a model on another camera's data (refused otherwise).
A KITTI Scene Flow 2015 tree (training/image_2, disp_occ_0, ...) is detected: each method then
also has "kitti" (D1, D2, Fl, SF outliers in percent, {bg, fg, all}, and the raw counts); depth
is the disparity the 3D flow is projected with, "gt" (an oracle depth) or "stereo";
write_submission=DIR writes the model's predictions in the devkit's encodings.
The GIL is released while it runs.
)doc");
}

}  // namespace sfrt::python
