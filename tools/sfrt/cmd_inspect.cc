// sfrt inspect: what a .sfrt model file holds and what it costs at one input size.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "sfrt/commands.h"
#include "sfrt/config/limits.h"
#include "sfrt/layer_kinds.h"
#include "sfrt/model.h"
#include "sfrt/model_notes.h"
#include "sfrt/session.h"
#include "sfrt/session_environment.h"
#include "sfrt/shapes.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "inspect";

struct InspectArgs {
  std::string model;
  std::string size;
  bool print_plan = false;
};

std::string Triple(const float v[3]) {
  return FormatFloat(v[0]) + "," + FormatFloat(v[1]) + "," + FormatFloat(v[2]);
}

// The input's kind: stereo images or RGB-D frames with their order and preprocessing, or a plain
// tensor.
std::string InputKindLines(const InputDesc& input) {
  if (input.is_tensor()) return "  kind            plain tensor, fed as given\n";
  std::string lines =
      std::string("  kind            ") + (input.is_rgbd() ? "RGB-D frames" : "images") +
      "\n  image order     " + Join(input.image_order, ",") + "\n  color order     " +
      input.color_order + "\n  value           (pixel * " + FormatFloat(input.scale) +
      " - mean[c]) / std[c], mean " + Triple(input.mean) + ", std " + Triple(input.std) + "\n";
  if (input.is_rgbd()) {
    lines += "  depth value     (metres - " + FormatFloat(input.depth_mean) + ") / " +
             FormatFloat(input.depth_std) + ", missing depth (0) as " +
             FormatFloat(input.depth_invalid) + "\n";
  }
  return lines;
}

std::string ShapeString(const TensorShape& s) {
  return std::to_string(s.height) + "x" + std::to_string(s.width) + "x" +
         std::to_string(s.channels);
}

// What a layer of a graph model reads, when it is not just the layer before it: " <- a, b".
std::string InputsSuffix(const Model& model, size_t i) {
  const LayerDesc& layer = model.layers()[i];
  if (layer.inputs.size() == 1 && layer.inputs[0] == static_cast<int>(i) - 1) return "";
  std::string names;
  for (int t : layer.inputs) {
    names += names.empty() ? " <- " : ", ";
    names += t == kModelInput ? model.metadata().input.name
                              : model.layers()[static_cast<size_t>(t)].name;
  }
  return names;
}

// A text table: left-aligned text columns, right-aligned number columns.
class Table {
 public:
  explicit Table(std::vector<std::pair<std::string, bool>> columns)  // (title, right-aligned)
      : columns_(std::move(columns)) {}
  void Add(std::vector<std::string> row) { rows_.push_back(std::move(row)); }
  void Print(std::ostream& out, const std::string& indent) const {
    std::vector<size_t> width(columns_.size());
    for (size_t c = 0; c < columns_.size(); ++c) {
      width[c] = columns_[c].first.size();
      for (const auto& row : rows_) width[c] = std::max(width[c], row[c].size());
    }
    auto line = [&](const std::vector<std::string>& cells) {
      std::string s = indent;
      for (size_t c = 0; c < cells.size(); ++c) {
        std::string pad(width[c] - cells[c].size(), ' ');
        if (c > 0) s += "  ";
        s += columns_[c].second ? pad + cells[c] : cells[c] + pad;
      }
      while (!s.empty() && s.back() == ' ') s.pop_back();
      out << s << "\n";
    };
    std::vector<std::string> titles;
    for (const auto& col : columns_) titles.push_back(col.first);
    line(titles);
    for (const auto& row : rows_) line(row);
  }

 private:
  std::vector<std::pair<std::string, bool>> columns_;
  std::vector<std::vector<std::string>> rows_;
};

// Weights are stored as float16 (2 bytes) or float32 (4 bytes) each; the runtime widens float16
// to float32 once at load.
std::string WeightStorageLine(const Model& model) {
  const uint64_t params = model.parameter_count();
  if (std::string int8 = Int8LayersText(model); !int8.empty()) {
    return int8 + ", " +
           (model.metadata().weight_type == WeightType::kFloat16 ? "float16" : "float32") +
           " elsewhere (" + GroupDigits(StoredParameterBytes(model)) + " bytes stored)";
  }
  if (model.metadata().weight_type == WeightType::kFloat16) {
    return "float16 (IEEE half, " + GroupDigits(params * 2) +
           " bytes stored; widened to float32 at load)";
  }
  return "float32 (" + GroupDigits(params * 4) + " bytes stored)";
}

