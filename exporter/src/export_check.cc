// Export's last step: the converted model runs once, on a seeded input or on the source
// framework's input, against its output when given (export.h, CheckModel).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

#include "message_text.h"
#include "sfrt/exporter/export.h"

namespace sfrt::exporter {
namespace {

constexpr uint32_t kCheckSeed = 0;
constexpr int kUnknownSizeHeight = 540;  // the paper's frames, when the traced size is unknown
constexpr int kUnknownSizeWidth = 960;

std::string SizeText(int height, int width) {
  return std::to_string(height) + "x" + std::to_string(width);
}

// Runs `model` once on `input` (height x width x the model's input channels).
Status RunOnce(const std::shared_ptr<const Model>& model, const std::vector<float>& input,
               int height, int width, const SessionOptions& session_options,
               std::vector<float>* output, CheckReport* report) {
  SessionOptions options = session_options;
  options.max_height = height;
  options.max_width = width;
  Result<std::unique_ptr<Session>> session = Session::Create(model, options);
  if (!session.ok()) {
    return Status::Error("check: cannot plan the model at " + SizeText(height, width) + ": " +
                         session.message());
  }
  Result<TensorShape> shape = (*session)->OutputShape(height, width);
  if (!shape.ok())
    return Status::Error("check: at " + SizeText(height, width) + ": " + shape.message());
  output->assign(shape->elements(), 0.0f);
  const auto t0 = std::chrono::steady_clock::now();
  Status s = (*session)->Run(input, height, width, *output);
  const auto t1 = std::chrono::steady_clock::now();
  if (!s.ok()) return Status::Error("check: the model fails to run: " + s.message());
  report->ran = true;
  report->output = *shape;
  report->ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  return Status::Ok();
}

// The output's range, mean and spread over its finite values, and its non-finite count.
void Summarise(const std::vector<float>& output, CheckReport* report) {
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
  report->min = lo;
  report->max = hi;
  report->mean = n > 0 ? sum / n : 0;
  report->stddev = n > 0 ? std::sqrt(std::max(sum2 / n - report->mean * report->mean, 0.0)) : 0;
  report->non_finite = non_finite;
}

std::string NonFinite(const CheckReport& report) {
  return "the output has " + std::to_string(report.non_finite) + " non-finite values";
}

// Pixel values uniform integers 0..255, put through the model's preprocessing.
std::vector<float> SeededInput(const InputDesc& in, int height, int width) {
  const size_t count =
      static_cast<size_t>(height) * static_cast<size_t>(width) * static_cast<size_t>(in.channels);
  std::vector<float> input(count);
  std::mt19937 rng(kCheckSeed);
  for (size_t i = 0; i < count; ++i) {
    const int c = static_cast<int>(i % static_cast<size_t>(in.channels)) % 3;
    const auto pixel = static_cast<float>(rng() % 256u);
    input[i] = (pixel * in.scale - in.mean[c]) / in.std[c];
  }
  return input;
}

Status SeededCheck(const std::shared_ptr<const Model>& model, const CheckOptions& options,
                   CheckReport* report) {
  const InputDesc& in = model->metadata().input;
  int height = options.height;
  int width = options.width;
  if (height == 0) {
    height = in.traced_height > 0 ? in.traced_height : kUnknownSizeHeight;
    width = in.traced_width > 0 ? in.traced_width : kUnknownSizeWidth;
  }
  report->seed = kCheckSeed;
  report->height = height;
  report->width = width;
  report->channels = in.channels;
  std::vector<float> output;
  if (Status s = RunOnce(model, SeededInput(in, height, width), height, width, options.session,
                         &output, report);
      !s.ok()) {
    return s;
  }
  Summarise(output, report);
  if (report->non_finite > 0) return Status::Error("check failed: " + NonFinite(*report));
  report->passed = true;
  return Status::Ok();
}

// The output against the reference: per pixel the largest |error| over the channels.
void Compare(const std::vector<float>& output, const CheckArray& reference, double tolerance,
             CheckReport* report) {
  double max_abs = 0;
  double ref_max = 0;
  for (float v : reference.values) ref_max = std::max(ref_max, std::fabs(static_cast<double>(v)));
  const double scale = ref_max > 0 ? ref_max : 1.0;
  size_t pixels_over = 0;
  const size_t pixels =
      static_cast<size_t>(reference.height) * static_cast<size_t>(reference.width);
  const auto channels = static_cast<size_t>(reference.channels);
  for (size_t p = 0; p < pixels; ++p) {
    double pixel_err = 0;
    for (size_t k = 0; k < channels; ++k) {
      const size_t i = p * channels + k;
      const double err = std::fabs(static_cast<double>(output[i]) - reference.values[i]);
      pixel_err = std::isnan(err) ? INFINITY : std::max(pixel_err, err);
    }
    max_abs = std::max(max_abs, pixel_err);
    pixels_over += pixel_err > tolerance * scale ? 1 : 0;
  }
  report->compared = true;
  report->max_abs_error = max_abs;
  report->reference_max = ref_max;
  report->relative_error = max_abs / scale;
  report->tolerance = tolerance;
  report->pixels_over = pixels_over;
  report->pixels = pixels;
}

Status ParityCheck(const std::shared_ptr<const Model>& model, const CheckOptions& options,
                   CheckReport* report) {
  const CheckArray& input = options.input;
  const int channels = model->metadata().input.channels;
  if (input.channels != channels) {
    return Status::Error("--check-input " + input.path + ": shape " + input.shape_text + " has " +
                         std::to_string(input.channels) + " channels but the model takes " +
                         std::to_string(channels));
  }
  report->height = input.height;
  report->width = input.width;
  report->channels = input.channels;
  std::vector<float> output;
  if (Status s =
          RunOnce(model, input.values, input.height, input.width, options.session, &output, report);
      !s.ok()) {
    return s;
  }
  Summarise(output, report);
  if (!options.reference) {
    if (report->non_finite > 0) return Status::Error("check: " + NonFinite(*report));
    report->passed = true;
    return Status::Ok();
  }
  const CheckArray& reference = *options.reference;
  const TensorShape& shape = report->output;
  if (reference.height != shape.height || reference.width != shape.width ||
      reference.channels != shape.channels) {
    return Status::Error("--check-output " + reference.path + ": shape " + reference.shape_text +
                         " differs from the model's output " + std::to_string(shape.height) + "x" +
                         std::to_string(shape.width) + "x" + std::to_string(shape.channels));
  }
  Compare(output, reference, options.tolerance, report);
  if (report->non_finite > 0) return Status::Error("parity check failed: " + NonFinite(*report));
  if (!(report->relative_error <= options.tolerance)) {
    return Status::Error(
        "parity check failed: max error relative to the reference's largest "
        "value " +
        Sci(report->relative_error) + " exceeds the tolerance " + Sci(options.tolerance) + " (" +
        GroupDigits(report->pixels_over) + " pixels over)");
  }
  report->passed = true;
  return Status::Ok();
}

}  // namespace

Status CheckModel(const std::shared_ptr<const Model>& model, const CheckOptions& options,
                  CheckReport* report) {
  report->kind = options.kind;
  switch (options.kind) {
    case CheckOptions::Kind::kNone:
      report->passed = true;
      return Status::Ok();
    case CheckOptions::Kind::kSeeded:
      return SeededCheck(model, options, report);
    case CheckOptions::Kind::kParity:
      return ParityCheck(model, options, report);
  }
  return Status::Error("check: unknown kind");
}

}  // namespace sfrt::exporter
