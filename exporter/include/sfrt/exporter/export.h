// Export: a trained network (ONNX, Keras 2 HDF5, or a .sfrt file to rewrite) -> the bytes of a
// verified .sfrt model file. One call does the whole job `sfrt export` does: import, set the
// metadata, serialise, load the bytes back and verify them as a deployment would, quantise, and
// run the checks asked for. It writes nothing: the caller writes `ExportResult::bytes` (the
// command atomically) only when the status is ok, so a model that fails a step never reaches the
// disk.
//
// Messages name what was given by the `sfrt export` flag that gives it (e.g. "--image-order"),
// so that a user of the command reads them as they are.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/exporter/keras_importer.h"
#include "sfrt/exporter/model_spec.h"
#include "sfrt/exporter/onnx_importer.h"
#include "sfrt/exporter/quantize.h"
#include "sfrt/model.h"
#include "sfrt/session.h"
#include "sfrt/status.h"

namespace sfrt::exporter {

// The source formats, told by the file name's extension.
enum class SourceFormat { kOnnx, kKeras, kSfrt };

// The format of `path`: .onnx, .h5/.hdf5 (Keras 2) or .sfrt (any case). Errors name the path and
// say what is read instead (a Keras 3 .keras archive, an unknown extension).
Result<SourceFormat> SourceFormatOf(const std::string& path);

// What the network's input holds (sfrt export --input-kind).
enum class InputKindChoice {
  kAuto,    // the kind of the image order (default stereo pairs) when the channels fit it, else
            // kTensor
  kImages,  // two stereo pairs, 12 channels, preprocessed by the metadata
  kRgbd,    // two RGB-D frames, 8 channels
  kTensor,  // any channel count, fed as given
};
inline constexpr std::array<std::string_view, 4> kInputKindChoiceNames = {"auto", "images", "rgbd",
                                                                          "tensor"};
constexpr std::string_view InputKindChoiceName(InputKindChoice kind) {
  return kInputKindChoiceNames[static_cast<size_t>(kind)];
}
// The choice named `name`, exactly as kInputKindChoiceNames spells it.
std::optional<InputKindChoice> ParseInputKindChoice(std::string_view name);

// The metadata the export sets. A field that holds a value was given: it replaces the source's
// value. A field left empty keeps the value a .sfrt source holds; the other sources take
// ModelSpec's default for it. Values are checked by the caller (finite, positive where a divisor).
struct MetadataChanges {
  std::optional<std::string> name;  // an empty name keeps the source's
  std::optional<InputKindChoice> input_kind;
  std::optional<std::vector<ImageSlot>> image_order;
  std::string image_order_text;  // as the user wrote it, for messages
  std::optional<ColorOrder> color_order;
  std::optional<float> scale;
  std::optional<std::array<float, 3>> mean;
  std::optional<std::array<float, 3>> std;
  std::optional<float> depth_mean;
  std::optional<float> depth_std;
  std::optional<float> depth_invalid;
  std::optional<float> focal_px;
  std::optional<float> baseline;
  std::optional<float> cx;
  std::optional<float> cy;
  std::optional<std::string> units;
  std::optional<TrainingState> training;
};

// What the export does to the convolutions' arithmetic.
enum class PrecisionChange {
  kNone,      // as the source has it (a float32 source stays float32; a .sfrt keeps its own)
  kBFloat16,  // every convolution with a bf16 form marked bf16 (the runtime rounds at load)
  kQuantize,  // int8 or per layer (QuantizeOptions::mode) from calibration frames
};

// Reads the calibration frames for `input`, the verified float32 model's input description (it
// says how frames are preprocessed). `described` receives one line saying what was read. Its
// errors are reported as they are.
using CalibrationReader =
    std::function<Result<CalibrationSet>(const InputDesc& input, std::string* described)>;

// A float32 array of shape (H, W, C) the parity check reads.
struct CheckArray {
  std::string path;        // where it came from: named in the report and in messages
  std::string shape_text;  // its shape as stored, e.g. "(1, 96, 128, 12)", for messages
  int height = 0;
  int width = 0;
  int channels = 0;
  std::vector<float> values;
};

struct CheckOptions {
  enum class Kind {
    kNone,
    // A seeded input (pixels uniform integers 0..255, put through the model's preprocessing) at
    // height x width (0: the traced size, else 540x960); fails on a non-finite output value.
    kSeeded,
    // `input` (already preprocessed); against `reference` when given, within `tolerance` of the
    // reference's largest |value| (<= 0: 1e-4, or 1e-2 with fp16 weights); fails on a
    // non-finite output value.
    kParity,
  };
  Kind kind = Kind::kNone;
  int height = 0;
  int width = 0;
  CheckArray input;
  std::optional<CheckArray> reference;
  double tolerance = 0;
  SessionOptions session;  // the check's session; its size limits are set from the input's
};

// The check's figures, for the report.
struct CheckReport {
  CheckOptions::Kind kind = CheckOptions::Kind::kNone;
  uint32_t seed = 0;  // kSeeded
  int height = 0;     // the input's size and channels
  int width = 0;
  int channels = 0;
  bool ran = false;  // the model ran; then:
  TensorShape output;
  double ms = 0;   // the one run, wall clock
  double min = 0;  // over the finite output values
  double max = 0;
  double mean = 0;
  double stddev = 0;
  size_t non_finite = 0;
  bool compared = false;      // against a reference; then:
  double max_abs_error = 0;   // the largest per-pixel max |error| over the channels
  double reference_max = 0;   // the reference's largest |value| (the scale; 1 if it is 0)
  double relative_error = 0;  // max_abs_error / the scale
  double tolerance = 0;
  size_t pixels_over = 0;  // pixels whose error exceeds tolerance x the scale
  size_t pixels = 0;
  bool passed = false;
};

struct ExportOptions {
  std::string source;       // .onnx, Keras 2 .h5/.hdf5, or .sfrt
  std::string destination;  // where the caller will write the file; named in messages
  OnnxImportOptions onnx;
  KerasImportOptions keras;
  std::optional<WeightType> weights;  // empty: a .sfrt source keeps its own, others float32
  MetadataChanges metadata;
  PrecisionChange precision = PrecisionChange::kNone;
  QuantizeOptions quantize;       // kQuantize
  CalibrationReader calibration;  // kQuantize: called once, after the float32 model verifies
  std::string calibration_name;   // how messages name the calibration data ("--calibration P")
  CheckOptions check;
};

struct ExportResult {
  // Ok, or why the model must not be written. The fields below hold what was done before a
  // failure (a failed check's figures, for one).
  Status status;
  std::vector<uint8_t> bytes;                  // the file
  std::shared_ptr<const Model> model;          // the bytes, loaded and verified
  std::vector<std::string> notes;              // what the import says the user should know
  int convolutions = 0;                        // PrecisionChange::kBFloat16: how many there are,
  int bf16_convolutions = 0;                   // and how many were marked bf16
  std::optional<CalibrationDesc> calibration;  // kQuantize: the method, data and errors
  std::vector<std::string> auto_steps;         // QuantizeMode::kAuto: QuantizeResult::auto_steps
  std::string calibration_described;           // kQuantize: what the reader read
  std::optional<TensorShape> traced_output;    // the output at the traced size, when it is known
  std::optional<CheckReport> check;
};

// Does the whole export, as the header comment says. Never throws; reads the source (and the
// calibration through `options.calibration`), writes nothing.
ExportResult Export(const ExportOptions& options);

// The check alone, on a verified model (Export's last step; options.tolerance must be > 0 for a
// parity check against a reference). Fills `report` as far as the check got.
Status CheckModel(const std::shared_ptr<const Model>& model, const CheckOptions& options,
                  CheckReport* report);

}  // namespace sfrt::exporter
