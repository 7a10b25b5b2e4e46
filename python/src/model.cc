#include "model.h"

#include <pybind11/stl.h>

#include "errors.h"
#include "sfrt/config/limits.h"
#include "sfrt/isa.h"
#include "sfrt/layer_kinds.h"

namespace py = pybind11;

namespace sfrt::python {
namespace {

const char* InputKind(const InputDesc& input) {
  return input.is_tensor() ? "tensor" : input.is_rgbd() ? "rgbd" : "stereo";
}

py::object Trained(TrainingState state) {
  if (state == TrainingState::kUnknown) return py::none();
  return py::bool_(state == TrainingState::kTrained);
}

py::dict InputInfo(const InputDesc& in) {
  py::dict d;
  d["kind"] = InputKind(in);
  d["slots"] = in.image_order;
  d["channels"] = in.channels;
  d["color_order"] = in.color_order;
  d["scale"] = in.scale;
  d["mean"] = py::make_tuple(in.mean[0], in.mean[1], in.mean[2]);
  d["std"] = py::make_tuple(in.std[0], in.std[1], in.std[2]);
  d["traced_size"] = in.traced_height > 0
                         ? py::object(py::make_tuple(in.traced_height, in.traced_width))
                         : py::object(py::none());
  if (in.is_rgbd()) {
    d["depth_mean"] = in.depth_mean;
    d["depth_std"] = in.depth_std;
    d["depth_invalid"] = in.depth_invalid;
  }
  return d;
}

// Each convolution's arithmetic, by layer name (other layers run in float32).
py::list LayerPrecisions(const Model& model) {
  py::list layers;
  for (const LayerDesc& layer : model.layers()) {
    py::dict d;
    d["name"] = layer.name;
    d["kind"] = LayerKindName(layer.kind);
    d["precision"] = PrecisionName(layer.kind == LayerKind::kConv2D ? layer.conv.precision
                                                                    : Precision::kFloat32);
    layers.append(d);
  }
  return layers;
}

py::dict Info(const PyModel& m) {
  const ModelMetadata& meta = m.model->metadata();
  py::dict d;
  d["path"] = m.path;
  d["name"] = meta.name;
  d["schema"] = std::to_string(meta.schema_major) + "." + std::to_string(meta.schema_minor);
  d["input"] = InputInfo(meta.input);
  py::dict out;
  out["channels"] = meta.output.channels;
  out["channel_names"] = meta.output.channel_names;
  out["units"] =
      meta.output.units_declared ? py::object(py::str(meta.output.units)) : py::object(py::none());
  d["output"] = out;
  if (meta.camera.focal_px > 0) {
    py::dict cam;
    cam["focal_px"] = meta.camera.focal_px;
    cam["baseline"] = meta.camera.baseline;
    cam["cx"] = meta.camera.cx;
    cam["cy"] = meta.camera.cy;
    d["training_camera"] = cam;
  } else {
    d["training_camera"] = py::none();
  }
  d["trained"] = Trained(meta.training);
  d["weights"] = WeightTypeName(meta.weight_type);
  d["precision"] = PrecisionSummary(meta);
  d["layers"] = LayerPrecisions(*m.model);
  d["parameters"] = m.model->parameter_count();
  d["file_bytes"] = m.model->file_bytes();
  return d;
}

std::string Repr(const PyModel& m) {
  const ModelMetadata& meta = m.model->metadata();
  const char* trained = meta.training == TrainingState::kTrained     ? "trained"
                        : meta.training == TrainingState::kUntrained ? "untrained"
                                                                     : "training unknown";
  return "<sfrt.Model '" + m.path + "' (" + meta.name + "): " + InputKind(meta.input) + " input, " +
         std::to_string(meta.input.channels) + " -> " + std::to_string(meta.output.channels) +
         " channels" + (meta.output.units_declared ? " in " + meta.output.units : "") + ", " +
         PrecisionSummary(meta) + ", " + trained + ">";
}

std::shared_ptr<PyModel> Load(const std::string& path) {
  CheckReadablePath(path, "model file", false);
  Result<std::shared_ptr<const Model>> loaded = [&] {
    py::gil_scoped_release released;
    return Model::LoadFile(path);
  }();
  ThrowIfError(loaded.status());
  return std::make_shared<PyModel>(PyModel{std::move(loaded).value(), path});
}

}  // namespace

void SessionSize(const PyModel& model, const py::object& size, int* height, int* width) {
  const InputDesc& in = model.model->metadata().input;
  if (size.is_none()) {
    if (model.model->metadata().training != TrainingState::kTrained || in.traced_height <= 0) {
      throw py::value_error("size: " + model.path +
                            " records no training size (it is not marked trained, or was "
                            "traced at no size); give size=(H, W)");
    }
    *height = in.traced_height;
    *width = in.traced_width;
    return;
  }
  try {
    auto hw = size.cast<std::pair<int, int>>();
    *height = hw.first;
    *width = hw.second;
  } catch (const py::cast_error&) {
    throw py::value_error("size: expected (H, W), two integers, got " +
                          py::repr(size).cast<std::string>());
  }
  if (std::string problem = config::CheckSize(config::kInputSide, "size", *height, *width);
      !problem.empty()) {
    throw py::value_error(problem);
  }
}

int ThreadsArgument(int threads) {
  if (std::string problem = config::CheckRange(config::kThreads, "threads", threads);
      !problem.empty()) {
    throw py::value_error(problem);
  }
  return threads;
}

Isa ParseIsaArgument(const std::string& name) {
  Isa isa = Isa::kAuto;
  if (!ParseIsa(name, &isa)) {
    throw py::value_error("isa: '" + name + "' is not one of " + IsaNameList(true));
  }
  if (isa != Isa::kAuto && !IsaSupported(isa)) {
    throw py::value_error("isa: '" + name + "': this CPU (or this build) cannot run it; it runs " +
                          SupportedIsaList());
  }
  return isa;
}

void BindModel(py::module_& m) {
  py::class_<PyModel, std::shared_ptr<PyModel>>(m, "Model", R"doc(
A SceneEDNet model file (.sfrt), loaded and verified (checksums, shapes, every layer).

    m = sfrt.Model("models/sceneednet-default.sfrt")

Raises FileNotFoundError (or PermissionError) naming the path when the file cannot be read, and
sfrt.Error with the loader's message when it is not a valid model file. A Model is immutable:
any number of Sessions, on any threads, may share one; each keeps it alive.
)doc")
      .def(py::init(&Load), py::arg("path"), "Loads and verifies the model file at `path`.")
      .def_property_readonly(
          "path", [](const PyModel& p) { return p.path; }, "The file the model was loaded from.")
      .def_property_readonly("info", &Info, R"doc(
What the model file says about itself, as a dict:
  name, schema, path
  input:  kind ("stereo", "rgbd" or "tensor"), slots (the images in channel order), channels,
          color_order, scale, mean, std (fed value = (pixel * scale - mean[c]) / std[c]),
          traced_size ((H, W) it was traced and trained at, or None)
  output: channels, channel_names, units (None when the file does not state them)
  training_camera: focal_px, baseline, cx, cy at the traced size (None when not recorded)
  trained: True, False, or None (files before schema 1.2 do not say)
  weights (storage type), precision (summary), layers (name, kind, precision of each layer)
  parameters, file_bytes
)doc")
      .def("__repr__", &Repr);
}

}  // namespace sfrt::python
