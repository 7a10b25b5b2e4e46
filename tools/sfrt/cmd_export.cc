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
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/calibration_input.h"
#include "sfrt/commands.h"
#include "sfrt/config/limits.h"
#include "sfrt/exporter/keras_importer.h"
#include "sfrt/exporter/model_spec.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/onnx_importer.h"
#include "sfrt/exporter/quantize.h"
#include "sfrt/exporter/sfrt_importer.h"
#include "sfrt/model.h"
#include "sfrt/model_notes.h"
#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/io/npy.h"
#include "sfrt/session.h"
#include "sfrt/session_environment.h"
#include "sfrt/shapes.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "export";
constexpr double kDefaultTolerance = 1e-4;      // relative to the reference's largest |value|
constexpr double kDefaultFp16Tolerance = 1e-2;  // with --weights fp16
constexpr uint32_t kCheckSeed = 0;

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
constexpr const char* kDepthFlags[] = {"--depth-mean", "--depth-std", "--depth-invalid"};
constexpr size_t kMaxUnitsLength = 64;
// Flags that only apply with --calibration.
constexpr const char* kCalibrationFlags[] = {"--calibration-size",    "--calibration-frames",
                                             "--calibration-method",  "--calibration-scales",
                                             "--calibration-threads", "--calibration-engine"};

bool Given(const ExportArgs& args, std::string_view flag) {
  return std::find(args.given.begin(), args.given.end(), flag) != args.given.end();
}

// What the network's input holds (--input-kind).
enum class InputKind { kImages, kRgbd, kTensor };

bool IsRgbdOrder(const std::vector<exporter::ImageSlot>& order) {
  return !order.empty() && vocabulary::IsRgbdSlot(order.front());
}

int OrderChannels(const std::vector<exporter::ImageSlot>& order) {
  int channels = 0;
  for (exporter::ImageSlot slot : order) channels += vocabulary::SlotChannels(slot);
  return channels;
}

// The input kind --input-kind asks for, checked against the network's channel count and the
// image order. `image_order` is --image-order's, or empty when it was not given. A .sfrt source
// without --input-kind keeps what its file says.
Result<InputKind> ChooseInputKind(const ExportArgs& args, const exporter::ModelSpec& spec,
                                  const std::vector<exporter::ImageSlot>& image_order,
                                  bool sfrt_source) {
  const int channels = spec.input.channels;
  std::string kind = args.input_kind;
  if (sfrt_source && !Given(args, "--input-kind")) {
    kind = spec.input.image_order.empty()        ? "tensor"
           : IsRgbdOrder(spec.input.image_order) ? "rgbd"
                                                 : "images";
  } else if (kind == "auto") {
    const bool rgbd = IsRgbdOrder(image_order);
    const int wanted = image_order.empty() ? 3 * vocabulary::kDefaultImageOrder.size()
                                           : OrderChannels(image_order);
    kind = channels != wanted ? "tensor" : rgbd ? "rgbd" : "images";
  }
  if (!image_order.empty() && kind != "tensor" && IsRgbdOrder(image_order) != (kind == "rgbd")) {
    return Status::Error("--image-order '" + args.image_order + "' names " +
                         (kind == "rgbd" ? "stereo images; --input-kind rgbd takes C0,D0,C1,D1"
                                         : "RGB-D frames; give --input-kind rgbd for them"));
  }
  if (kind != "rgbd") {
    for (const char* flag : kDepthFlags) {
      if (Given(args, flag)) {
        return Status::Error(std::string(flag) +
                             " describes the depth maps of RGB-D frames, but the input is " +
                             (kind == "images" ? "stereo images" : "a plain tensor") +
                             "; give --input-kind rgbd for RGB-D frames");
      }
    }
  }
  if (kind == "images" || kind == "rgbd") {
    const bool rgbd = kind == "rgbd";
    const int wanted = rgbd ? 8 : 12;
    if (channels != wanted) {
      return Status::Error(args.input + ": the network's input has " + std::to_string(channels) +
                           " channels; --input-kind " + kind + " takes " + std::to_string(wanted) +
                           (rgbd ? " (colour and depth of two frames: 3 + 1 + 3 + 1)"
                                 : " (3 per image of --image-order, default L0,R0,L1,R1)"));
    }
    return rgbd ? InputKind::kRgbd : InputKind::kImages;
  }
  for (const char* flag : {"--image-order", "--color-order", "--scale", "--mean", "--std"}) {
    if (Given(args, flag)) {
      return Status::Error(std::string(flag) + " describes image inputs, but the input is a " +
                           std::to_string(channels) + "-channel plain tensor (--input-kind " +
                           args.input_kind + "); give --input-kind images or rgbd for images");
    }
  }
  return InputKind::kTensor;
}

