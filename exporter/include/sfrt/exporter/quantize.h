// Post-training quantisation of a float32 ModelSpec to int8 convolutions (schema 1.3), from a
// calibration set, with the errors it causes measured against float32. Pure library: no I/O.
//
// Method "percentile:P" (docs/model-format.md, "Calibration"):
// - Activations: every tensor an int8 convolution reads or writes (the model input, and each
//   convolution's output) is observed on the float32 model over all calibration frames
//   (QuantizeOptions::engine: a Session's RunObserved, or RunReferenceForward). Pass 1 finds
//   its [min, max]; pass 2 counts its values into 4096 equal bins over [min, max].
//   hi = the upper edge of the bin holding the value of rank ceil(P/100 * count) from the
//   bottom, lo = the lower edge of the bin holding the value of the same rank from the top
//   (P = 100: min and max exactly). Then lo = min(lo, 0) and hi = max(hi, 0), so that real zero
//   is exactly representable: scale = (hi - lo) / 255, zero_point = round(-lo / scale) clamped
//   to 0..255; a tensor that is 0 everywhere gets scale 1, zero point 0. "minmax" is
//   percentile:100.
// - Weights: symmetric per output channel, scale = max |w| / 127 (1 for a channel of zeros),
//   q = round-half-even(w / scale) clamped to -127..127. Biases stay float (with
//   QuantizeOptions::bias_correction, moved by the mean error each channel shows).
// - A convolution's input_quant is the quantisation of the tensor it reads (the previous
//   convolution's output, through any upsampling and crop, or the model input), its
//   output_quant that of its own output: so an int8 convolution feeding an int8 convolution
//   always hands over exactly the parameters the reader expects.
// Errors (the quantised model vs float32, both on the engine's kernels, over the calibration
// set, sums over all frames; a tensor a session keeps uint8 between int8 convolutions is
// measured as it holds it, dequantised): per convolution relative_rms = RMS(out - fp32 out) /
// RMS(fp32 out) (0 when both are 0, infinity when only the reference is); the model output's
// output_max_rel = max |diff| / max |fp32| and output_rms_rel likewise.
// Everything is deterministic: the same spec, data and options give the same bytes, whatever
// QuantizeOptions::threads, on one CPU (and on every CPU with CalibrationEngine::kReference).
#pragma once

#include <functional>
#include <span>
#include <string>
#include <vector>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/model.h"
#include "sfrt/status.h"

