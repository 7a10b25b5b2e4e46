// sfrt export: a trained network (ONNX for now) -> a verified .sfrt model file.
#include <CLI/CLI.hpp>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "sfrt/commands.h"
#include "sfrt/exporter/model_spec.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/onnx_importer.h"
#include "sfrt/io/atomic_write.h"
#include "sfrt/model.h"
#include "sfrt/shapes.h"

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
  float scale = 1.0f;
  std::string mean;
  std::string std;
  float focal = 0;
  float baseline = 0;
  float cx = 0;
  float cy = 0;
};

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string FormatFloat(float v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", static_cast<double>(v));
  return buf;
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

// "L0,R0,L1,R1" (or left0,right0,...; any case) -> a permutation of the four image slots.
bool ParseImageOrder(const std::string& text, std::vector<exporter::ImageSlot>* out,
                     std::string* error) {
  out->clear();
  size_t start = 0;
  while (true) {
    size_t comma = text.find(',', start);
    std::string token = Upper(text.substr(start, comma - start));
    while (!token.empty() && token.front() == ' ') token.erase(token.begin());
    while (!token.empty() && token.back() == ' ') token.pop_back();
    exporter::ImageSlot slot;
    if (token == "L0" || token == "LEFT0") {
      slot = exporter::ImageSlot::kLeft0;
    } else if (token == "R0" || token == "RIGHT0") {
      slot = exporter::ImageSlot::kRight0;
    } else if (token == "L1" || token == "LEFT1") {
      slot = exporter::ImageSlot::kLeft1;
    } else if (token == "R1" || token == "RIGHT1") {
      slot = exporter::ImageSlot::kRight1;
    } else {
      *error = "--image-order: unknown image '" + token + "' (use L0, R0, L1, R1)";
      return false;
    }
    for (exporter::ImageSlot seen : *out) {
      if (seen == slot) {
        *error = "--image-order: image '" + token + "' appears twice";
        return false;
      }
    }
    out->push_back(slot);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (out->size() != 4) {
    *error =
        "--image-order: expected the four images L0,R0,L1,R1 in some order, got '" + text + "'";
    return false;
  }
  return true;
}

// One line describing how the model's convolutions pad, as the loaded file states it.
std::string DescribePadding(const Model& model) {
  int same_upper = 0;
  int explicit_pads = 0;
  for (const LayerDesc& layer : model.layers()) {
    if (layer.kind != LayerKind::kConv2D) continue;
    if (layer.conv.padding_rule == PaddingRule::kSameUpper) {
      ++same_upper;
    } else {
      ++explicit_pads;
    }
  }
  const InputDesc& in = model.metadata().input;
  std::string traced = in.traced_height > 0 ? std::to_string(in.traced_height) + "x" +
                                                  std::to_string(in.traced_width)
                                            : "an unknown size";
  if (explicit_pads == 0) {
    return "same-upper at all " + std::to_string(same_upper) +
           " convs (pads computed per input size)";
  }
  if (same_upper == 0) {
    return "explicit at all " + std::to_string(explicit_pads) + " convs (the amounts traced at " +
           traced + ", applied unchanged at every size)";
  }
  return "mixed: " + std::to_string(same_upper) + " convs same-upper, " +
         std::to_string(explicit_pads) + " explicit (as traced at " + traced + ")";
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
  std::vector<exporter::ImageSlot> image_order = defaults.input.image_order;
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
  if (!(args.focal > 0) || !std::isfinite(args.focal)) {
    return ReportError(kName, "--focal: must be a positive number of pixels", kExitUsage);
  }
  if (!(args.baseline > 0) || !std::isfinite(args.baseline)) {
    return ReportError(kName, "--baseline: must be positive", kExitUsage);
  }
  if (!std::isfinite(args.cx) || !std::isfinite(args.cy)) {
    return ReportError(kName, "--cx/--cy: must be finite numbers", kExitUsage);
  }
  exporter::OnnxImportOptions import_options;
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
  const std::string ext = LowerExtension(args.input);
  if (ext == ".h5" || ext == ".hdf5" || ext == ".keras") {
    return ReportError(kName,
                       args.input +
                           ": Keras HDF5 import is not implemented yet (issue #3); "
                           "export the network to ONNX and pass the .onnx file",
                       kExitUsage);
  }
  if (ext != ".onnx") {
    return ReportError(kName,
                       args.input + ": unsupported input format '" +
                           (ext.empty() ? std::string("(no extension)") : ext) +
                           "' (supported: .onnx; Keras .h5 is planned, issue #3)",
                       kExitUsage);
  }
  if (args.output.empty()) return ReportError(kName, "-o: output path is empty", kExitUsage);

  // Import.
  if (std::string problem = CheckInputFile(args.input, "input file"); !problem.empty()) {
    return ReportError(kName, problem, kExitFailure);
  }
  if (std::string problem = CheckOutputDirectory(args.output); !problem.empty()) {
    return ReportError(kName, problem, kExitFailure);
  }
  Result<exporter::ModelSpec> imported = exporter::ImportOnnx(args.input, import_options);
  if (!imported.ok()) return ReportError(kName, imported.message(), kExitFailure);
  exporter::ModelSpec spec = std::move(imported).value();

  // Apply the flags.
  if (!args.name.empty()) spec.name = args.name;
  spec.input.image_order = image_order;
  spec.input.color_order = color_order;
  spec.input.scale = args.scale;
  spec.input.mean = mean;
  spec.input.std = stddev;
  spec.camera.focal_px = args.focal;
  spec.camera.baseline = args.baseline;
  spec.camera.cx = args.cx;
  spec.camera.cy = args.cy;

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
  const Model& model = **loaded;
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

  if (Status s = WriteFileAtomically(args.output, *bytes); !s.ok()) {
    return ReportError(kName, s.message(), kExitFailure);
  }

  int convs = 0;
  int upsamples = 0;
  int crops = 0;
  for (const LayerDesc& layer : model.layers()) {
    convs += layer.kind == LayerKind::kConv2D;
    upsamples += layer.kind == LayerKind::kUpsample;
    crops += layer.kind == LayerKind::kCrop;
  }
  std::string order;
  for (const std::string& slot : meta.input.image_order) {
    if (!order.empty()) order += ",";
    order += slot;
  }
  const std::string traced =
      meta.input.traced_height > 0
          ? std::to_string(meta.input.traced_height) + "x" + std::to_string(meta.input.traced_width)
          : "unknown";
  std::cout << "sfrt export: " << args.input << " -> " << args.output << "\n"
            << "  source      " << meta.source_format << ", sha256 " << meta.source_sha256 << "\n"
            << "  name        " << meta.name << "\n"
            << "  layers      " << model.layers().size() << " (" << convs << " conv, " << upsamples
            << " upsample, " << crops << " crop), traced at " << traced << "\n"
            << "  parameters  " << GroupDigits(model.parameter_count()) << "\n"
            << "  padding     " << DescribePadding(model) << "\n"
            << "  shapes      " << shapes_line << "\n"
            << "  input       " << meta.input.channels << " channels: " << order << ", "
            << meta.input.color_order << ", value = (pixel * " << FormatFloat(meta.input.scale)
            << " - mean) / std, mean " << FormatFloat(meta.input.mean[0]) << ","
            << FormatFloat(meta.input.mean[1]) << "," << FormatFloat(meta.input.mean[2]) << ", std "
            << FormatFloat(meta.input.std[0]) << "," << FormatFloat(meta.input.std[1]) << ","
            << FormatFloat(meta.input.std[2]) << "\n"
            << "  camera      f " << FormatFloat(meta.camera.focal_px) << " px, baseline "
            << FormatFloat(meta.camera.baseline) << ", cx " << FormatFloat(meta.camera.cx)
            << ", cy " << FormatFloat(meta.camera.cy) << "\n"
            << "  file        " << GroupDigits(model.file_bytes())
            << " bytes, loads and verifies (CRC-32C ok)\n";
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

  CLI::App* cmd =
      parent.add_subcommand("export", "Convert a trained network (.onnx) into a .sfrt model file");
  cmd->add_option("model", args->input, "Source network (.onnx)")->required();
  cmd->add_option("-o,--output", args->output, "Model file to write (.sfrt)")->required();
  cmd->add_option("--name", args->name,
                  "Model name stored in the file (default: " + defaults.name + ")");
  cmd->add_option("--padding", args->padding,
                  "How conv padding is stored: auto (same-upper if every conv's pads equal the "
                  "same-upper amounts at the traced size, else explicit), same-upper (fail if "
                  "the traced pads contradict it), explicit (keep the traced numbers)")
      ->check(CLI::IsMember({"auto", "same-upper", "explicit"}))
      ->capture_default_str();
  cmd->add_option("--color-order", args->color_order,
                  "Channel order the network was trained on: BGR or RGB (default: BGR, as "
                  "OpenCV reads images)");
  cmd->add_option("--image-order", args->image_order,
                  "Order of the four images along the input channels, e.g. L0,R0,L1,R1 "
                  "(default; L = left, R = right, 0 = time t, 1 = t+1)");
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
  cmd->add_option("--baseline", args->baseline, "Training camera stereo baseline (scene units)")
      ->capture_default_str();
  cmd->add_option("--cx", args->cx, "Training camera principal point x (pixels)")
      ->capture_default_str();
  cmd->add_option("--cy", args->cy, "Training camera principal point y (pixels)")
      ->capture_default_str();
  cmd->footer(
      "Reads ONNX as torch.onnx.export writes it (Keras .h5 import is not implemented yet,\n"
      "issue #3). Records the preprocessing and the training camera given by the flags; the\n"
      "defaults are the SceneEDNet authors' setup (BGR, L0,R0,L1,R1, raw 0..255 pixels,\n"
      "FlyingThings3D camera). Writes the file atomically, then loads it back to verify it.\n"
      "Exit codes: 0 success, 1 import/write/verify failure, 2 usage error.");
  return Command{cmd, [args] { return RunExport(*args); }};
}

}  // namespace sfrt::tools