// The report's description of the input: the images and their preprocessing, or a plain tensor.
std::string InputLine(const InputDesc& input) {
  const std::string channels = std::to_string(input.channels) + " channels: ";
  if (input.image_order.empty()) return channels + "a plain tensor, fed as given";
  std::string line = channels + Join(input.image_order, ",") + ", " + input.color_order +
                     ", value = (pixel * " + FormatFloat(input.scale) + " - mean) / std, mean " +
                     FormatFloat(input.mean[0]) + "," + FormatFloat(input.mean[1]) + "," +
                     FormatFloat(input.mean[2]) + ", std " + FormatFloat(input.std[0]) + "," +
                     FormatFloat(input.std[1]) + "," + FormatFloat(input.std[2]);
  if (input.is_rgbd()) {
    line += "; depth value = (metres - " + FormatFloat(input.depth_mean) + ") / " +
            FormatFloat(input.depth_std) + ", missing depth " + FormatFloat(input.depth_invalid);
  }
  return line;
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
  static constexpr struct {
    const char* short_name;
    const char* long_name;
    ImageSlot slot;
  } kTokens[] = {{"L0", "LEFT0", ImageSlot::kLeft0},   {"R0", "RIGHT0", ImageSlot::kRight0},
                 {"L1", "LEFT1", ImageSlot::kLeft1},   {"R1", "RIGHT1", ImageSlot::kRight1},
                 {"C0", "COLOR0", ImageSlot::kColor0}, {"D0", "DEPTH0", ImageSlot::kDepth0},
                 {"C1", "COLOR1", ImageSlot::kColor1}, {"D1", "DEPTH1", ImageSlot::kDepth1}};
  out->clear();
  size_t start = 0;
  while (true) {
    size_t comma = text.find(',', start);
    std::string token = Upper(text.substr(start, comma - start));
    while (!token.empty() && token.front() == ' ') token.erase(token.begin());
    while (!token.empty() && token.back() == ' ') token.pop_back();
    const auto* match = std::find_if(std::begin(kTokens), std::end(kTokens), [&](const auto& t) {
      return token == t.short_name || token == t.long_name;
    });
    if (match == std::end(kTokens)) {
      *error = "--image-order: unknown image '" + token +
               "' (use L0, R0, L1, R1 for stereo pairs, C0, D0, C1, D1 for RGB-D frames)";
      return false;
    }
    for (ImageSlot seen : *out) {
      if (seen == match->slot) {
        *error = "--image-order: image '" + token + "' appears twice";
        return false;
      }
      if (vocabulary::IsRgbdSlot(seen) != vocabulary::IsRgbdSlot(match->slot)) {
        *error = "--image-order: '" + text + "' mixes stereo images and RGB-D frames";
        return false;
      }
    }
    out->push_back(match->slot);
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

// One line describing how the model's convolutions pad, as the loaded file states it.
std::string DescribePadding(const Model& model) {
  int same_upper = 0;
  int same_lower = 0;
  int explicit_pads = 0;
  for (const LayerDesc& layer : model.layers()) {
    if (layer.kind != LayerKind::kConv2D) continue;
    same_upper += layer.conv.padding_rule == PaddingRule::kSameUpper;
    same_lower += layer.conv.padding_rule == PaddingRule::kSameLower;
    explicit_pads += layer.conv.padding_rule == PaddingRule::kExplicit;
  }
  const InputDesc& in = model.metadata().input;
  std::string traced = in.traced_height > 0 ? std::to_string(in.traced_height) + "x" +
                                                  std::to_string(in.traced_width)
                                            : "an unknown size";
  const int convs = same_upper + same_lower + explicit_pads;
  for (const auto& [count, rule] :
       {std::pair{same_upper, "same-upper"}, {same_lower, "same-lower"}}) {
    if (count == convs) {
      return std::string(rule) + " at all " + std::to_string(count) +
             " convs (pads computed per input size)";
    }
  }
  if (explicit_pads == convs) {
    return "explicit at all " + std::to_string(explicit_pads) + " convs (the amounts traced at " +
           traced + ", applied unchanged at every size)";
  }
  return "mixed: " + std::to_string(same_upper) + " convs same-upper, " +
         (same_lower > 0 ? std::to_string(same_lower) + " same-lower, " : "") +
         std::to_string(explicit_pads) + " explicit (as traced at " + traced + ")";
}

std::string Sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2e", v);
  return buf;
}

std::string SizeText(int height, int width) {
  return std::to_string(height) + "x" + std::to_string(width);
}

// "float16, 1,234 bytes (float32: 2,468; saves 1,234)".
std::string WeightsLine(const Model& model) {
  const uint64_t params = model.parameter_count();
  if (std::string int8 = Int8LayersText(model); !int8.empty()) {
    return int8 + ", " + GroupDigits(StoredParameterBytes(model)) + " bytes (float32 would need " +
           GroupDigits(params * 4) + ")";
  }
  if (model.metadata().weight_type == WeightType::kFloat16) {
    return "float16, " + GroupDigits(params * 2) + " bytes (float32 would need " +
           GroupDigits(params * 4) + "; saves " + GroupDigits(params * 2) +
           "), widened to float32 at load";
  }
  return "float32, " + GroupDigits(params * 4) + " bytes";
}

// Runs `model` once on `input` (height x width x input channels).
bool RunOnce(const std::shared_ptr<const Model>& model, const std::vector<float>& input, int height,
             int width, std::vector<float>* output, TensorShape* out_shape, double* ms,
             std::string* failure) {
  SessionOptions options;
  options.max_height = height;
  options.max_width = width;
  if (Status env = tools::ApplySessionEnvironment(options); !env.ok()) {
    *failure = "check: " + env.message();
    return false;
  }
  Result<std::unique_ptr<Session>> session = Session::Create(model, options);
  if (!session.ok()) {
    *failure =
        "check: cannot plan the model at " + SizeText(height, width) + ": " + session.message();
    return false;
  }
  Result<TensorShape> shape = (*session)->OutputShape(height, width);
  if (!shape.ok()) {
    *failure = "check: at " + SizeText(height, width) + ": " + shape.message();
    return false;
  }
  *out_shape = *shape;
  output->assign(shape->elements(), 0.0f);
  const auto t0 = std::chrono::steady_clock::now();
  Status s = (*session)->Run(input, height, width, *output);
  *ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!s.ok()) {
    *failure = "check: the model fails to run: " + s.message();
    return false;
  }
  return true;
}

// Reads a float32 .npy of shape (H, W, C) or (1, H, W, C).
bool ReadImageArray(const std::string& path, const char* flag, io::NpyArray* array, int* height,
                    int* width, int* channels, std::string* failure) {
  Result<io::NpyArray> read = io::ReadNpy(path);
  if (!read.ok()) {
    *failure = std::string(flag) + ": " + read.message();
    return false;
  }
  *array = std::move(read).value();
  std::vector<int64_t> shape = array->shape;
  if (shape.size() == 4 && shape[0] == 1) shape.erase(shape.begin());
  if (shape.size() != 3 || shape[0] <= 0 || shape[1] <= 0 || shape[2] <= 0 ||
      shape[0] > (1 << 16) || shape[1] > (1 << 16)) {
    *failure = std::string(flag) + " " + path + ": shape " + array->ShapeString() +
               " is not (H, W, C) or (1, H, W, C)";
    return false;
  }
  *height = static_cast<int>(shape[0]);
  *width = static_cast<int>(shape[1]);
  *channels = static_cast<int>(shape[2]);
  return true;
}

