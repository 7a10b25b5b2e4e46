// sfrt export: a trained network (ONNX or Keras 2 HDF5) -> a verified .sfrt model file, with an
// optional parity check of the converted model against the source framework's output.
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "sfrt/calibration_input.h"
#include "sfrt/commands.h"
#include "sfrt/config/limits.h"
#include "sfrt/export_report.h"
#include "sfrt/exporter/export.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/io/npy.h"
#include "sfrt/session.h"
#include "sfrt/session_environment.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "export";

struct ExportArgs {
  std::string input;
  std::string output;
  std::string name;
  std::string padding = "auto";
  std::string color_order;
  std::string image_order;
  std::string input_kind = "auto";
  float scale = 1.0f;
  float depth_mean = 0.0f;
  float depth_std = 1.0f;
  float depth_invalid = 0.0f;
  std::string mean;
  std::string std;
  float focal = 0;
  float baseline = 0;
  float cx = 0;
  float cy = 0;
  std::string architecture;
  std::string keras_bilinear;
  std::string onnx_output;
  std::string weights = "fp32";
  bool check = false;
  std::string check_input;
  std::string check_output;
  std::string check_size;
  double tolerance = -1;                 // < 0: the default for the weight type
  CLI::Option* tolerance_opt = nullptr;  // given on the command line: must be > 0
  std::string units;
  std::string training_state;
  // Quantisation (schema 1.3).
  std::string precision = "fp32";
  std::string calibration;
  double accuracy_budget = 0.02;
  std::string accuracy_metric = "rms";
  bool no_auto_bf16 = false;
  bool bias_correction = false;
  std::string calibration_size;
  int calibration_frames = 64;
  int calibration_threads = 1;
  std::string calibration_engine = "session";
  std::string calibration_method = "percentile:99.99";
  std::string calibration_scales = "shared";
  // The metadata flags given on the command line: a .sfrt source keeps its own value of the rest.
  std::vector<std::string> given;
};

// The flags that set metadata; with a .sfrt source only the given ones replace the file's values.
constexpr const char* kMetadataFlags[] = {
    "--name", "--input-kind", "--color-order", "--image-order",   "--scale", "--mean",
    "--std",  "--depth-mean", "--depth-std",   "--depth-invalid", "--focal", "--baseline",
    "--cx",   "--cy",         "--units",       "--training-state"};
constexpr size_t kMaxUnitsLength = 64;
// Flags that only apply with --calibration.
constexpr const char* kCalibrationFlags[] = {"--calibration-size",    "--calibration-frames",
                                             "--calibration-method",  "--calibration-scales",
                                             "--calibration-threads", "--calibration-engine"};

bool Given(const ExportArgs& args, std::string_view flag) {
  return std::find(args.given.begin(), args.given.end(), flag) != args.given.end();
}

// Empty when `units` can be stored: 1..64 printable ASCII characters.
std::string CheckUnits(const std::string& units) {
  if (units.empty() || units.size() > kMaxUnitsLength) {
    return "--units: must be 1 to " + std::to_string(kMaxUnitsLength) + " characters, got " +
           std::to_string(units.size());
  }
  for (char c : units) {
    if (c < 0x20 || c > 0x7E) return "--units: printable ASCII only, got '" + units + "'";
  }
  return "";
}

exporter::TrainingState ParseTrainingState(const std::string& text) {
  if (text == "trained") return exporter::TrainingState::kTrained;
  if (text == "untrained") return exporter::TrainingState::kUntrained;
  return exporter::TrainingState::kUnknown;
}

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