// The file size saved by float16 storage (or that it would save), from the parameter count:
// the rest of the file (metadata, alignment) is the same for both types to within 64 bytes per
// tensor.
std::string Fp32ComparisonLine(const Model& model) {
  const uint64_t params = model.parameter_count();
  const uint64_t file = model.file_bytes();
  char ratio[32];
  if (model.metadata().has_int8) {
    const uint64_t stored = StoredParameterBytes(model);
    const uint64_t as_fp32 = file - std::min(file, stored) + params * 4;
    std::snprintf(ratio, sizeof(ratio), "%.3f", static_cast<double>(file) / as_fp32);
    return "this file is " + std::string(ratio) + " of its float32 size (about " +
           GroupDigits(as_fp32) + " bytes)";
  }
  if (model.metadata().weight_type == WeightType::kFloat16) {
    const uint64_t as_fp32 = file + params * 2;
    std::snprintf(ratio, sizeof(ratio), "%.3f", static_cast<double>(file) / as_fp32);
    return "saves about " + GroupDigits(params * 2) + " bytes: this file is " + ratio +
           " of its float32 size (about " + GroupDigits(as_fp32) + " bytes)";
  }
  const uint64_t as_fp16 = file > params * 2 ? file - params * 2 : 0;
  std::snprintf(ratio, sizeof(ratio), "%.3f", static_cast<double>(as_fp16) / file);
  return "is float32; float16 storage (sfrt export --weights fp16) would save about " +
         GroupDigits(params * 2) + " bytes (" + ratio + " of this size)";
}

// How the quantisation was chosen and what it costs against float32 (schema 1.3).
void PrintCalibration(std::ostream& out, const CalibrationDesc& cal) {
  out << "calibration  (how the int8 quantisation was chosen; errors against float32)\n"
      << "  method          " << cal.method << "\n"
      << "  data sha256     " << cal.data_sha256 << "\n"
      << "  frames          " << cal.frames << " at " << cal.height << "x" << cal.width << "\n"
      << "  output error    max " << ErrorText(cal.output_max_rel) << ", rms "
      << ErrorText(cal.output_rms_rel) << " (max |diff| / max |float32|, RMS diff / RMS float32)\n"
      << "  layer errors    relative rms = RMS(output - float32 output) / RMS(float32 output)\n";
  Table table({{"layer", false}, {"precision", false}, {"relative rms", true}});
  for (const LayerErrorDesc& e : cal.layers) {
    table.Add({e.layer, PrecisionName(e.precision), ErrorText(e.relative_rms)});
  }
  table.Print(out, "    ");
}

// The model's metadata: name, producer, input, output, training camera, weights.
void PrintModelHeader(std::ostream& out, const std::string& path, const Model& model,
                      const std::string& traced) {
  const ModelMetadata& meta = model.metadata();
  char crc[16];
  std::snprintf(crc, sizeof(crc), "0x%08x", static_cast<unsigned>(meta.weights_crc32c));
  out << "model     " << path << "\n"
      << "  name            " << meta.name << "\n"
      << "  schema version  " << meta.schema_major << "." << meta.schema_minor << "\n"
      << "  file size       " << GroupDigits(model.file_bytes()) << " bytes\n"
      << "  training        " << TrainingStateName(meta.training) << "\n"
      << "producer\n"
      << "  exporter        " << meta.exporter_version << "\n"
      << "  source          " << meta.source_format << " file " << meta.source_file << "\n"
      << "  source sha256   " << meta.source_sha256 << "\n"
      << "input     " << meta.input.name << "\n"
      << "  channels        " << meta.input.channels << "\n"
      << InputKindLines(meta.input) << "  traced size     " << traced << "\n"
      << "output    " << meta.output.name << "\n"
      << "  channels        " << meta.output.channels
      << (meta.output.channel_names.empty() ? std::string(" (unnamed)")
                                            : " (" + Join(meta.output.channel_names, ", ") + ")")
      << "\n"
      << "  units           " << UnitsText(meta) << "\n"
      << "camera    (training)\n"
      << "  focal           " << FormatFloat(meta.camera.focal_px) << " px\n"
      << "  baseline        " << BaselineText(meta) << "\n"
      << "  cx, cy          " << FormatFloat(meta.camera.cx) << ", " << FormatFloat(meta.camera.cy)
      << "\n"
      << "weights\n"
      << "  type            " << WeightStorageLine(model) << "\n"
      << "  vs float32      " << Fp32ComparisonLine(model) << "\n"
      << "  CRC-32C         " << crc << "\n";
}