// --check-input [--check-output]: runs the model on the given (already preprocessed) input and
// compares with the reference. Appends report lines; false (with `failure`) when it fails.
bool ParityCheck(const std::shared_ptr<const Model>& model, const std::string& input_path,
                 const std::string& output_path, double tolerance, std::vector<std::string>* lines,
                 std::string* failure) {
  io::NpyArray input;
  int h = 0, w = 0, c = 0;
  if (!ReadImageArray(input_path, "--check-input", &input, &h, &w, &c, failure)) return false;
  if (c != model->metadata().input.channels) {
    *failure = "--check-input " + input_path + ": shape " + input.ShapeString() + " has " +
               std::to_string(c) + " channels but the model takes " +
               std::to_string(model->metadata().input.channels);
    return false;
  }
  io::NpyArray reference;
  int rh = 0, rw = 0, rc = 0;
  if (!output_path.empty() &&
      !ReadImageArray(output_path, "--check-output", &reference, &rh, &rw, &rc, failure)) {
    return false;
  }
  std::vector<float> output;
  TensorShape shape;
  double ms = 0;
  if (!RunOnce(model, input.data, h, w, &output, &shape, &ms, failure)) return false;
  char line[512];
  std::snprintf(line, sizeof(line),
                "  check       input %s (%dx%dx%d) -> output %dx%dx%d in %.0f ms",
                input_path.c_str(), h, w, c, shape.height, shape.width, shape.channels, ms);
  lines->push_back(line);
  size_t non_finite = 0;
  for (float v : output) non_finite += std::isfinite(v) ? 0 : 1;
  if (output_path.empty()) {
    double lo = INFINITY, hi = -INFINITY;
    for (float v : output) {
      if (!std::isfinite(v)) continue;
      lo = std::min(lo, static_cast<double>(v));
      hi = std::max(hi, static_cast<double>(v));
    }
    lines->push_back("  output      min " + Sci(lo) + ", max " + Sci(hi) + "; finite " +
                     (non_finite == 0 ? "yes" : "NO (" + std::to_string(non_finite) + ")"));
    if (non_finite > 0) {
      *failure = "check: the output has " + std::to_string(non_finite) + " non-finite values";
      return false;
    }
    return true;
  }
  if (rh != shape.height || rw != shape.width || rc != shape.channels) {
    *failure = "--check-output " + output_path + ": shape " + reference.ShapeString() +
               " differs from the model's output " + std::to_string(shape.height) + "x" +
               std::to_string(shape.width) + "x" + std::to_string(shape.channels);
    return false;
  }
  double max_abs = 0;
  double ref_max = 0;
  for (float v : reference.data) ref_max = std::max(ref_max, std::fabs(static_cast<double>(v)));
  const double scale = ref_max > 0 ? ref_max : 1.0;
  size_t pixels_over = 0;
  const size_t pixels = static_cast<size_t>(rh) * static_cast<size_t>(rw);
  for (size_t p = 0; p < pixels; ++p) {
    double pixel_err = 0;
    for (int k = 0; k < rc; ++k) {
      const size_t i = p * static_cast<size_t>(rc) + static_cast<size_t>(k);
      const double err = std::fabs(static_cast<double>(output[i]) - reference.data[i]);
      pixel_err = std::isnan(err) ? INFINITY : std::max(pixel_err, err);
    }
    max_abs = std::max(max_abs, pixel_err);
    pixels_over += pixel_err > tolerance * scale ? 1 : 0;
  }
  const double relative = max_abs / scale;
  char share[32];
  std::snprintf(share, sizeof(share), "%.3f%%",
                pixels > 0 ? 100.0 * static_cast<double>(pixels_over) / pixels : 0.0);
  lines->push_back("  parity      vs " + output_path + ": max abs error " + Sci(max_abs) +
                   ", reference max |value| " + Sci(ref_max) + ", max error relative to it " +
                   Sci(relative) + " (tolerance " + Sci(tolerance) + "), pixels over tolerance " +
                   GroupDigits(pixels_over) + " of " + GroupDigits(pixels) + " (" + share +
                   "), finite " + (non_finite == 0 ? "yes" : "NO"));
  if (non_finite > 0) {
    *failure =
        "parity check failed: the output has " + std::to_string(non_finite) + " non-finite values";
    return false;
  }
  if (!(relative <= tolerance)) {
    *failure = "parity check failed: max error relative to the reference's largest value " +
               Sci(relative) + " exceeds the tolerance " + Sci(tolerance) + " (" +
               GroupDigits(pixels_over) + " pixels over)";
    return false;
  }
  lines->push_back("  parity      ok");
  return true;
}