// "a,b,c" -> three finite floats.
bool ParseTriple(const std::string& text, std::array<float, 3>* out) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (true) {
    size_t comma = text.find(',', start);
    parts.push_back(text.substr(start, comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (parts.size() != 3) return false;
  for (size_t i = 0; i < 3; ++i) {
    std::string p = parts[i];
    while (!p.empty() && p.front() == ' ') p.erase(p.begin());
    while (!p.empty() && p.back() == ' ') p.pop_back();
    const char* end = p.data() + p.size();
    auto [ptr, ec] = std::from_chars(p.data(), end, (*out)[i]);
    if (p.empty() || ec != std::errc() || ptr != end || !std::isfinite((*out)[i])) return false;
  }
  return true;
}

// "L0,R0,L1,R1" (or left0,right0,...; any case) -> a permutation of the four stereo image slots;
// "C0,D0,C1,D1" (color0,depth0,...) -> one of the two RGB-D frames' slots.
bool ParseImageOrder(const std::string& text, std::vector<exporter::ImageSlot>* out,
                     std::string* error) {
  using exporter::ImageSlot;
  out->clear();
  size_t start = 0;
  while (true) {
    size_t comma = text.find(',', start);
    std::string token = Upper(text.substr(start, comma - start));
    while (!token.empty() && token.front() == ' ') token.erase(token.begin());
    while (!token.empty() && token.back() == ' ') token.pop_back();
    const std::optional<ImageSlot> slot = vocabulary::ImageSlotFromAnyName(token);
    if (!slot) {
      *error = "--image-order: unknown image '" + token +
               "' (use L0, R0, L1, R1 for stereo pairs, C0, D0, C1, D1 for RGB-D frames)";
      return false;
    }
    for (ImageSlot seen : *out) {
      if (seen == *slot) {
        *error = "--image-order: image '" + token + "' appears twice";
        return false;
      }
      if (vocabulary::IsRgbdSlot(seen) != vocabulary::IsRgbdSlot(*slot)) {
        *error = "--image-order: '" + text + "' mixes stereo images and RGB-D frames";
        return false;
      }
    }
    out->push_back(*slot);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (out->size() != 4) {
    *error =
        "--image-order: expected the four images L0,R0,L1,R1 or C0,D0,C1,D1 in some order, "
        "got '" +
        text + "'";
    return false;
  }
  return true;
}

// Defence in depth: libhdf5 1.10 is not hardened against crafted files. The importer checks
// every global-heap reference before libhdf5 follows it (exporter/src/hdf5_vlen_guard.h: the
// SIGSEGV in H5HG_read that fuzzing found), but a Keras file is still first read in a child
// process: if that dies by a signal, the file is reported as unreadable and nothing is written;
// if it returns, the same deterministic import is safe to run here. Empty string: the child
// survived. SFRT_TEST_KERAS_PROBE_CRASH (tests only) makes the child crash, to test this.
std::string ProbeKerasImportInChild(const std::string& path,
                                    const exporter::KerasImportOptions& options) {
  std::fflush(nullptr);
  const pid_t child = ::fork();
  if (child < 0) return "";  // cannot isolate (no fork): fall back to importing in-process
  if (child == 0) {
    // Silence the child: the parent reports the import's own errors when it repeats it.
    std::freopen("/dev/null", "w", stderr);
    std::freopen("/dev/null", "w", stdout);
    if (std::getenv("SFRT_TEST_KERAS_PROBE_CRASH") != nullptr) std::raise(SIGSEGV);
    (void)exporter::ImportKerasH5(path, options);
    ::_exit(0);
  }
  int status = 0;
  while (::waitpid(child, &status, 0) < 0) {
    if (errno != EINTR) return "";
  }
  // The child ends with status 0 whenever the import returns, failed or not. Anything else is a
  // crash: a signal, or (in sanitizer builds) the sanitizer's own exit after catching one.
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return "";
  const std::string how =
      WIFSIGNALED(status)
          ? "signal " + std::to_string(WTERMSIG(status)) + ", " + ::strsignal(WTERMSIG(status))
          : "the reader process ended with status " + std::to_string(WEXITSTATUS(status));
  return path + ": reading this HDF5 file crashed the HDF5 library (" + how +
         ") in an isolated reader process; the file is damaged or not a Keras model. "
         "Nothing was written";
}

// Reads a float32 .npy of shape (H, W, C) or (1, H, W, C) for the check.
Result<exporter::CheckArray> ReadCheckArray(const std::string& path, const char* flag) {
  Result<io::NpyArray> read = io::ReadNpy(path);
  if (!read.ok()) return Status::Error(std::string(flag) + ": " + read.message());
  std::vector<int64_t> shape = read->shape;
  if (shape.size() == 4 && shape[0] == 1) shape.erase(shape.begin());
  if (shape.size() != 3 || shape[0] <= 0 || shape[1] <= 0 || shape[2] <= 0 ||
      shape[0] > (1 << 16) || shape[1] > (1 << 16)) {
    return Status::Error(std::string(flag) + " " + path + ": shape " + read->ShapeString() +
                         " is not (H, W, C) or (1, H, W, C)");
  }
  exporter::CheckArray array;
  array.path = path;
  array.shape_text = read->ShapeString();
  array.height = static_cast<int>(shape[0]);
  array.width = static_cast<int>(shape[1]);
  array.channels = static_cast<int>(shape[2]);
  array.values = std::move(read->data);
  return array;
}

// The metadata flags: each one given sets its field (export.h, MetadataChanges).
std::string MetadataFromFlags(const ExportArgs& args, exporter::MetadataChanges* changes) {
  const exporter::InputSpec defaults;
  std::array<float, 3> mean = defaults.mean;
  std::array<float, 3> stddev = defaults.std;
  if (!args.mean.empty() && !ParseTriple(args.mean, &mean)) {
    return "--mean: expected three comma-separated numbers, got '" + args.mean + "'";
  }
  if (!args.std.empty()) {
    if (!ParseTriple(args.std, &stddev)) {
      return "--std: expected three comma-separated numbers, got '" + args.std + "'";
    }
    for (float s : stddev) {
      if (!(s > 0)) return "--std: every value must be positive, got '" + args.std + "'";
    }
  }
  std::vector<exporter::ImageSlot> image_order;  // empty when not given
  if (!args.image_order.empty()) {
    if (std::string error; !ParseImageOrder(args.image_order, &image_order, &error)) return error;
  }
  exporter::ColorOrder color_order = defaults.color_order;
  if (!args.color_order.empty()) {
    const std::optional<exporter::ColorOrder> parsed =
        vocabulary::ColorOrderFromName(Upper(args.color_order));
    if (!parsed) return "--color-order: expected BGR or RGB, got '" + args.color_order + "'";
    color_order = *parsed;
  }
  if (!std::isfinite(args.scale) || args.scale == 0) {
    return "--scale: must be a finite non-zero number";
  }
  if (!std::isfinite(args.depth_mean) || !std::isfinite(args.depth_invalid)) {
    return "--depth-mean, --depth-invalid: must be finite numbers";
  }
  if (!std::isfinite(args.depth_std) || args.depth_std == 0) {
    return "--depth-std: must be a finite non-zero number";
  }
  if (!(args.focal > 0) || !std::isfinite(args.focal)) {
    return "--focal: must be a positive number of pixels";
  }
  if (!(args.baseline > 0) || !std::isfinite(args.baseline)) return "--baseline: must be positive";
  if (!std::isfinite(args.cx) || !std::isfinite(args.cy))
    return "--cx/--cy: must be finite numbers";
  if (!args.units.empty() || Given(args, "--units")) {
    if (std::string problem = CheckUnits(args.units); !problem.empty()) return problem;
  }
  const auto set = [&](std::string_view flag, auto value, auto* field) {
    if (Given(args, flag)) *field = value;
  };
  if (!args.name.empty()) changes->name = args.name;
  set("--input-kind", *exporter::ParseInputKindChoice(args.input_kind), &changes->input_kind);
  set("--image-order", image_order, &changes->image_order);
  changes->image_order_text = args.image_order;
  set("--color-order", color_order, &changes->color_order);
  set("--scale", args.scale, &changes->scale);
  set("--mean", mean, &changes->mean);
  set("--std", stddev, &changes->std);
  set("--depth-mean", args.depth_mean, &changes->depth_mean);
  set("--depth-std", args.depth_std, &changes->depth_std);
  set("--depth-invalid", args.depth_invalid, &changes->depth_invalid);
  set("--focal", args.focal, &changes->focal_px);
  set("--baseline", args.baseline, &changes->baseline);
  set("--cx", args.cx, &changes->cx);
  set("--cy", args.cy, &changes->cy);
  set("--units", args.units, &changes->units);
  set("--training-state", ParseTrainingState(args.training_state), &changes->training);
  return "";
}

// The source and how it is imported, and the weight storage.
std::string SourceFromFlags(const ExportArgs& args, exporter::ExportOptions* options) {
  options->source = args.input;
  options->destination = args.output;
  const std::optional<WeightType> weights = WeightTypeFromName(args.weights);
  if (!weights) return "--weights: expected fp32 or fp16, got '" + args.weights + "'";
  if (Given(args, "--weights")) options->weights = *weights;
  options->onnx.output = args.onnx_output;
  if (args.padding == "auto") {
    options->onnx.padding = exporter::PaddingDetection::kAuto;
  } else if (args.padding == "same-upper") {
    options->onnx.padding = exporter::PaddingDetection::kSameUpper;
  } else if (args.padding == "explicit") {
    options->onnx.padding = exporter::PaddingDetection::kExplicit;
  } else {
    return "--padding: expected auto, same-upper or explicit, got '" + args.padding + "'";
  }
  Result<exporter::SourceFormat> format = exporter::SourceFormatOf(args.input);
  if (!format.ok()) return format.message();
  const bool keras = *format == exporter::SourceFormat::kKeras;
  if (*format == exporter::SourceFormat::kSfrt && args.padding != "auto") {
    return "--padding applies to ONNX input only (a .sfrt file keeps its rules)";
  }
  if (keras && args.padding != "auto") {
    return "--padding applies to ONNX input only (Keras layers state 'same' or 'valid' "
           "themselves)";
  }
  if (!keras && !args.architecture.empty()) {
    return "--architecture applies to Keras .h5 input only";
  }
  if (*format != exporter::SourceFormat::kOnnx && !args.onnx_output.empty()) {
    return "--onnx-output applies to ONNX input only";
  }
  if (!keras && !args.keras_bilinear.empty()) {
    return "--keras-bilinear applies to Keras .h5 input only (ONNX Resize states its "
           "coordinate_transformation_mode)";
  }
  options->keras.architecture_json = args.architecture;
  if (args.keras_bilinear == "half-pixel") {
    options->keras.bilinear_grid = exporter::KerasBilinearGrid::kHalfPixel;
  } else if (args.keras_bilinear == "asymmetric") {
    options->keras.bilinear_grid = exporter::KerasBilinearGrid::kAsymmetric;
  }
  if (args.output.empty()) return "-o: output path is empty";
  return "";
}

// --check, --check-size, --check-input, --check-output, --tolerance (the arrays are read later).
std::string CheckFromFlags(const ExportArgs& args, exporter::CheckOptions* check) {
  if (args.tolerance_opt->count() > 0 && !(args.tolerance > 0 && std::isfinite(args.tolerance))) {
    return "--tolerance: must be a positive number, got " + FormatFloat(args.tolerance);
  }
  if (!args.check_output.empty() && args.check_input.empty()) {
    return "--check-output needs --check-input (the input it was computed from)";
  }
  if (!args.check_size.empty()) {
    if (!ParseSize(args.check_size, &check->height, &check->width)) {
      return "--check-size: expected HxW with positive integers, got '" + args.check_size + "'";
    }
    if (!args.check || !args.check_input.empty()) {
      return "--check-size applies to --check without --check-input";
    }
    // The limits every --size has (a 5000x5000 check: 3.9 GB).
    if (std::string problem =
            config::CheckSize(config::kInputSide, "--check-size", check->height, check->width);
        !problem.empty()) {
      return problem;
    }
  }
  using Kind = exporter::CheckOptions::Kind;
  check->kind = !args.check_input.empty() ? Kind::kParity
                : args.check              ? Kind::kSeeded
                                          : Kind::kNone;
  check->tolerance = args.tolerance;  // <= 0: the default for the weight type
  return "";
}

// --calibration PATH: the frames for the verified float32 model whose input is `input`: a
// directory of stereo frames (preprocessed as `input` says) or a .npy of network inputs.
Result<exporter::CalibrationSet> ReadCalibration(const ExportArgs& args, const InputDesc& input,
                                                 std::string* described) {
  const std::string& path = args.calibration;
  const std::string flag = "--calibration " + path;
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    int height = input.traced_height;
    int width = input.traced_width;
    if (!args.calibration_size.empty()) ParseSize(args.calibration_size, &height, &width);
    if (height <= 0 || width <= 0) {
      return Status::Error(flag +
                           ": the model's traced size is unknown; give --calibration-size "
                           "HxW to say what size to preprocess the frames at");
    }
    Result<exporter::CalibrationSet> data =
        ReadCalibrationDirectory(path, input, height, width, args.calibration_frames, described);
    if (!data.ok()) return Status::Error("--calibration " + data.message());
    return data;
  }
  if (std::string problem = CheckInputFile(path, "--calibration file"); !problem.empty()) {
    return Status::Error(problem);
  }
  if (LowerExtension(path) != ".npy") {
    return Status::Error(flag + ": neither a directory of stereo frames nor a .npy file");
  }
  Result<exporter::CalibrationSet> data =
      ReadCalibrationNpy(path, input.channels, args.calibration_frames);
  if (!data.ok()) return Status::Error("--calibration " + data.message());
  *described = std::to_string(data->frames) + " frames of " + path;
  return data;
}

// The flags that apply to --precision int8|auto only, each refused without it.
std::string CheckQuantizeFlags(const ExportArgs& args) {
  for (const char* flag : kCalibrationFlags) {
    if (Given(args, flag) && args.calibration.empty()) {
      return std::string(flag) + " applies with --calibration";
    }
  }
  if (args.no_auto_bf16 && args.precision != "auto") {
    return "--no-auto-bf16 applies to --precision auto";
  }
  if (args.bias_correction && args.precision != "int8") {
    return "--bias-correction applies to --precision int8";
  }
  if (Given(args, "--accuracy-metric") && args.precision != "auto") {
    return "--accuracy-metric applies to --precision auto";
  }
  if (Given(args, "--accuracy-budget")) {
    if (args.precision != "auto") return "--accuracy-budget applies to --precision auto";
    if (!(args.accuracy_budget >= 0) || !std::isfinite(args.accuracy_budget)) {
      return "--accuracy-budget: must be a finite number >= 0, got " +
             FormatFloat(args.accuracy_budget);
    }
  }
  if (args.calibration_frames < 1) {
    return "--calibration-frames: must be at least 1, got " +
           std::to_string(args.calibration_frames);
  }
  if (args.calibration_threads < 1) {
    return "--calibration-threads: must be at least 1, got " +
           std::to_string(args.calibration_threads);
  }
  if (Result<exporter::CalibrationMethod> method =
          exporter::ParseCalibrationMethod(args.calibration_method);
      !method.ok()) {
    return "--calibration-method: " + method.message();
  }
  if (args.calibration_size.empty()) return "";
  int h = 0;
  int w = 0;
  if (!ParseSize(args.calibration_size, &h, &w)) {
    return "--calibration-size: expected HxW with positive integers, got '" +
           args.calibration_size + "'";
  }
  if (std::string problem = config::CheckSize(config::kInputSide, "--calibration-size", h, w);
      !problem.empty()) {
    return problem;
  }
  if (LowerExtension(args.calibration) == ".npy") {
    return "--calibration-size applies to a directory of frames; a .npy gives its own size";
  }
  return "";
}

// --precision and its calibration: int8 and auto quantise from calibration frames; bf16 only
// marks the layers (the runtime rounds the float32 weights to bf16 at load).
std::string PrecisionFromFlags(const ExportArgs& args, exporter::ExportOptions* options) {
  const std::optional<Precision> precision = PrecisionFromName(args.precision);
  const bool quantise = args.precision == "auto" || precision == Precision::kInt8;
  if (!precision && !quantise) {
    return "--precision: expected fp32, bf16, int8 or auto, got '" + args.precision + "'";
  }
  if (quantise && args.calibration.empty()) {
    return "--precision " + args.precision +
           " needs --calibration PATH (a float32 .npy of network inputs, or a directory of "
           "stereo frames)";
  }
  if (!quantise && !args.calibration.empty()) {
    return "--calibration applies to --precision int8 or auto (bf16 needs no calibration: it "
           "rounds weights and activations, it chooses no ranges)";
  }
  if (std::string problem = CheckQuantizeFlags(args); !problem.empty()) return problem;
  options->precision = quantise                            ? exporter::PrecisionChange::kQuantize
                       : precision == Precision::kBFloat16 ? exporter::PrecisionChange::kBFloat16
                                                           : exporter::PrecisionChange::kNone;
  exporter::QuantizeOptions& q = options->quantize;
  q.mode = args.precision == "auto" ? exporter::QuantizeMode::kAuto : exporter::QuantizeMode::kInt8;
  q.accuracy_budget = args.accuracy_budget;
  q.auto_bf16 = !args.no_auto_bf16;
  q.bias_correction = args.bias_correction;
  q.threads = args.calibration_threads;
  q.engine = args.calibration_engine == "reference" ? exporter::CalibrationEngine::kReference
                                                    : exporter::CalibrationEngine::kSession;
  q.accuracy_metric = args.accuracy_metric == "max" ? exporter::AccuracyMetric::kMax
                                                    : exporter::AccuracyMetric::kRms;
  q.method = args.calibration_method;
  q.shared_scales = args.calibration_scales == "shared";
  q.progress = [](const char* pass, int frame, int frames) {
    const int step = std::max(1, frames / 4);
    if (frame % step == 0 || frame == frames) {
      std::cout << "calibration: frame " << frame << "/" << frames << " (" << pass << ")"
                << std::endl;
    }
  };
  options->calibration_name = "--calibration " + args.calibration;
  options->calibration = [&args](const InputDesc& input, std::string* described) {
    return ReadCalibration(args, input, described);
  };
  return "";
}

// Flags -> options; a usage error when the command line alone is inconsistent.
std::string OptionsFromFlags(const ExportArgs& args, exporter::ExportOptions* options) {
  if (std::string e = MetadataFromFlags(args, &options->metadata); !e.empty()) return e;
  if (std::string e = SourceFromFlags(args, options); !e.empty()) return e;
  if (std::string e = CheckFromFlags(args, &options->check); !e.empty()) return e;
  return PrecisionFromFlags(args, options);
}

// The files named on the command line exist (the input and the ones beside it) and -o can be
// written; a Keras file is read once in a child process first.
std::string CheckFiles(const ExportArgs& args, const exporter::ExportOptions& options) {
  if (std::string problem = CheckInputFile(args.input, "input file"); !problem.empty()) {
    return problem;
  }
  if (std::string problem = CheckOutputFile(args.output, "-o"); !problem.empty()) return problem;
  const std::pair<const std::string*, const char*> files[] = {
      {&args.architecture, "--architecture file"},
      {&args.check_input, "--check-input file"},
      {&args.check_output, "--check-output file"}};
  for (const auto& [file, role] : files) {
    if (file->empty()) continue;
    if (std::string problem = CheckInputFile(*file, role); !problem.empty()) return problem;
  }
  if (exporter::SourceFormatOf(args.input).value() == exporter::SourceFormat::kKeras) {
    return ProbeKerasImportInChild(args.input, options.keras);
  }
  return "";
}

// The check's arrays and session, read where the command line names them.
Status PrepareCheck(const ExportArgs& args, exporter::CheckOptions* check) {
  if (check->kind == exporter::CheckOptions::Kind::kNone) return Status::Ok();
  if (Status env = tools::ApplySessionEnvironment(check->session); !env.ok()) {
    return Status::Error("check: " + env.message());
  }
  if (check->kind != exporter::CheckOptions::Kind::kParity) return Status::Ok();
  Result<exporter::CheckArray> input = ReadCheckArray(args.check_input, "--check-input");
  if (!input.ok()) return input.status();
  check->input = std::move(input).value();
  if (args.check_output.empty()) return Status::Ok();
  Result<exporter::CheckArray> reference = ReadCheckArray(args.check_output, "--check-output");
  if (!reference.ok()) return reference.status();
  check->reference = std::move(reference).value();
  return Status::Ok();
}

int RunExport(const ExportArgs& args) {
  exporter::ExportOptions options;
  if (std::string usage = OptionsFromFlags(args, &options); !usage.empty()) {
    return ReportError(kName, usage, kExitUsage);
  }
  if (std::string problem = CheckFiles(args, options); !problem.empty()) {
    return ReportError(kName, problem, kExitFailure);
  }
  if (Status s = PrepareCheck(args, &options.check); !s.ok()) {
    return ReportError(kName, s.message() + "; nothing written to " + args.output, kExitFailure);
  }
  const exporter::ExportResult result = exporter::Export(options);
  if (!result.status.ok()) {
    if (result.check) {
      for (const std::string& line : CheckLines(options.check, *result.check)) {
        std::cout << line << "\n";
      }
      std::cout.flush();
    }
    return ReportError(kName, result.status.message(), kExitFailure);
  }
  if (Status s = io::WriteFileAtomically(args.output, result.bytes); !s.ok()) {
    return ReportError(kName, s.message(), kExitFailure);
  }
  PrintExportReport(options, result);
  return kExitOk;
}

}  // namespace

// --precision: a convolution precision, or auto (per layer, within an accuracy budget).
std::vector<std::string> PrecisionChoices() {
  std::vector<std::string> choices(kPrecisionNames.begin(), kPrecisionNames.end());
  choices.push_back("auto");
  return choices;
}

// The help text after the options.
constexpr char kFooter[] =
    "Reads ONNX as torch.onnx.export writes it (opsets 11-17), and Keras 2 HDF5 (.h5/.hdf5)\n"
    "from model.save() (functional or Sequential; a multi_gpu_model checkpoint exports its\n"
    "nested model) or save_weights() with --architecture. Keras 3 .keras archives are not\n"
    "read. Records the preprocessing and the training camera given by the flags; the\n"
    "defaults are the SceneEDNet authors' setup (BGR, L0,R0,L1,R1, raw 0..255 pixels,\n"
    "FlyingThings3D camera). Serialises, loads the bytes back and verifies them, runs the\n"
    "checks asked for, and only then writes the file (atomically).\n"
    "A .sfrt source is rewritten at the current schema version with the same layers and\n"
    "weights: its metadata is kept except for the flags given (e.g. sfrt export m.sfrt\n"
    "-o m.sfrt --units metres --training-state trained).\n"
    "Quantisation (--precision int8|auto): activation ranges are observed on the float32\n"
    "model over the calibration frames (--calibration-method), weights are quantised per\n"
    "output channel, then the int8 model is run against float32 on the same frames (both\n"
    "on this CPU's kernels; on the scalar reference with --calibration-engine reference);\n"
    "the method, a SHA-256 of the frames and the output and per-layer errors are stored in\n"
    "the file (sfrt inspect shows them) and printed. auto starts from every convolution\n"
    "int8 and moves up, one step at a time, the layer whose error rose most over its input's\n"
    "(int8 to bf16, bf16 to float32; int8 straight to float32 with --no-auto-bf16), until\n"
    "the output's error (--accuracy-metric) is within --accuracy-budget. A .sfrt source\n"
    "must be float32 to be quantised; an int8 .sfrt is rewritten without --precision.\n"
    "bf16 (--precision bf16) marks every convolution bf16 (dilated and grouped ones stay\n"
    "fp32): a session rounds the weights to bf16 at load and keeps bf16 activations\n"
    "between the layers of a chain; measure its accuracy with sfrt eval.\n"
    "Graphs (Concat, Add, named inputs) and models with a pooling, resize, transposed\n"
    "convolution or channel affine layer keep float32 tensors between layers: each int8\n"
    "or bf16 convolution converts what it reads and writes float32, except that tensors\n"
    "stay uint8 or bf16 where every reader (through upsamplings, crops and Concats) is a\n"
    "convolution of that precision (int8: of one quantisation, which\n"
    "--calibration-scales shared arranges).\n"
    "Parity check: prints max abs error, max error relative to the reference's largest\n"
    "|value| and the share of pixels over the tolerance. When a check fails, NO file is\n"
    "written (an existing file at -o is left unchanged) and the exit code is 1.\n"
    "Exit codes: 0 success, 1 import/check/write/verify failure, 2 usage error.";

// The source, the file to write and its name.
void AddSourceOptions(CLI::App* cmd, ExportArgs* args) {
  const exporter::ModelSpec defaults;
  cmd->add_option("model", args->input,
                  "Source network (.onnx, or Keras 2 .h5/.hdf5), or a .sfrt file whose metadata "
                  "to rewrite")
      ->required();
  cmd->add_option("-o,--output", args->output, "Model file to write (.sfrt)")->required();
  cmd->add_option("--name", args->name,
                  "Model name stored in the file (default: " + defaults.name + ")");
  cmd->add_option(
         "--padding", args->padding,
         "ONNX only: how conv padding is stored: auto (same-upper if every conv's pads equal the "
         "same-upper amounts at the traced size, else explicit), same-upper (fail if "
         "the traced pads contradict it), explicit (keep the traced numbers)")
      ->check(CLI::IsMember({"auto", "same-upper", "explicit"}))
      ->capture_default_str();
}

// The input's preprocessing, the training camera, the units, the training state.
void AddMetadataOptions(CLI::App* cmd, ExportArgs* args) {
  cmd->add_option("--color-order", args->color_order,
                  "Channel order the network was trained on: BGR or RGB (default: BGR, as "
                  "OpenCV reads images)");
  cmd->add_option("--image-order", args->image_order,
                  "Order of the images along the input channels: stereo pairs L0,R0,L1,R1 "
                  "(default; L = left, R = right, 0 = time t, 1 = t+1) or RGB-D frames "
                  "C0,D0,C1,D1 (default with --input-kind rgbd; C = colour, 3 channels, D = "
                  "depth, 1 channel)");
  cmd->add_option("--input-kind", args->input_kind,
                  "What the network's input holds: images (two stereo pairs, 12 channels, "
                  "preprocessed by the metadata), rgbd (two RGB-D frames, 8 channels: colour as "
                  "images, depth in metres by --depth-mean/--depth-std), tensor (any channel "
                  "count, fed as given: sfrt infer --input-npy), or auto: the kind of "
                  "--image-order (default stereo pairs) when the channel count fits it, else "
                  "tensor")
      ->check(CLI::IsMember(std::vector<std::string>(exporter::kInputKindChoiceNames.begin(),
                                                     exporter::kInputKindChoiceNames.end())))
      ->capture_default_str();
  cmd->add_option("--depth-mean", args->depth_mean,
                  "RGB-D frames: fed depth = (metres - depth-mean) / depth-std")
      ->capture_default_str();
  cmd->add_option("--depth-std", args->depth_std, "RGB-D frames: the divisor above (non-zero)")
      ->capture_default_str();
  cmd->add_option("--depth-invalid", args->depth_invalid,
                  "RGB-D frames: the value fed where a depth map has no depth (0, negative or "
                  "not finite)")
      ->capture_default_str();
  cmd->add_option("--scale", args->scale,
                  "Pixel scale: fed value = (pixel * scale - mean[c]) / std[c]")
      ->capture_default_str();
  cmd->add_option("--mean", args->mean,
                  "Per-channel mean a,b,c in the model's color order, subtracted after scaling "
                  "(default: 0,0,0)");
  cmd->add_option("--std", args->std,
                  "Per-channel divisor a,b,c in the model's color order (default: 1,1,1)");
  cmd->add_option("--focal", args->focal, "Training camera focal length in pixels")
      ->capture_default_str();
  cmd->add_option("--baseline", args->baseline,
                  "Training camera stereo baseline, in the units of --units")
      ->capture_default_str();
  cmd->add_option("--cx", args->cx, "Training camera principal point x (pixels)")
      ->capture_default_str();
  cmd->add_option("--cy", args->cy, "Training camera principal point y (pixels)")
      ->capture_default_str();
  cmd->add_option("--units", args->units,
                  "What the output values measure, as stored in the file (1-64 printable "
                  "characters), e.g. metres; default: unknown");
  cmd->add_option("--training-state", args->training_state,
                  "Whether the weights were trained: trained, untrained (sfrt run, infer, eval and "
                  "inspect then say so) or unknown (default)")
      ->check(CLI::IsMember({"trained", "untrained", "unknown"}));
}

// How each source format is read, and the weights' storage.
void AddImportOptions(CLI::App* cmd, ExportArgs* args) {
  cmd->add_option("--architecture", args->architecture,
                  "Keras only: architecture JSON (model.to_json()); needed for a weights-only "
                  ".h5 from save_weights(), replaces a full model's own model_config");
  cmd->add_option("--onnx-output", args->onnx_output,
                  "ONNX only: the graph output the model computes, for a graph with several "
                  "(an sfrt model has one output; a MaxPool's Indices output becomes an argmax "
                  "pool whose values are the indices)");
  cmd->add_option("--keras-bilinear", args->keras_bilinear,
                  "Keras only: the grid of bilinear UpSampling2D layers, half-pixel (TensorFlow "
                  "2) or asymmetric (TensorFlow 1: align_corners=False); default: half-pixel for "
                  "files saved by Keras 2.4 or later, others refused (Keras 2.0-2.3 ran on "
                  "either)")
      ->check(CLI::IsMember({"half-pixel", "asymmetric"}));
  cmd->add_option("--weights", args->weights,
                  "Weight storage: fp32, or fp16 (IEEE half: about half the file; the runtime "
                  "widens to float32 once at load and computes in float32)")
      ->check(
          CLI::IsMember(std::vector<std::string>(kWeightTypeNames.begin(), kWeightTypeNames.end())))
      ->capture_default_str();
}

// The checks before anything is written (--tolerance is added last, after the precision).
void AddCheckOptions(CLI::App* cmd, ExportArgs* args) {
  cmd->add_flag("--check", args->check,
                "Run the converted model on a seeded input (pixels 0..255 through the model's "
                "preprocessing) at the built size (or --check-size; 540x960 if unknown); "
                "print output statistics; fail if any value is not finite");
  cmd->add_option("--check-size", args->check_size, "Input size HxW for --check");
  cmd->add_option("--check-input", args->check_input,
                  "Parity check input: float32 .npy (H,W,C) or (1,H,W,C), the values the "
                  "source framework was fed (after preprocessing)");
  cmd->add_option("--check-output", args->check_output,
                  "Parity check reference: the source framework's output for --check-input, "
                  "float32 .npy (H,W,3) or (1,H,W,3)");
}

// The convolutions' arithmetic and the calibration it is chosen from.
void AddPrecisionOptions(CLI::App* cmd, ExportArgs* args) {
  cmd->add_option("--precision", args->precision,
                  "Arithmetic of the convolutions (dilated and grouped ones stay fp32): fp32; "
                  "bf16 (bf16 weights and activations, float32 sums; no calibration); int8 "
                  "(int8 weights per output channel, uint8 activations, quantised from "
                  "--calibration); auto (per layer int8, else bf16, else fp32, so that the "
                  "output's error stays within --accuracy-budget)")
      ->check(CLI::IsMember(PrecisionChoices()))
      ->capture_default_str();
  cmd->add_option("--calibration", args->calibration,
                  "With --precision int8|auto: network inputs to choose the quantisation from: a "
                  "float32 .npy (H,W,C) or (N,H,W,C) as infer --input-npy takes, or a directory "
                  "of stereo frames as run --replay reads (consecutive pairs form (t, t+1) "
                  "windows, preprocessed as the model's metadata says)");
  cmd->add_flag("--no-auto-bf16", args->no_auto_bf16,
                "--precision auto: put a layer over the budget straight back to fp32 instead of "
                "trying bf16 first (for CPUs without bf16 kernels, where bf16 runs on the "
                "reference kernel)");
  cmd->add_option("--accuracy-budget", args->accuracy_budget,
                  "--precision auto: largest output error accepted over the calibration frames, "
                  "as --accuracy-metric measures it")
      ->capture_default_str();
  cmd->add_option("--accuracy-metric", args->accuracy_metric,
                  "--precision auto: the output error the budget holds: rms, RMS(output - "
                  "float32 output) / RMS(float32 output); max, max |output - float32 output| / "
                  "max |float32 output|")
      ->check(CLI::IsMember({"rms", "max"}))
      ->capture_default_str();
  cmd->add_option("--calibration-size", args->calibration_size,
                  "Directory calibration: the size HxW frames are resized to (default: the "
                  "model's traced size); a .npy gives its own size");
  cmd->add_option("--calibration-frames", args->calibration_frames,
                  "Use at most the first N frames (windows) of --calibration")
      ->capture_default_str();
  cmd->add_option("--calibration-threads", args->calibration_threads,
                  "Run N calibration frames at once (threads beyond the frame count go to each "
                  "frame's session); each holds one forward pass's tensors in memory. The file "
                  "is the same for every N")
      ->capture_default_str();
  cmd->add_option("--calibration-engine", args->calibration_engine,
                  "What runs the calibration passes: session (this CPU's fastest kernels; the "
                  "last bits of float32 sums, so the ranges and errors, can differ on a CPU "
                  "with other kernels) or reference (the scalar reference kernels: the same "
                  "file on every CPU, but tens of times slower, about 20 s per float32 pass "
                  "of a full-width 540x960 frame)")
      ->check(CLI::IsMember({"session", "reference"}))
      ->capture_default_str();
  cmd->add_option("--calibration-method", args->calibration_method,
                  "How activation ranges are chosen: percentile:P (the central P percent of the "
                  "values, 50 <= P <= 100) or minmax")
      ->capture_default_str();
  cmd->add_option("--calibration-scales", args->calibration_scales,
                  "Graphs: shared (convolutions that read values of one tensor, through "
                  "upsamplings, crops and Concats, share one range, the union of theirs, so that "
                  "a session keeps those tensors uint8) or per-tensor (a range per tensor read: "
                  "tighter, but each convolution then converts a float32 copy); chains are the "
                  "same either way")
      ->check(CLI::IsMember({"shared", "per-tensor"}))
      ->capture_default_str();
  cmd->add_flag("--bias-correction", args->bias_correction,
                "--precision int8: move each int8 convolution's bias by the mean error (before "
                "its activation) each output channel shows against float32 on the calibration "
                "frames, one convolution after the other (one more pass over the frames per "
                "convolution); recorded in the file's calibration method");
}

Command AddExportCommand(CLI::App& parent) {
  auto args = std::make_shared<ExportArgs>();
  const exporter::ModelSpec defaults;
  args->focal = defaults.camera.focal_px;
  args->baseline = defaults.camera.baseline;
  args->cx = defaults.camera.cx;
  args->cy = defaults.camera.cy;
  args->scale = defaults.input.scale;

  CLI::App* cmd = parent.add_subcommand(
      "export", "Convert a trained network (.onnx, Keras .h5) into a .sfrt model file");
  for (auto* add : {AddSourceOptions, AddMetadataOptions, AddImportOptions, AddCheckOptions,
                    AddPrecisionOptions}) {
    add(cmd, args.get());
  }
  args->tolerance_opt =
      cmd->add_option("--tolerance", args->tolerance,
                      "Parity tolerance: largest allowed |error| relative to the reference's "
                      "largest |value| (default 1e-4; 1e-2 with --weights fp16)");
  cmd->footer(kFooter);
  return Command{cmd, [args, cmd] {
                   args->given.clear();
                   for (const char* flag : kMetadataFlags) {
                     if (cmd->count(flag) > 0) args->given.push_back(flag);
                   }
                   if (cmd->count("--weights") > 0) args->given.push_back("--weights");
                   for (const char* flag : kCalibrationFlags) {
                     if (cmd->count(flag) > 0) args->given.push_back(flag);
                   }
                   for (const char* flag : {"--accuracy-budget", "--accuracy-metric"}) {
                     if (cmd->count(flag) > 0) args->given.push_back(flag);
                   }
                   return RunExport(*args);
                 }};
}

}  // namespace sfrt::tools