// The layers at height x width: op, precision, pads, output shape, MACs and parameters; then the
// totals.
void PrintLayerTable(std::ostream& out, const Model& model,
                     const std::vector<LayerGeometry>& geometry, int height, int width,
                     const std::string& size_source, const std::string& traced) {
  const ModelMetadata& meta = model.metadata();
  std::span<const LayerDesc> layers = model.layers();
  Table table({{"#", true},
               {"name", false},
               {"op", false},
               {"precision", false},
               {"pads t,l,b,r", false},
               {"output HxWxC", true},
               {"MACs", true},
               {"params", true}});
  uint64_t total_macs = 0;
  uint64_t total_params = 0;
  bool any_explicit = false;
  for (size_t i = 0; i < layers.size(); ++i) {
    const LayerGeometry& g = geometry[i];
    total_macs += g.macs;
    total_params += g.params;
    any_explicit |= layers[i].kind == LayerKind::kConv2D &&
                    layers[i].conv.padding_rule == PaddingRule::kExplicit;
    const bool conv = layers[i].kind == LayerKind::kConv2D;
    const bool deconv = layers[i].kind == LayerKind::kConvTranspose2D;  // float32 only
    table.Add({std::to_string(i), layers[i].name,
               DescribeLayer(layers[i], LayerText::kFull) + InputsSuffix(model, i),
               conv     ? PrecisionName(layers[i].conv.precision)
               : deconv ? PrecisionName(Precision::kFloat32)
                        : "-",
               DescribePadding(layers[i], g), ShapeString(g.output),
               conv || deconv ? GroupDigits(g.macs) : "-",
               g.params > 0 ? GroupDigits(g.params) : "-"});
  }
  char gmac[32];
  std::snprintf(gmac, sizeof(gmac), "%.2f", static_cast<double>(total_macs) / 1e9);
  out << "\nlayers at " << height << "x" << width << " (" << size_source << ")\n";
  table.Print(out, "  ");
  out << "totals\n"
      << "  compute         " << gmac << " GMAC (" << GroupDigits(total_macs) << " MACs)\n"
      << "  parameters      " << GroupDigits(total_params) << "\n"
      << "  weight bytes    " << GroupDigits(StoredParameterBytes(model)) << " ("
      << (meta.has_int8                              ? "int8 and float"
          : meta.weight_type == WeightType::kFloat16 ? "float16"
                                                     : "float32")
      << ")\n";
  if (any_explicit && traced != std::to_string(height) + "x" + std::to_string(width)) {
    out << "  note            explicit pads apply unchanged at every size; if the source padded "
           "by a size-dependent rule (TF/Keras 'same') they are exact only at the traced size "
        << traced << "\n";
  }
}

// --print-plan: where each tensor lives in the arena.
void PrintArenaPlan(std::ostream& out, const Session& session, std::span<const LayerDesc> layers,
                    int height, int width) {
  const size_t arena = session.arena_bytes();
  std::span<const PlannedTensor> plan = session.plan();
  Table plan_table({{"tensor", true},
                    {"producer", false},
                    {"last consumer", false},
                    {"offset", true},
                    {"bytes", true},
                    {"type", false}});
  auto layer_label = [&](int index) -> std::string {
    if (index < 0 || static_cast<size_t>(index) >= layers.size()) return std::to_string(index);
    return std::to_string(index) + " " + layers[static_cast<size_t>(index)].name;
  };
  for (size_t t = 0; t < plan.size(); ++t) {
    plan_table.Add({std::to_string(t), layer_label(plan[t].producer),
                    layer_label(plan[t].last_consumer), GroupDigits(plan[t].offset),
                    GroupDigits(plan[t].bytes),
                    plan[t].is_u8     ? "uint8"
                    : plan[t].is_bf16 ? "bf16"
                                      : "fp32"});
  }
  out << "\narena plan at " << height << "x" << width << " (" << plan.size() << " tensors, "
      << GroupDigits(arena) << " bytes)\n";
  plan_table.Print(out, "  ");
}