namespace sfrt::exporter {

// The network input for calibration, as Session::Run and `sfrt infer --input-npy` take it.
struct CalibrationSet {
  int frames = 0;
  int height = 0;
  int width = 0;
  int channels = 0;
  std::vector<float> values;  // frames x height x width x channels, frame after frame
};

enum class QuantizeMode {
  kInt8,  // every convolution int8
  // Start from every convolution int8; while the output's error (accuracy_metric) exceeds
  // accuracy_budget, move one step up (int8 -> bf16 with QuantizeOptions::auto_bf16, else
  // int8 -> float32; bf16 -> float32) the convolution whose error in the same metric (its
  // output's relative rms, or its largest error relative to its largest |float32 value|) rose
  // most over that of the tensor it reads (the previous convolution's; 0 for the model input),
  // the earliest on a tie, and measure again. Ends with every convolution float32 at worst.
  kAuto,
};

// Which of the output's errors against float32 kAuto holds within its budget: the relative RMS
// error (Errors::output_rms_rel) or the largest error relative to the largest |float32 output|
// (output_max_rel, the measure of issue 12's fixture bars).
enum class AccuracyMetric { kRms, kMax };

// What runs the forward passes of calibration and measurement.
enum class CalibrationEngine {
  // A Session per worker thread (sfrt/session.h, RunObserved) on this CPU's fastest kernels,
  // tens of times faster than the reference. Its float32 layers (Winograd, SIMD sums) round
  // their last bits by the ISA, so a CPU with other kernels may give other ranges and errors.
  kSession,
  // The scalar reference forward pass (sfrt/reference.h): the same file on every CPU; slow (a
  // full-width SceneEDNet frame takes about 20 s per pass).
  kReference,
};

struct QuantizeOptions {
  QuantizeMode mode = QuantizeMode::kInt8;
  double accuracy_budget = 0.02;  // kAuto: the largest output error accepted
  AccuracyMetric accuracy_metric = AccuracyMetric::kRms;
  // kAuto: an int8 layer over the budget tries bf16 before float32 (bf16 is faster than float32
  // where the CPU has bf16 kernels, and slower where it has not).
  bool auto_bf16 = true;
  std::string method = "percentile:99.99";
  // Graphs: convolutions whose inputs come from one tensor (through nearest upsamplings, crops
  // and Concats; SharedScaleGroups) read one quantisation, from the union of their ranges, so
  // that a session keeps those tensors uint8 instead of converting float32 at each reader.
  // false: each convolution's input gets its own range. Chains are the same either way. The
  // record's method then ends in ", shared scales" (where some group has two members).
  bool shared_scales = true;
  // kInt8 only: empirical bias correction. After the ranges and weights are chosen, each int8
  // convolution in turn has its (float) bias moved, per output channel, by the mean over the
  // calibration frames and pixels of its error before the activation against float32, measured
  // on the quantised model with the corrections before it made: one pass over the frames per
  // convolution, and one of the float32 model. The value before the activation is its output
  // with leaky ReLU inverted (no activation: as it is); a convolution with another activation
  // keeps its bias. The record's method then ends in ", bias correction". It removes the part
  // of the error that is the same at every pixel of a channel (rounding of weights and inputs
  // that does not average out over a sum).
  bool bias_correction = false;
  CalibrationEngine engine = CalibrationEngine::kSession;
  // Calibration frames run on this many threads at once (at most one per frame; with kSession,
  // threads left over go to each frame's session). Each worker holds one forward pass's tensors
  // (kSession: a session of the float32 model and one of the quantised model), so memory grows
  // with it; the result does not change by a bit (ranges are minima and maxima, histograms
  // integer counts, the error sums are added in frame order, and a session's output does not
  // depend on its thread count).
  int threads = 1;
  // Called after each frame of each pass, one call at a time, `frame` counting the frames done:
  // pass is "range", "histogram" or "measure", and with bias_correction "bias correction:
  // float32" and "bias correction: LAYER" for each corrected convolution.
  std::function<void(const char* pass, int frame, int frames)> progress;
};

struct QuantizeResult {
  // The model as quantised; spec.calibration is set when some convolution is int8.
  ModelSpec spec;
  CalibrationDesc calibration;  // the method, data and measured errors of `spec`, always
  // kAuto: one line per convolution put back to float32, in order, with the errors that did it.
  std::vector<std::string> auto_steps;
};

// Quantises `model` (every convolution float32) as `options` say. Errors name the frame, element
// or layer at fault: an invalid calibration set (CheckCalibrationSet), a model that cannot run at
// the frames' size, an unknown method.
Result<QuantizeResult> Quantize(const ModelSpec& model, const CalibrationSet& data,
                                const QuantizeOptions& options);

// The building blocks, also for tests.

// The set holds at least one frame of `channels` channels, values.size() matches, every value is
// finite (an error names frame, [y, x, c] and the flat index), and not every frame is constant.
Status CheckCalibrationSet(const CalibrationSet& data, int channels);

struct CalibrationMethod {
  double percentile = 100;
  std::string text;  // as written into the file: "percentile:99.99" (P in %g form) or "minmax"
};
// "percentile:P" with 50 <= P <= 100, or "minmax" (P = 100). Errors name the text.
Result<CalibrationMethod> ParseCalibrationMethod(const std::string& method);

// The uint8 quantisation of a tensor with values in [lo, hi] (lo and hi first widened to include
// 0), as defined above.
QuantParams ActivationQuantParams(double lo, double hi);

// For the convolutions at `conv_layers` (indices into `layers`), a group number each: two are in
// one group when the values they read come, through nearest upsamplings, crops (their first
// input) and Concats, from one convolution's output, directly or through other members. Groups
// are numbered by their first member; in a chain each convolution is a group of its own.
std::vector<int> SharedScaleGroups(std::span<const LayerDesc> layers,
                                   std::span<const int> conv_layers);

// Symmetric per-output-channel int8 weights of an HWIO tensor with `out_channels` outputs.
void QuantizeWeights(std::span<const float> hwio, int out_channels, std::vector<int8_t>* q,
                     std::vector<float>* scales);

// The phase kernels of a 3x3 convolution that reads a nearest-2x upsampling (sfrt/model.h,
// ConvParams::phase_weights_q): for phase (py, px) and tap (ty, tx), the float sum of the 3x3
// taps that read the same low-resolution pixel (along an axis, phase 0: tap 0 = w0 + w1,
// tap 1 = w2; phase 1: tap 0 = w0, tap 1 = w1 + w2), each phase then quantised like
// QuantizeWeights. q: [4][2][2][in][out]; scales: [4][out].
void QuantizePhaseWeights(std::span<const float> hwio3x3, int in_channels, int out_channels,
                          std::vector<int8_t>* q, std::vector<float>* scales);

// The SHA-256 (lowercase hex) of the calibration values as little-endian float32, in order.
std::string CalibrationDataSha256(const CalibrationSet& data);

}  // namespace sfrt::exporter
