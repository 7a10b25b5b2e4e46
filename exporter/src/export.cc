// Export: import, set the metadata, serialise and verify, quantise, check (export.h).
#include "sfrt/exporter/export.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <utility>
#include <variant>

#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/sfrt_importer.h"
#include "sfrt/shapes.h"
#include "sfrt/vocabulary/stereo_input.h"

namespace sfrt::exporter {
namespace {

// The flags that describe the depth maps of RGB-D frames, and those that describe images.
struct GivenFlag {
  const char* flag;
  bool given;
};

bool IsRgbdOrder(const std::vector<ImageSlot>& order) {
  return !order.empty() && vocabulary::IsRgbdSlot(order.front());
}

int OrderChannels(const std::vector<ImageSlot>& order) {
  int channels = 0;
  for (ImageSlot slot : order) channels += vocabulary::SlotChannels(slot);
  return channels;
}

// The kind the metadata asks for before any check: a .sfrt source without --input-kind keeps
// what its file says; auto is the kind of the image order when the channel count fits it.
InputKindChoice RequestedKind(const MetadataChanges& changes, const ModelSpec& spec,
                              bool sfrt_source) {
  if (sfrt_source && !changes.input_kind) {
    return spec.input.image_order.empty()        ? InputKindChoice::kTensor
           : IsRgbdOrder(spec.input.image_order) ? InputKindChoice::kRgbd
                                                 : InputKindChoice::kImages;
  }
  const InputKindChoice kind = changes.input_kind.value_or(InputKindChoice::kAuto);
  if (kind != InputKindChoice::kAuto) return kind;
  const std::vector<ImageSlot> order = changes.image_order.value_or(std::vector<ImageSlot>{});
  const int wanted = order.empty() ? static_cast<int>(3 * vocabulary::kDefaultImageOrder.size())
                                   : OrderChannels(order);
  return spec.input.channels != wanted ? InputKindChoice::kTensor
         : IsRgbdOrder(order)          ? InputKindChoice::kRgbd
                                       : InputKindChoice::kImages;
}

// The input kind asked for, checked against the network's channel count, the image order and
// the flags given for another kind. Never kAuto.
Result<InputKindChoice> ChooseInputKind(const ExportOptions& options, const ModelSpec& spec,
                                        bool sfrt_source) {
  const MetadataChanges& changes = options.metadata;
  const InputKindChoice kind = RequestedKind(changes, spec, sfrt_source);
  const int channels = spec.input.channels;
  const bool rgbd = kind == InputKindChoice::kRgbd;
  if (changes.image_order && !changes.image_order->empty() && kind != InputKindChoice::kTensor &&
      IsRgbdOrder(*changes.image_order) != rgbd) {
    return Status::Error("--image-order '" + changes.image_order_text + "' names " +
                         (rgbd ? "stereo images; --input-kind rgbd takes C0,D0,C1,D1"
                               : "RGB-D frames; give --input-kind rgbd for them"));
  }
  if (!rgbd) {
    const GivenFlag depth_flags[] = {{"--depth-mean", changes.depth_mean.has_value()},
                                     {"--depth-std", changes.depth_std.has_value()},
                                     {"--depth-invalid", changes.depth_invalid.has_value()}};
    for (const GivenFlag& f : depth_flags) {
      if (!f.given) continue;
      return Status::Error(std::string(f.flag) +
                           " describes the depth maps of RGB-D frames, but the input is " +
                           (kind == InputKindChoice::kImages ? "stereo images" : "a plain tensor") +
                           "; give --input-kind rgbd for RGB-D frames");
    }
  }
  if (kind != InputKindChoice::kTensor) {
    const int wanted = rgbd ? 8 : 12;
    if (channels == wanted) return kind;
    return Status::Error(options.source + ": the network's input has " + std::to_string(channels) +
                         " channels; --input-kind " + std::string(InputKindChoiceName(kind)) +
                         " takes " + std::to_string(wanted) +
                         (rgbd ? " (colour and depth of two frames: 3 + 1 + 3 + 1)"
                               : " (3 per image of --image-order, default L0,R0,L1,R1)"));
  }
  const GivenFlag image_flags[] = {{"--image-order", changes.image_order.has_value()},
                                   {"--color-order", changes.color_order.has_value()},
                                   {"--scale", changes.scale.has_value()},
                                   {"--mean", changes.mean.has_value()},
                                   {"--std", changes.std.has_value()}};
  for (const GivenFlag& f : image_flags) {
    if (!f.given) continue;
    return Status::Error(
        std::string(f.flag) + " describes image inputs, but the input is a " +
        std::to_string(channels) + "-channel plain tensor (--input-kind " +
        std::string(InputKindChoiceName(changes.input_kind.value_or(InputKindChoice::kAuto))) +
        "); give --input-kind images or rgbd for images");
  }
  return InputKindChoice::kTensor;
}

// Sets `field` to the value given, or (not a .sfrt source) to the default.
template <typename T>
void Apply(const std::optional<T>& given, const T& default_value, bool sfrt_source, T* field) {
  if (given) {
    *field = *given;
  } else if (!sfrt_source) {
    *field = default_value;
  }
}

// The image input's description: its order, colour order and pixel transform (depth too for
// RGB-D frames); a plain tensor's is the identity.
void ApplyInputChanges(const MetadataChanges& changes, InputKindChoice kind, bool sfrt_source,
                       InputSpec* input) {
  const InputSpec defaults;
  if (kind == InputKindChoice::kTensor) {
    if (input->name == defaults.name) input->name = "tensor";
    input->image_order.clear();
    input->color_order = defaults.color_order;
    input->scale = defaults.scale;
    input->mean = defaults.mean;
    input->std = defaults.std;
    input->depth_mean = defaults.depth_mean;
    input->depth_std = defaults.depth_std;
    input->depth_invalid = defaults.depth_invalid;
    return;
  }
  const bool rgbd = kind == InputKindChoice::kRgbd;
  std::vector<ImageSlot> order = changes.image_order.value_or(std::vector<ImageSlot>{});
  if (order.empty()) {
    order = rgbd ? std::vector<ImageSlot>(vocabulary::kDefaultRgbdOrder.begin(),
                                          vocabulary::kDefaultRgbdOrder.end())
                 : defaults.image_order;
  }
  if (!sfrt_source || changes.image_order || changes.input_kind) input->image_order = order;
  Apply(changes.color_order, defaults.color_order, sfrt_source, &input->color_order);
  Apply(changes.scale, defaults.scale, sfrt_source, &input->scale);
  Apply(changes.mean, defaults.mean, sfrt_source, &input->mean);
  Apply(changes.std, defaults.std, sfrt_source, &input->std);
  // Stereo images have no depth flags given (ChooseInputKind refuses them), so they keep the
  // depth fields at their defaults.
  Apply(changes.depth_mean, defaults.depth_mean, sfrt_source, &input->depth_mean);
  Apply(changes.depth_std, defaults.depth_std, sfrt_source, &input->depth_std);
  Apply(changes.depth_invalid, defaults.depth_invalid, sfrt_source, &input->depth_invalid);
}

Status ApplyMetadata(const ExportOptions& options, bool sfrt_source, ModelSpec* spec) {
  Result<InputKindChoice> kind = ChooseInputKind(options, *spec, sfrt_source);
  if (!kind.ok()) return kind.status();
  const MetadataChanges& changes = options.metadata;
  ApplyInputChanges(changes, *kind, sfrt_source, &spec->input);
  const ModelSpec defaults;
  if (changes.name && !changes.name->empty()) spec->name = *changes.name;
  Apply(changes.focal_px, defaults.camera.focal_px, sfrt_source, &spec->camera.focal_px);
  Apply(changes.baseline, defaults.camera.baseline, sfrt_source, &spec->camera.baseline);
  Apply(changes.cx, defaults.camera.cx, sfrt_source, &spec->camera.cx);
  Apply(changes.cy, defaults.camera.cy, sfrt_source, &spec->camera.cy);
  Apply(changes.units, defaults.output.units, sfrt_source, &spec->output.units);
  Apply(changes.training, defaults.training, sfrt_source, &spec->training);
  return Status::Ok();
}

// The source read into a ModelSpec, with the import's notes.
Status Import(const ExportOptions& options, SourceFormat format, ExportResult* result,
              ModelSpec* spec) {
  if (format == SourceFormat::kKeras) {
    Result<KerasImportResult> imported = ImportKerasH5(options.source, options.keras);
    if (!imported.ok()) return imported.status();
    *spec = std::move(imported->spec);
    result->notes = std::move(imported->notes);
    return Status::Ok();
  }
  Result<ModelSpec> imported = format == SourceFormat::kSfrt
                                   ? ImportSfrt(options.source)
                                   : ImportOnnx(options.source, options.onnx);
  if (!imported.ok()) return imported.status();
  *spec = std::move(imported).value();
  if (format == SourceFormat::kSfrt) {
    const bool quantise = options.precision == PrecisionChange::kQuantize;
    result->notes.push_back(std::string(quantise ? "quantised from a .sfrt file: layers and "
                                                   "float32 weights from "
                                                 : "rewritten from a .sfrt file: weights and "
                                                   "layers unchanged, metadata from ") +
                            options.source + (quantise ? ", its metadata" : "") +
                            " except the flags given");
  }
  return Status::Ok();
}

// A precision change starts from float32 convolutions only.
Status CheckFloat32(const ExportOptions& options, const ModelSpec& spec) {
  if (options.precision == PrecisionChange::kNone) return Status::Ok();
  for (const LayerSpec& layer : spec.layers) {
    const auto* conv = std::get_if<ConvSpec>(&layer);
    if (conv == nullptr || conv->precision == Precision::kFloat32) continue;
    return Status::Error(options.source + ": layer '" + conv->name + "' is already " +
                         PrecisionName(conv->precision) +
                         "; --precision converts a float32 model (export from the float32 "
                         "source, or drop --precision to rewrite metadata)");
  }
  return Status::Ok();
}

// PrecisionChange::kBFloat16: marks every convolution that has a bf16 form.
Status MarkBFloat16(const ExportOptions& options, ModelSpec* spec, ExportResult* result) {
  for (LayerSpec& layer : spec->layers) {
    auto* conv = std::get_if<ConvSpec>(&layer);
    if (conv == nullptr) continue;
    ++result->convolutions;
    if (!ReducibleConv(*conv)) continue;
    conv->precision = Precision::kBFloat16;
    ++result->bf16_convolutions;
  }
  if (result->bf16_convolutions > 0) return Status::Ok();
  return Status::Error(options.source + ": no convolution has a bf16 form (" +
                       std::to_string(result->convolutions) +
                       " found; dilated and grouped ones run in fp32 only): drop --precision");
}

// Serialises `spec` and loads the bytes back exactly as a deployment would load them.
Status SerializeAndVerify(const ExportOptions& options, const ModelSpec& spec, const char* what,
                          ExportResult* result) {
  Result<std::vector<uint8_t>> bytes = SerializeModel(spec);
  if (!bytes.ok()) return Status::Error(options.source + ": " + bytes.message());
  result->bytes = std::move(bytes).value();
  Result<std::shared_ptr<const Model>> loaded = Model::LoadBuffer(
      result->bytes.data(), result->bytes.size(), BufferOwnership::kCopy, {}, options.destination);
  if (!loaded.ok()) {
    return Status::Error(std::string("the ") + what +
                         " model does not verify, nothing written: " + loaded.message());
  }
  result->model = *loaded;
  return Status::Ok();
}

// PrecisionChange::kQuantize: reads the calibration frames for the verified float32 model and
// quantises `spec`.
Status QuantizeStep(const ExportOptions& options, ModelSpec* spec, ExportResult* result) {
  if (!options.calibration) return Status::Error(options.calibration_name + ": no reader");
  Result<CalibrationSet> data =
      options.calibration(result->model->metadata().input, &result->calibration_described);
  if (!data.ok()) return data.status();
  Result<QuantizeResult> quantised = Quantize(*spec, *data, options.quantize);
  if (!quantised.ok()) return Status::Error(options.calibration_name + ": " + quantised.message());
  *spec = std::move(quantised->spec);
  result->calibration = std::move(quantised->calibration);
  result->auto_steps = std::move(quantised->auto_steps);
  return Status::Ok();
}

// The output's shape at the traced size, when the file records one.
Status TracedShape(ExportResult* result) {
  const InputDesc& input = result->model->metadata().input;
  if (input.traced_height <= 0 || input.traced_width <= 0) return Status::Ok();
  Result<std::vector<LayerGeometry>> geometry =
      InferGeometry(*result->model, input.traced_height, input.traced_width);
  if (!geometry.ok() || geometry->empty()) {
    return Status::Error(
        "the converted model has no valid shapes at its traced size, nothing written: " +
        (geometry.ok() ? std::string("no layers") : geometry.message()));
  }
  result->traced_output = geometry->back().output;
  return Status::Ok();
}

// The steps, each on what the one before made; stops at the first failure.
Status RunSteps(const ExportOptions& options, ExportResult* result) {
  Result<SourceFormat> format = SourceFormatOf(options.source);
  if (!format.ok()) return format.status();
  const bool sfrt_source = *format == SourceFormat::kSfrt;
  ModelSpec spec;
  if (Status s = Import(options, *format, result, &spec); !s.ok()) return s;
  if (options.weights) {
    spec.weight_type = *options.weights;
  } else if (!sfrt_source) {
    spec.weight_type = WeightType::kFloat32;
  }
  if (Status s = CheckFloat32(options, spec); !s.ok()) return s;
  if (options.precision == PrecisionChange::kBFloat16) {
    if (Status s = MarkBFloat16(options, &spec, result); !s.ok()) return s;
  }
  if (Status s = ApplyMetadata(options, sfrt_source, &spec); !s.ok()) return s;
  if (Status s = SerializeAndVerify(options, spec, "converted", result); !s.ok()) return s;
  if (options.precision == PrecisionChange::kQuantize) {
    if (Status s = QuantizeStep(options, &spec, result); !s.ok()) return s;
    if (Status s = SerializeAndVerify(options, spec, "quantised", result); !s.ok()) return s;
  }
  if (Status s = TracedShape(result); !s.ok()) return s;
  if (options.check.kind == CheckOptions::Kind::kNone) return Status::Ok();
  CheckOptions check = options.check;
  if (!(check.tolerance > 0)) {
    check.tolerance =
        options.weights.value_or(WeightType::kFloat32) == WeightType::kFloat16 ? 1e-2 : 1e-4;
  }
  result->check.emplace();
  if (Status s = CheckModel(result->model, check, &*result->check); !s.ok()) {
    return Status::Error(s.message() + "; nothing written to " + options.destination);
  }
  return Status::Ok();
}

std::string Lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

}  // namespace

Result<SourceFormat> SourceFormatOf(const std::string& path) {
  const std::string ext = Lower(std::filesystem::path(path).extension().string());
  if (ext == ".onnx") return SourceFormat::kOnnx;
  if (ext == ".h5" || ext == ".hdf5") return SourceFormat::kKeras;
  if (ext == ".sfrt") return SourceFormat::kSfrt;
  if (ext == ".keras") {
    return Status::Error(path +
                         ": Keras 3 .keras archives are not supported; save the model from "
                         "Keras 2 / tf.keras as HDF5 (model.save('model.h5')) and pass that");
  }
  return Status::Error(path + ": unsupported input format '" +
                       (ext.empty() ? std::string("(no extension)") : ext) +
                       "' (supported: .onnx, Keras 2 .h5/.hdf5, .sfrt to rewrite metadata)");
}

std::optional<InputKindChoice> ParseInputKindChoice(std::string_view name) {
  for (size_t i = 0; i < kInputKindChoiceNames.size(); ++i) {
    if (kInputKindChoiceNames[i] == name) return static_cast<InputKindChoice>(i);
  }
  return std::nullopt;
}

ExportResult Export(const ExportOptions& options) {
  ExportResult result;
  result.status = RunSteps(options, &result);
  return result;
}

}  // namespace sfrt::exporter