int RunInspect(const InspectArgs& args) {
  int height = 0;
  int width = 0;
  if (!args.size.empty() && !ParseSize(args.size, &height, &width)) {
    return ReportError(
        kName,
        "--size: expected HxW with positive integers (e.g. 540x960), got '" + args.size + "'",
        kExitUsage);
  }
  if (!args.size.empty()) {
    if (std::string problem = config::CheckSize(config::kInputSide, "--size", height, width);
        !problem.empty()) {
      return ReportError(kName, problem, kExitUsage);
    }
  }
  Result<std::shared_ptr<const Model>> loaded = LoadModelFile(args.model);
  if (!loaded.ok()) return ReportError(kName, loaded.message(), kExitFailure);
  std::shared_ptr<const Model> model = std::move(loaded).value();
  const ModelMetadata& meta = model->metadata();

  std::string size_source = "--size";
  if (args.size.empty()) size_source = DefaultInputSize(meta, &height, &width);

  std::ostream& out = std::cout;
  if (std::string notice = UntrainedNotice(args.model, meta.training); !notice.empty()) {
    std::cout << notice << "\n";
  }
  const std::string traced =
      meta.input.traced_height > 0
          ? std::to_string(meta.input.traced_height) + "x" + std::to_string(meta.input.traced_width)
          : "unknown";
  PrintModelHeader(out, args.model, *model, traced);
  if (meta.calibration) PrintCalibration(out, *meta.calibration);

  Result<std::vector<LayerGeometry>> geometry = InferGeometry(*model, height, width);
  if (!geometry.ok()) {
    return ReportError(
        kName,
        "at " + std::to_string(height) + "x" + std::to_string(width) + ": " + geometry.message(),
        kExitFailure);
  }
  PrintLayerTable(out, *model, *geometry, height, width, size_source, traced);
  SessionOptions options;
  options.max_height = height;
  options.max_width = width;
  if (Status env = tools::ApplySessionEnvironment(options); !env.ok()) {
    return ReportError(kName, env.message(), kExitUsage);
  }
  Result<std::unique_ptr<Session>> session = Session::Create(model, options);
  if (!session.ok()) {
    return ReportError(kName,
                       "cannot plan a session at " + std::to_string(height) + "x" +
                           std::to_string(width) + ": " + session.message(),
                       kExitFailure);
  }
  const size_t arena = (*session)->arena_bytes();
  char mib[32];
  std::snprintf(mib, sizeof(mib), "%.2f", static_cast<double>(arena) / (1024.0 * 1024.0));
  out << "  arena           " << GroupDigits(arena) << " bytes (" << mib << " MiB) at " << height
      << "x" << width << "\n";

  if (args.print_plan) PrintArenaPlan(out, **session, model->layers(), height, width);
  return kExitOk;
}

}  // namespace

Command AddInspectCommand(CLI::App& parent) {
  auto args = std::make_shared<InspectArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "inspect", "Show a model file's metadata, per-layer shapes and costs, and arena size");
  cmd->add_option("model", args->model, "Model file (.sfrt)")->required();
  cmd->add_option("--size", args->size,
                  "Input size HxW for the layer table and arena (default: the size the model was "
                  "traced at, else 540x960)");
  cmd->add_flag("--print-plan", args->print_plan,
                "Also list every planned arena tensor: producer, last consumer, offset, bytes, "
                "element type");
  cmd->footer(
      "Prints the metadata (name, schema version, producer and source SHA-256, input\n"
      "preprocessing, output channels and units, training camera, weight type, CRC-32C), for\n"
      "an int8 file its calibration (method, data SHA-256, frames and size, output and\n"
      "per-layer errors against float32), then every layer at one input size (op, precision\n"
      "fp32 or int8, pads in effect, output shape, MACs, parameters), the totals, and the\n"
      "arena bytes a session planned for that size needs.\n"
      "Exit codes: 0 success, 1 model fails to load or plan, 2 usage error.");
  return Command{cmd, [args] { return RunInspect(*args); }};
}

}  // namespace sfrt::tools
