// sfrt export's report (export_report.h).
#include "sfrt/export_report.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <iostream>
#include <utility>

#include "sfrt/commands.h"
#include "sfrt/model_notes.h"

namespace sfrt::tools {
namespace {

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

// One line describing how the model's convolutions pad, as the loaded file states it.
std::string PaddingLine(const Model& model) {
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

// "12 (9 conv, 2 upsample, 1 crop, 1 concat)": the three kinds of a SceneEDNet chain always,
// the others (the ops beyond a chain of convolutions) where the model has them.
std::string LayersLine(const Model& model) {
  struct Counted {
    LayerKind kind;
    const char* word;
    bool always;
  };
  static constexpr Counted kCounted[] = {{LayerKind::kConv2D, "conv", true},
                                         {LayerKind::kUpsample, "upsample", true},
                                         {LayerKind::kCrop, "crop", true},
                                         {LayerKind::kConvTranspose2D, "deconv", false},
                                         {LayerKind::kPool2D, "pool", false},
                                         {LayerKind::kResize, "resize", false},
                                         {LayerKind::kChannelAffine, "affine", false},
                                         {LayerKind::kConcat, "concat", false},
                                         {LayerKind::kAdd, "add", false}};
  std::string line = std::to_string(model.layers().size()) + " (";
  bool first = true;
  for (const Counted& c : kCounted) {
    const auto count = std::count_if(model.layers().begin(), model.layers().end(),
                                     [&](const LayerDesc& l) { return l.kind == c.kind; });
    if (count == 0 && !c.always) continue;
    line += (first ? "" : ", ") + std::to_string(count) + " " + c.word;
    first = false;
  }
  return line + ")";
}

// The precision lines: bf16 marking, or the quantisation's calibration and errors.
std::vector<std::string> PrecisionLines(const exporter::ExportOptions& options,
                                        const exporter::ExportResult& result) {
  std::vector<std::string> lines;
  if (options.precision == exporter::PrecisionChange::kBFloat16) {
    const int marked = result.bf16_convolutions;
    const int convs = result.convolutions;
    lines.push_back("  precision   bf16, " +
                    (marked == convs ? "all " + std::to_string(convs)
                                     : std::to_string(marked) + " of " + std::to_string(convs)) +
                    " convolutions (weights stored as --weights says, rounded to bf16 when a "
                    "session loads them; activations bf16 between the bf16 convolutions of a "
                    "chain, float32 in a graph or around a float32-only layer)");
  }
  if (!result.calibration) return lines;
  const CalibrationDesc& cal = *result.calibration;
  const exporter::QuantizeOptions& q = options.quantize;
  size_t int8 = 0, bf16 = 0, name_width = 0;
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
  if (q.mode == exporter::QuantizeMode::kAuto) {
    precision += " (--precision auto, accuracy budget " + ErrorText(q.accuracy_budget) +
                 " on the output's " +
                 (q.accuracy_metric == exporter::AccuracyMetric::kMax ? "largest" : "rms") +
                 " error)";
    if (int8 + bf16 == 0) precision += "; no int8 or bf16 convolution fits: the file is float32";
  }
  lines.push_back("  precision   " + precision);
  lines.push_back("  calibration " + cal.method + ", " + std::to_string(cal.frames) +
                  " frames of " + std::to_string(cal.height) + "x" + std::to_string(cal.width) +
                  ", data sha256 " + cal.data_sha256);
  lines.push_back("  frames      " + result.calibration_described);
  lines.push_back("  error       output max " + ErrorText(cal.output_max_rel) + ", rms " +
                  ErrorText(cal.output_rms_rel) +
                  " relative to float32 over the calibration frames, on " +
                  (q.engine == exporter::CalibrationEngine::kReference
                       ? std::string("the reference kernels")
                       : std::string("this CPU's ") + IsaName(BestIsa()) + " kernels"));
  for (const LayerErrorDesc& e : cal.layers) {
    lines.push_back("  layer       " + e.layer + std::string(name_width - e.layer.size(), ' ') +
                    "  " + PrecisionName(e.precision) + "  relative rms " +
                    ErrorText(e.relative_rms));
  }
  for (const std::string& step : result.auto_steps) lines.push_back("  auto        " + step);
  return lines;
}

std::string FiniteText(const exporter::CheckReport& r) {
  return r.non_finite == 0 ? "yes" : "NO (" + std::to_string(r.non_finite) + ")";
}

std::string ParityLine(const std::string& reference, const exporter::CheckReport& r) {
  char share[32];
  std::snprintf(share, sizeof(share), "%.3f%%",
                r.pixels > 0 ? 100.0 * static_cast<double>(r.pixels_over) / r.pixels : 0.0);
  return "  parity      vs " + reference + ": max abs error " + ErrorText(r.max_abs_error) +
         ", reference max |value| " + ErrorText(r.reference_max) + ", max error relative to it " +
         ErrorText(r.relative_error) + " (tolerance " + ErrorText(r.tolerance) +
         "), pixels over tolerance " + GroupDigits(r.pixels_over) + " of " + GroupDigits(r.pixels) +
         " (" + share + "), finite " + (r.non_finite == 0 ? "yes" : "NO");
}

}  // namespace

std::vector<std::string> CheckLines(const exporter::CheckOptions& check,
                                    const exporter::CheckReport& r) {
  std::vector<std::string> lines;
  if (!r.ran) return lines;
  char line[512];
  if (r.kind == exporter::CheckOptions::Kind::kSeeded) {
    std::snprintf(line, sizeof(line),
                  "  check       seeded input (pixels uniform 0..255, seed %u) at %dx%d -> output "
                  "%dx%dx%d in %.0f ms",
                  r.seed, r.height, r.width, r.output.height, r.output.width, r.output.channels,
                  r.ms);
    lines.push_back(line);
    lines.push_back("  output      min " + ErrorText(r.min) + ", max " + ErrorText(r.max) +
                    ", mean " + ErrorText(r.mean) + ", std " + ErrorText(r.stddev) + "; finite " +
                    FiniteText(r));
    return lines;
  }
  std::snprintf(line, sizeof(line),
                "  check       input %s (%dx%dx%d) -> output %dx%dx%d in %.0f ms",
                check.input.path.c_str(), r.height, r.width, r.channels, r.output.height,
                r.output.width, r.output.channels, r.ms);
  lines.push_back(line);
  if (!check.reference) {
    lines.push_back("  output      min " + ErrorText(r.min) + ", max " + ErrorText(r.max) +
                    "; finite " + FiniteText(r));
    return lines;
  }
  if (r.compared) lines.push_back(ParityLine(check.reference->path, r));
  if (r.compared && r.passed) lines.push_back("  parity      ok");
  return lines;
}

void PrintExportReport(const exporter::ExportOptions& options,
                       const exporter::ExportResult& result) {
  const Model& model = *result.model;
  const ModelMetadata& meta = model.metadata();
  const std::string traced =
      meta.input.traced_height > 0
          ? std::to_string(meta.input.traced_height) + "x" + std::to_string(meta.input.traced_width)
          : "unknown";
  std::string shapes = "not checked (traced size unknown)";
  if (const std::optional<TensorShape>& out = result.traced_output) {
    shapes = "at the traced size " + traced + " the output is " + std::to_string(out->height) +
             "x" + std::to_string(out->width) + "x" + std::to_string(out->channels);
  }
  std::cout << "sfrt export: " << options.source << " -> " << options.destination << "\n"
            << "  source      " << meta.source_format << ", sha256 " << meta.source_sha256 << "\n"
            << "  name        " << meta.name << "\n"
            << "  layers      " << LayersLine(model) << ", traced at " << traced << "\n"
            << "  parameters  " << GroupDigits(model.parameter_count()) << "\n"
            << "  padding     " << PaddingLine(model) << "\n"
            << "  shapes      " << shapes << "\n"
            << "  input       " << InputLine(meta.input) << "\n"
            << "  camera      f " << FormatFloat(meta.camera.focal_px) << " px, baseline "
            << FormatFloat(meta.camera.baseline) << ", cx " << FormatFloat(meta.camera.cx)
            << ", cy " << FormatFloat(meta.camera.cy) << "\n"
            << "  units       " << UnitsText(meta) << "\n"
            << "  training    " << TrainingStateName(meta.training) << "\n"
            << "  weights     " << WeightsLine(model) << "\n"
            << "  file        " << GroupDigits(model.file_bytes())
            << " bytes, loads and verifies (CRC-32C ok)\n";
  for (const std::string& note : result.notes) std::cout << "  note        " << note << "\n";
  for (const std::string& line : PrecisionLines(options, result)) std::cout << line << "\n";
  if (result.check) {
    for (const std::string& line : CheckLines(options.check, *result.check)) {
      std::cout << line << "\n";
    }
  }
}

}  // namespace sfrt::tools