// --check without a reference: a seeded input (pixel values: uniform integers 0..255, put
// through the model's preprocessing) at the built size (or --check-size, else 540x960).
bool SeededCheck(const std::shared_ptr<const Model>& model, int height, int width,
                 std::vector<std::string>* lines, std::string* failure) {
  const InputDesc& in = model->metadata().input;
  if (height == 0) {
    height = in.traced_height > 0 ? in.traced_height : 540;
    width = in.traced_width > 0 ? in.traced_width : 960;
  }
  const size_t count =
      static_cast<size_t>(height) * static_cast<size_t>(width) * static_cast<size_t>(in.channels);
  std::vector<float> input(count);
  std::mt19937 rng(kCheckSeed);
  for (size_t i = 0; i < count; ++i) {
    const int c = static_cast<int>(i % static_cast<size_t>(in.channels)) % 3;
    const auto pixel = static_cast<float>(rng() % 256u);
    input[i] = (pixel * in.scale - in.mean[c]) / in.std[c];
  }
  std::vector<float> output;
  TensorShape shape;
  double ms = 0;
  if (!RunOnce(model, input, height, width, &output, &shape, &ms, failure)) return false;
  double sum = 0, sum2 = 0, lo = INFINITY, hi = -INFINITY;
  size_t non_finite = 0;
  for (float v : output) {
    if (!std::isfinite(v)) {
      ++non_finite;
      continue;
    }
    sum += v;
    sum2 += static_cast<double>(v) * v;
    lo = std::min(lo, static_cast<double>(v));
    hi = std::max(hi, static_cast<double>(v));
  }
  const double n = static_cast<double>(output.size() - non_finite);
  const double mean = n > 0 ? sum / n : 0;
  const double stddev = n > 0 ? std::sqrt(std::max(sum2 / n - mean * mean, 0.0)) : 0;
  char line[256];
  std::snprintf(line, sizeof(line),
                "  check       seeded input (pixels uniform 0..255, seed %u) at %dx%d -> output "
                "%dx%dx%d in %.0f ms",
                kCheckSeed, height, width, shape.height, shape.width, shape.channels, ms);
  lines->push_back(line);
  lines->push_back("  output      min " + Sci(lo) + ", max " + Sci(hi) + ", mean " + Sci(mean) +
                   ", std " + Sci(stddev) + "; finite " +
                   (non_finite == 0 ? "yes" : "NO (" + std::to_string(non_finite) + ")"));
  if (non_finite > 0) {
    *failure = "check failed: the output has " + std::to_string(non_finite) + " non-finite values";
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

// --precision int8|auto: reads the calibration frames, quantises `spec` (float32) and appends
// the summary lines. Errors name the calibration file or directory.
Result<exporter::QuantizeResult> QuantizeForExport(const ExportArgs& args,
                                                   const exporter::ModelSpec& spec,
                                                   const ModelMetadata& meta,
                                                   std::vector<std::string>* lines) {
  const std::string& path = args.calibration;
  const std::string flag = "--calibration " + path;
  std::error_code ec;
  Result<exporter::CalibrationSet> data = Status::Error("unread");
  std::string described;
  if (std::filesystem::is_directory(path, ec)) {
    int height = meta.input.traced_height;
    int width = meta.input.traced_width;
    if (!args.calibration_size.empty()) ParseSize(args.calibration_size, &height, &width);
    if (height <= 0 || width <= 0) {
      return Status::Error(flag +
                           ": the model's traced size is unknown; give --calibration-size "
                           "HxW to say what size to preprocess the frames at");
    }
    data = ReadCalibrationDirectory(path, meta.input, height, width, args.calibration_frames,
                                    &described);
    if (!data.ok()) return Status::Error("--calibration " + data.message());
  } else {
    if (std::string problem = CheckInputFile(path, "--calibration file"); !problem.empty()) {
      return Status::Error(problem);
    }
    if (LowerExtension(path) != ".npy") {
      return Status::Error(flag + ": neither a directory of stereo frames nor a .npy file");
    }
    data = ReadCalibrationNpy(path, meta.input.channels, args.calibration_frames);
    if (!data.ok()) return Status::Error("--calibration " + data.message());
    described = std::to_string(data->frames) + " frames of " + path;
  }
  exporter::QuantizeOptions options;
  options.mode =
      args.precision == "auto" ? exporter::QuantizeMode::kAuto : exporter::QuantizeMode::kInt8;
  options.accuracy_budget = args.accuracy_budget;
  options.auto_bf16 = !args.no_auto_bf16;
  options.bias_correction = args.bias_correction;
  options.threads = args.calibration_threads;
  options.engine = args.calibration_engine == "reference" ? exporter::CalibrationEngine::kReference
                                                          : exporter::CalibrationEngine::kSession;
  options.accuracy_metric = args.accuracy_metric == "max" ? exporter::AccuracyMetric::kMax
                                                          : exporter::AccuracyMetric::kRms;
  options.method = args.calibration_method;
  options.shared_scales = args.calibration_scales == "shared";
  options.progress = [](const char* pass, int frame, int frames) {
    const int step = std::max(1, frames / 4);
    if (frame % step == 0 || frame == frames) {
      std::cout << "calibration: frame " << frame << "/" << frames << " (" << pass << ")"
                << std::endl;
    }
  };
  Result<exporter::QuantizeResult> result = exporter::Quantize(spec, *data, options);
  if (!result.ok()) return Status::Error(flag + ": " + result.message());

  const CalibrationDesc& cal = result->calibration;
  size_t int8 = 0, bf16 = 0;
  size_t name_width = 0;
  for (const LayerErrorDesc& e : cal.layers) {
    int8 += e.precision == Precision::kInt8;
    bf16 += e.precision == Precision::kBFloat16;
    name_width = std::max(name_width, e.layer.size());
  }
  const size_t convs = cal.layers.size();
  std::string precision = int8 == convs
                              ? "int8, all " + std::to_string(convs) + " convolutions"
                              : std::to_string(int8) + " of " + std::to_string(convs) +
                                    " convolutions int8, " + std::to_string(bf16) + " bf16, " +
                                    std::to_string(convs - int8 - bf16) + " fp32";
  if (args.precision == "auto") {
    precision += " (--precision auto, accuracy budget " + ErrorText(args.accuracy_budget) +
                 " on the output's " + (args.accuracy_metric == "max" ? "largest" : "rms") +
                 " error)";
    if (int8 + bf16 == 0) precision += "; no int8 or bf16 convolution fits: the file is float32";
  }
  lines->push_back("  precision   " + precision);
  lines->push_back("  calibration " + cal.method + ", " + std::to_string(cal.frames) +
                   " frames of " + std::to_string(cal.height) + "x" + std::to_string(cal.width) +
                   ", data sha256 " + cal.data_sha256);
  lines->push_back("  frames      " + described);
  lines->push_back("  error       output max " + ErrorText(cal.output_max_rel) + ", rms " +
                   ErrorText(cal.output_rms_rel) +
                   " relative to float32 over the calibration frames, on " +
                   (options.engine == exporter::CalibrationEngine::kReference
                        ? std::string("the reference kernels")
                        : std::string("this CPU's ") + IsaName(BestIsa()) + " kernels"));
  for (const LayerErrorDesc& e : cal.layers) {
    lines->push_back("  layer       " + e.layer + std::string(name_width - e.layer.size(), ' ') +
                     "  " + PrecisionName(e.precision) + "  relative rms " +
                     ErrorText(e.relative_rms));
  }
  for (const std::string& step : result->auto_steps) lines->push_back("  auto        " + step);
  return result;
}

int RunExport(const ExportArgs& args) {
  // Everything decidable from the command line alone is checked first (usage errors).
  exporter::ModelSpec defaults;
  std::array<float, 3> mean = defaults.input.mean;
  std::array<float, 3> stddev = defaults.input.std;
  if (!args.mean.empty() && !ParseTriple(args.mean, &mean)) {
    return ReportError(kName,
                       "--mean: expected three comma-separated numbers, got '" + args.mean + "'",
                       kExitUsage);
  }
  if (!args.std.empty()) {
    if (!ParseTriple(args.std, &stddev)) {
      return ReportError(kName,
                         "--std: expected three comma-separated numbers, got '" + args.std + "'",
                         kExitUsage);
    }
    for (float s : stddev) {
      if (!(s > 0)) {
        return ReportError(kName, "--std: every value must be positive, got '" + args.std + "'",
                           kExitUsage);
      }
    }
  }
  std::vector<exporter::ImageSlot> image_order;  // --image-order's; empty when not given
  if (!args.image_order.empty()) {
    std::string error;
    if (!ParseImageOrder(args.image_order, &image_order, &error)) {
      return ReportError(kName, error, kExitUsage);
    }
  }
  exporter::ColorOrder color_order = defaults.input.color_order;
  if (!args.color_order.empty()) {
    std::string c = Upper(args.color_order);
    if (c == "BGR") {
      color_order = exporter::ColorOrder::kBGR;
    } else if (c == "RGB") {
      color_order = exporter::ColorOrder::kRGB;
    } else {
      return ReportError(
          kName, "--color-order: expected BGR or RGB, got '" + args.color_order + "'", kExitUsage);
    }
  }
  if (!std::isfinite(args.scale) || args.scale == 0) {
    return ReportError(kName, "--scale: must be a finite non-zero number", kExitUsage);
  }
  if (!std::isfinite(args.depth_mean) || !std::isfinite(args.depth_invalid)) {
    return ReportError(kName, "--depth-mean, --depth-invalid: must be finite numbers", kExitUsage);
  }
  if (!std::isfinite(args.depth_std) || args.depth_std == 0) {
    return ReportError(kName, "--depth-std: must be a finite non-zero number", kExitUsage);
  }
  if (!(args.focal > 0) || !std::isfinite(args.focal)) {
    return ReportError(kName, "--focal: must be a positive number of pixels", kExitUsage);
  }
  if (!(args.baseline > 0) || !std::isfinite(args.baseline)) {
    return ReportError(kName, "--baseline: must be positive", kExitUsage);
  }
  if (!std::isfinite(args.cx) || !std::isfinite(args.cy)) {
    return ReportError(kName, "--cx/--cy: must be finite numbers", kExitUsage);
  }
  exporter::WeightType weight_type = exporter::WeightType::kFloat32;
  if (args.weights == "fp16") {
    weight_type = exporter::WeightType::kFloat16;
  } else if (args.weights != "fp32") {
    return ReportError(kName, "--weights: expected fp32 or fp16, got '" + args.weights + "'",
                       kExitUsage);
  }
  if (args.tolerance_opt->count() > 0 && !(args.tolerance > 0 && std::isfinite(args.tolerance))) {
    return ReportError(kName,
                       "--tolerance: must be a positive number, got " + FormatFloat(args.tolerance),
                       kExitUsage);
  }
  if (!args.check_output.empty() && args.check_input.empty()) {
    return ReportError(kName, "--check-output needs --check-input (the input it was computed from)",
                       kExitUsage);
  }
  int check_height = 0;
  int check_width = 0;
  if (!args.check_size.empty() && !ParseSize(args.check_size, &check_height, &check_width)) {
    return ReportError(
        kName, "--check-size: expected HxW with positive integers, got '" + args.check_size + "'",
        kExitUsage);
  }
  if (!args.check_size.empty() && (!args.check || !args.check_input.empty())) {
    return ReportError(kName, "--check-size applies to --check without --check-input", kExitUsage);
  }
  if (!args.check_size.empty()) {  // the limits every --size has (a 5000x5000 check: 3.9 GB)
    if (std::string problem =
            config::CheckSize(config::kInputSide, "--check-size", check_height, check_width);
        !problem.empty()) {
      return ReportError(kName, problem, kExitUsage);
    }
  }
  exporter::OnnxImportOptions import_options;
  import_options.output = args.onnx_output;
  if (args.padding == "auto") {
    import_options.padding = exporter::PaddingDetection::kAuto;
  } else if (args.padding == "same-upper") {
    import_options.padding = exporter::PaddingDetection::kSameUpper;
  } else if (args.padding == "explicit") {
    import_options.padding = exporter::PaddingDetection::kExplicit;
  } else {
    return ReportError(
        kName, "--padding: expected auto, same-upper or explicit, got '" + args.padding + "'",
        kExitUsage);
  }
  if (!args.units.empty() || Given(args, "--units")) {
    if (std::string problem = CheckUnits(args.units); !problem.empty()) {
      return ReportError(kName, problem, kExitUsage);
    }
  }
  const std::string ext = LowerExtension(args.input);
  const bool keras = ext == ".h5" || ext == ".hdf5";
  const bool sfrt_source = ext == ".sfrt";
  if (ext == ".keras") {
    return ReportError(kName,
                       args.input +
                           ": Keras 3 .keras archives are not supported; save the model from "
                           "Keras 2 / tf.keras as HDF5 (model.save('model.h5')) and pass that",
                       kExitUsage);
  }
  if (ext != ".onnx" && !keras && !sfrt_source) {
    return ReportError(kName,
                       args.input + ": unsupported input format '" +
                           (ext.empty() ? std::string("(no extension)") : ext) +
                           "' (supported: .onnx, Keras 2 .h5/.hdf5, .sfrt to rewrite metadata)",
                       kExitUsage);
  }
  if (sfrt_source && args.padding != "auto") {
    return ReportError(kName, "--padding applies to ONNX input only (a .sfrt file keeps its rules)",
                       kExitUsage);
  }
  if (keras && args.padding != "auto") {
    return ReportError(kName,
                       "--padding applies to ONNX input only (Keras layers state 'same' or "
                       "'valid' themselves)",
                       kExitUsage);
  }
  if (!keras && !args.architecture.empty()) {
    return ReportError(kName, "--architecture applies to Keras .h5 input only", kExitUsage);
  }
  if (ext != ".onnx" && !args.onnx_output.empty()) {
    return ReportError(kName, "--onnx-output applies to ONNX input only", kExitUsage);
  }
  if (!keras && !args.keras_bilinear.empty()) {
    return ReportError(kName,
                       "--keras-bilinear applies to Keras .h5 input only (ONNX Resize states its "
                       "coordinate_transformation_mode)",
                       kExitUsage);
  }
  if (args.output.empty()) return ReportError(kName, "-o: output path is empty", kExitUsage);
  // int8 and auto quantise from calibration frames; bf16 only marks the layers (the runtime
  // rounds the float32 weights to bf16 at load).
  const bool quantise = args.precision == "int8" || args.precision == "auto";
  const bool bf16 = args.precision == "bf16";
  if (args.precision != "fp32" && args.precision != "bf16" && !quantise) {
    return ReportError(
        kName, "--precision: expected fp32, bf16, int8 or auto, got '" + args.precision + "'",
        kExitUsage);
  }
  if (quantise && args.calibration.empty()) {
    return ReportError(kName,
                       "--precision " + args.precision +
                           " needs --calibration PATH (a float32 .npy of network inputs, or a "
                           "directory of stereo frames)",
                       kExitUsage);
  }
  if (!quantise && !args.calibration.empty()) {
    return ReportError(kName,
                       "--calibration applies to --precision int8 or auto (bf16 needs no "
                       "calibration: it rounds weights and activations, it chooses no ranges)",
                       kExitUsage);
  }
  for (const char* flag : kCalibrationFlags) {
    if (Given(args, flag) && args.calibration.empty()) {
      return ReportError(kName, std::string(flag) + " applies with --calibration", kExitUsage);
    }
  }
  if (args.no_auto_bf16 && args.precision != "auto") {
    return ReportError(kName, "--no-auto-bf16 applies to --precision auto", kExitUsage);
  }
  if (args.bias_correction && args.precision != "int8") {
    return ReportError(kName, "--bias-correction applies to --precision int8", kExitUsage);
  }
  if (Given(args, "--accuracy-metric") && args.precision != "auto") {
    return ReportError(kName, "--accuracy-metric applies to --precision auto", kExitUsage);
  }
  if (Given(args, "--accuracy-budget")) {
    if (args.precision != "auto") {
      return ReportError(kName, "--accuracy-budget applies to --precision auto", kExitUsage);
    }
    if (!(args.accuracy_budget >= 0) || !std::isfinite(args.accuracy_budget)) {
      return ReportError(kName,
                         "--accuracy-budget: must be a finite number >= 0, got " +
                             FormatFloat(args.accuracy_budget),
                         kExitUsage);
    }
  }
  if (args.calibration_frames < 1) {
    return ReportError(
        kName,
        "--calibration-frames: must be at least 1, got " + std::to_string(args.calibration_frames),
        kExitUsage);
  }
  if (args.calibration_threads < 1) {
    return ReportError(kName,
                       "--calibration-threads: must be at least 1, got " +
                           std::to_string(args.calibration_threads),
                       kExitUsage);
  }
  if (Result<exporter::CalibrationMethod> method =
          exporter::ParseCalibrationMethod(args.calibration_method);
      !method.ok()) {
    return ReportError(kName, "--calibration-method: " + method.message(), kExitUsage);
  }
  if (!args.calibration_size.empty()) {
    int h = 0;
    int w = 0;
    if (!ParseSize(args.calibration_size, &h, &w)) {
      return ReportError(kName,
                         "--calibration-size: expected HxW with positive integers, got '" +
                             args.calibration_size + "'",
                         kExitUsage);
    }
    if (std::string problem = config::CheckSize(config::kInputSide, "--calibration-size", h, w);
        !problem.empty()) {
      return ReportError(kName, problem, kExitUsage);
    }
    if (LowerExtension(args.calibration) == ".npy") {
      return ReportError(kName,
                         "--calibration-size applies to a directory of frames; a .npy gives its "
                         "own size",
                         kExitUsage);
    }
  }

  // Import.
  if (std::string problem = CheckInputFile(args.input, "input file"); !problem.empty()) {
    return ReportError(kName, problem, kExitFailure);
  }
  if (std::string problem = CheckOutputFile(args.output, "-o"); !problem.empty()) {
    return ReportError(kName, problem, kExitFailure);
  }
  for (const std::string* file : {&args.architecture, &args.check_input, &args.check_output}) {
    if (file->empty()) continue;
    const char* role = file == &args.architecture  ? "--architecture file"
                       : file == &args.check_input ? "--check-input file"
                                                   : "--check-output file";
    if (std::string problem = CheckInputFile(*file, role); !problem.empty()) {
      return ReportError(kName, problem, kExitFailure);
    }
  }
  exporter::ModelSpec spec;
  std::vector<std::string> notes;
  if (keras) {
    exporter::KerasImportOptions keras_options;
    keras_options.architecture_json = args.architecture;
    if (args.keras_bilinear == "half-pixel") {
      keras_options.bilinear_grid = exporter::KerasBilinearGrid::kHalfPixel;
    } else if (args.keras_bilinear == "asymmetric") {
      keras_options.bilinear_grid = exporter::KerasBilinearGrid::kAsymmetric;
    }
    if (std::string crash = ProbeKerasImportInChild(args.input, keras_options); !crash.empty()) {
      return ReportError(kName, crash, kExitFailure);
    }
    Result<exporter::KerasImportResult> imported =
        exporter::ImportKerasH5(args.input, keras_options);
    if (!imported.ok()) return ReportError(kName, imported.message(), kExitFailure);
    spec = std::move(imported->spec);
    notes = std::move(imported->notes);
  } else if (sfrt_source) {
    Result<exporter::ModelSpec> imported = exporter::ImportSfrt(args.input);
    if (!imported.ok()) return ReportError(kName, imported.message(), kExitFailure);
    spec = std::move(imported).value();
    notes.push_back(std::string(quantise ? "quantised from a .sfrt file: layers and float32 "
                                           "weights from "
                                         : "rewritten from a .sfrt file: weights and layers "
                                           "unchanged, metadata from ") +
                    args.input + (quantise ? ", its metadata" : "") + " except the flags given");
  } else {
    Result<exporter::ModelSpec> imported = exporter::ImportOnnx(args.input, import_options);
    if (!imported.ok()) return ReportError(kName, imported.message(), kExitFailure);
    spec = std::move(imported).value();
  }
  if (!sfrt_source || Given(args, "--weights")) spec.weight_type = weight_type;
  std::string bf16_line;
  if (quantise || bf16) {
    for (const exporter::LayerSpec& layer : spec.layers) {
      const auto* conv = std::get_if<exporter::ConvSpec>(&layer);
      if (conv == nullptr || conv->precision == Precision::kFloat32) continue;
      return ReportError(kName,
                         args.input + ": layer '" + conv->name + "' is already " +
                             PrecisionName(conv->precision) +
                             "; --precision converts a float32 model (export from the float32 "
                             "source, or drop --precision to rewrite metadata)",
                         kExitFailure);
    }
  }
  if (bf16) {
    int convs = 0, marked = 0;
    for (exporter::LayerSpec& layer : spec.layers) {
      auto* conv = std::get_if<exporter::ConvSpec>(&layer);
      if (conv == nullptr) continue;
      ++convs;
      if (!exporter::ReducibleConv(*conv)) continue;
      conv->precision = Precision::kBFloat16;
      ++marked;
    }
    if (marked == 0) {
      return ReportError(kName,
                         args.input + ": no convolution has a bf16 form (" + std::to_string(convs) +
                             " found; dilated and grouped ones run in fp32 only): drop "
                             "--precision",
                         kExitFailure);
    }
    bf16_line = "  precision   bf16, " +
                (marked == convs ? "all " + std::to_string(convs)
                                 : std::to_string(marked) + " of " + std::to_string(convs)) +
                " convolutions (weights stored as --weights says, rounded to bf16 when a "
                "session loads them; activations bf16 between the bf16 convolutions of a chain, "
                "float32 in a graph or around a float32-only layer)";
  }

  // Apply the flags (a .sfrt source keeps its own value of each flag not given).
  auto apply = [&](std::string_view flag) { return !sfrt_source || Given(args, flag); };
  Result<InputKind> kind = ChooseInputKind(args, spec, image_order, sfrt_source);
  if (!kind.ok()) return ReportError(kName, kind.message(), kExitFailure);
  if (*kind != InputKind::kTensor) {
    const bool rgbd = *kind == InputKind::kRgbd;
    if (image_order.empty()) {
      image_order = rgbd ? std::vector<exporter::ImageSlot>(vocabulary::kDefaultRgbdOrder.begin(),
                                                            vocabulary::kDefaultRgbdOrder.end())
                         : defaults.input.image_order;
    }
    if (apply("--image-order") || apply("--input-kind")) spec.input.image_order = image_order;
    if (apply("--color-order")) spec.input.color_order = color_order;
    if (apply("--scale")) spec.input.scale = args.scale;
    if (apply("--mean")) spec.input.mean = mean;
    if (apply("--std")) spec.input.std = stddev;
    if (apply("--depth-mean")) spec.input.depth_mean = rgbd ? args.depth_mean : 0.0f;
    if (apply("--depth-std")) spec.input.depth_std = rgbd ? args.depth_std : 1.0f;
    if (apply("--depth-invalid")) spec.input.depth_invalid = rgbd ? args.depth_invalid : 0.0f;
  } else {
    // A plain tensor is fed as given: no image order, and the pixel transform is the identity.
    const exporter::InputSpec plain;
    if (spec.input.name == plain.name) spec.input.name = "tensor";
    spec.input.image_order.clear();
    spec.input.color_order = plain.color_order;
    spec.input.scale = plain.scale;
    spec.input.mean = plain.mean;
    spec.input.std = plain.std;
    spec.input.depth_mean = plain.depth_mean;
    spec.input.depth_std = plain.depth_std;
    spec.input.depth_invalid = plain.depth_invalid;
  }
  if (!args.name.empty()) spec.name = args.name;
  if (apply("--focal")) spec.camera.focal_px = args.focal;
  if (apply("--baseline")) spec.camera.baseline = args.baseline;
  if (apply("--cx")) spec.camera.cx = args.cx;
  if (apply("--cy")) spec.camera.cy = args.cy;
  if (apply("--units")) spec.output.units = args.units;
  if (apply("--training-state")) spec.training = ParseTrainingState(args.training_state);

  // Serialise, then check the bytes load and verify exactly as a deployment would load them
  // before anything is written: a model that fails here never reaches the disk.
  Result<std::vector<uint8_t>> bytes = exporter::SerializeModel(spec);
  if (!bytes.ok()) return ReportError(kName, args.input + ": " + bytes.message(), kExitFailure);
  Result<std::shared_ptr<const Model>> loaded =
      Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy, {}, args.output);
  if (!loaded.ok()) {
    return ReportError(kName,
                       "the converted model does not verify, nothing written: " + loaded.message(),
                       kExitFailure);
  }
  // --precision int8|auto: quantise the verified float32 model, then verify what is written.
  std::vector<std::string> quant_lines;
  if (!bf16_line.empty()) quant_lines.push_back(bf16_line);
  if (quantise) {
    Result<exporter::QuantizeResult> quantised =
        QuantizeForExport(args, spec, (*loaded)->metadata(), &quant_lines);
    if (!quantised.ok()) return ReportError(kName, quantised.message(), kExitFailure);
    spec = std::move(quantised->spec);
    bytes = exporter::SerializeModel(spec);
    if (!bytes.ok()) return ReportError(kName, args.input + ": " + bytes.message(), kExitFailure);
    loaded =
        Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy, {}, args.output);
    if (!loaded.ok()) {
      return ReportError(
          kName, "the quantised model does not verify, nothing written: " + loaded.message(),
          kExitFailure);
    }
  }
  const std::shared_ptr<const Model> model_ptr = *loaded;
  const Model& model = *model_ptr;
  const ModelMetadata& meta = model.metadata();
  std::string shapes_line = "not checked (traced size unknown)";
  if (meta.input.traced_height > 0 && meta.input.traced_width > 0) {
    Result<std::vector<LayerGeometry>> geometry =
        InferGeometry(model, meta.input.traced_height, meta.input.traced_width);
    if (!geometry.ok() || geometry->empty()) {
      return ReportError(kName,
                         "the converted model has no valid shapes at its traced size, nothing "
                         "written: " +
                             (geometry.ok() ? std::string("no layers") : geometry.message()),
                         kExitFailure);
    }
    const TensorShape& out = geometry->back().output;
    shapes_line = "at the traced size " + std::to_string(meta.input.traced_height) + "x" +
                  std::to_string(meta.input.traced_width) + " the output is " +
                  std::to_string(out.height) + "x" + std::to_string(out.width) + "x" +
                  std::to_string(out.channels);
  }

  // The parity check runs before anything is written: a model that fails it never reaches
  // the disk (and an existing file at -o stays as it was).
  std::vector<std::string> check_lines;
  if (args.check || !args.check_input.empty()) {
    const double tolerance = args.tolerance > 0                              ? args.tolerance
                             : weight_type == exporter::WeightType::kFloat16 ? kDefaultFp16Tolerance
                                                                             : kDefaultTolerance;
    std::string failure;
    const bool passed =
        args.check_input.empty()
            ? SeededCheck(model_ptr, check_height, check_width, &check_lines, &failure)
            : ParityCheck(model_ptr, args.check_input, args.check_output, tolerance, &check_lines,
                          &failure);
    if (!passed) {
      for (const std::string& line : check_lines) std::cout << line << "\n";
      std::cout.flush();
      return ReportError(kName, failure + "; nothing written to " + args.output, kExitFailure);
    }
  }

  if (Status s = io::WriteFileAtomically(args.output, *bytes); !s.ok()) {
    return ReportError(kName, s.message(), kExitFailure);
  }

  int convs = 0;
  int upsamples = 0;
  int crops = 0;
  int concats = 0;
  int adds = 0;
  int deconvs = 0;
  int pools = 0;
  int resizes = 0;
  int affines = 0;
  for (const LayerDesc& layer : model.layers()) {
    resizes += layer.kind == LayerKind::kResize;
    affines += layer.kind == LayerKind::kChannelAffine;
    pools += layer.kind == LayerKind::kPool2D;
    deconvs += layer.kind == LayerKind::kConvTranspose2D;
    convs += layer.kind == LayerKind::kConv2D;
    upsamples += layer.kind == LayerKind::kUpsample;
    crops += layer.kind == LayerKind::kCrop;
    concats += layer.kind == LayerKind::kConcat;
    adds += layer.kind == LayerKind::kAdd;
  }
  // The ops beyond a chain of convolutions: transposed convolutions, poolings, resizes,
  // per-channel scale and shift, and a graph's skip connections (Concats and Adds).
  const std::string merges = (deconvs > 0 ? ", " + std::to_string(deconvs) + " deconv" : "") +
                             (pools > 0 ? ", " + std::to_string(pools) + " pool" : "") +
                             (resizes > 0 ? ", " + std::to_string(resizes) + " resize" : "") +
                             (affines > 0 ? ", " + std::to_string(affines) + " affine" : "") +
                             (concats > 0 ? ", " + std::to_string(concats) + " concat" : "") +
                             (adds > 0 ? ", " + std::to_string(adds) + " add" : "");
  const std::string traced =
      meta.input.traced_height > 0
          ? std::to_string(meta.input.traced_height) + "x" + std::to_string(meta.input.traced_width)
          : "unknown";
  std::cout << "sfrt export: " << args.input << " -> " << args.output << "\n"
            << "  source      " << meta.source_format << ", sha256 " << meta.source_sha256 << "\n"
            << "  name        " << meta.name << "\n"
            << "  layers      " << model.layers().size() << " (" << convs << " conv, " << upsamples
            << " upsample, " << crops << " crop" << merges << "), traced at " << traced << "\n"
            << "  parameters  " << GroupDigits(model.parameter_count()) << "\n"
            << "  padding     " << DescribePadding(model) << "\n"
            << "  shapes      " << shapes_line << "\n"
            << "  input       " << InputLine(meta.input) << "\n"
            << "  camera      f " << FormatFloat(meta.camera.focal_px) << " px, baseline "
            << FormatFloat(meta.camera.baseline) << ", cx " << FormatFloat(meta.camera.cx)
            << ", cy " << FormatFloat(meta.camera.cy) << "\n"
            << "  units       " << UnitsText(meta) << "\n"
            << "  training    " << TrainingStateName(meta.training) << "\n"
            << "  weights     " << WeightsLine(model) << "\n"
            << "  file        " << GroupDigits(model.file_bytes())
            << " bytes, loads and verifies (CRC-32C ok)\n";
  for (const std::string& note : notes) std::cout << "  note        " << note << "\n";
  for (const std::string& line : quant_lines) std::cout << line << "\n";
  for (const std::string& line : check_lines) std::cout << line << "\n";
  return kExitOk;
}

}  // namespace

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
      ->check(CLI::IsMember({"auto", "images", "rgbd", "tensor"}))
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
      ->check(CLI::IsMember({"fp32", "fp16"}))
      ->capture_default_str();
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
  cmd->add_option("--precision", args->precision,
                  "Arithmetic of the convolutions (dilated and grouped ones stay fp32): fp32; "
                  "bf16 (bf16 weights and activations, float32 sums; no calibration); int8 "
                  "(int8 weights per output channel, uint8 activations, quantised from "
                  "--calibration); auto (per layer int8, else bf16, else fp32, so that the "
                  "output's error stays within --accuracy-budget)")
      ->check(CLI::IsMember({"fp32", "bf16", "int8", "auto"}))
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
  args->tolerance_opt =
      cmd->add_option("--tolerance", args->tolerance,
                      "Parity tolerance: largest allowed |error| relative to the reference's "
                      "largest |value| (default 1e-4; 1e-2 with --weights fp16)");
  cmd->footer(
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
      "Exit codes: 0 success, 1 import/check/write/verify failure, 2 usage error.");
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
