#include "sfrt/exporter/model_writer.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <map>

#include "sfrt/crc32c.h"
#include "sfrt/model.h"
#include "sfrt_model_generated.h"
#include "writers/layer_writer.h"

namespace sfrt::exporter {
namespace {

namespace fb = ::sfrt::schema;
using writers::ToSchema;

fb::ImageSlot ToSchema(ImageSlot s) {
  switch (s) {
    case ImageSlot::kLeft0:
      return fb::ImageSlot::Left0;
    case ImageSlot::kRight0:
      return fb::ImageSlot::Right0;
    case ImageSlot::kLeft1:
      return fb::ImageSlot::Left1;
    case ImageSlot::kRight1:
      return fb::ImageSlot::Right1;
    case ImageSlot::kColor0:
      return fb::ImageSlot::Color0;
    case ImageSlot::kDepth0:
      return fb::ImageSlot::Depth0;
    case ImageSlot::kColor1:
      return fb::ImageSlot::Color1;
    case ImageSlot::kDepth1:
      return fb::ImageSlot::Depth1;
  }
  return fb::ImageSlot::Left0;
}

std::string LayerLabel(size_t i, const std::string& name) {
  return "layer " + std::to_string(i) + " '" + name + "'";
}

flatbuffers::Offset<fb::Calibration> AddCalibration(flatbuffers::FlatBufferBuilder& b,
                                                    const CalibrationDesc& c) {
  std::vector<flatbuffers::Offset<fb::LayerError>> errors;
  for (const LayerErrorDesc& e : c.layers) {
    errors.push_back(
        fb::CreateLayerError(b, b.CreateString(e.layer), ToSchema(e.precision), e.relative_rms));
  }
  return fb::CreateCalibration(b, b.CreateString(c.method), b.CreateString(c.data_sha256), c.frames,
                               c.height, c.width, c.output_max_rel, c.output_rms_rel,
                               b.CreateVector(errors));
}

}  // namespace

const char* ExporterVersion() { return SFRT_VERSION; }

Status UpdateFileChecksum(std::span<uint8_t> file) {
  flatbuffers::Verifier verifier(file.data(), file.size());
  if (!verifier.VerifyBuffer<fb::VersionProbe>(fb::ModelIdentifier())) {
    return Status::Error("cannot set the file checksum: the model's root table does not verify");
  }
  const auto* root = reinterpret_cast<const flatbuffers::Table*>(
      flatbuffers::GetRoot<fb::VersionProbe>(file.data()));
  const uint8_t* field = root->GetAddressOf(fb::VersionProbe::VT_FILE_CRC32C);
  if (field == nullptr) {
    return Status::Error(
        "cannot set the file checksum: the model has no file_crc32c field (schema 1.0 layout)");
  }
  uint8_t* at = file.data() + (field - file.data());
  std::memset(at, 0, 4);
  const uint32_t crc = Crc32c(0, file.data(), file.size());
  for (int i = 0; i < 4; ++i) at[i] = static_cast<uint8_t>(crc >> (8 * i));  // little-endian
  return Status::Ok();
}

namespace {

Status CheckSpec(const ModelSpec& spec, const SerializeOptions& options) {
  if (options.schema_minor < 0 || options.schema_minor > kSchemaVersionMinor) {
    return Status::Error("schema version 1." + std::to_string(options.schema_minor) +
                         " cannot be written; this exporter writes 1.0 to 1." +
                         std::to_string(kSchemaVersionMinor));
  }
  if (spec.layers.empty()) return Status::Error("model '" + spec.name + "' has no layers");
  if (spec.input.channels <= 0) {
    return Status::Error("input.channels is " + std::to_string(spec.input.channels));
  }
  return Status::Ok();
}

struct WrittenLayers {
  std::vector<flatbuffers::Offset<fb::Layer>> layers;
  int channels = 0;  // the last layer's output channels
};

// The layers, each by its kind's writer (writers/), in order: tensors are written in layer
// order, weights then bias, which defines the checksum order.
Result<WrittenLayers> WriteLayers(writers::TensorWriter& w, const ModelSpec& spec,
                                  const SerializeOptions& options) {
  auto& b = w.builder();
  WrittenLayers out;
  // Output channels by tensor name; the previous layer's under "" (what an empty `inputs` reads).
  std::map<std::string, int> channels_of{{spec.input.name, spec.input.channels},
                                         {"", spec.input.channels}};
  for (size_t i = 0; i < spec.layers.size(); ++i) {
    const LayerSpec& ls = spec.layers[i];
    const std::string& layer_name =
        std::visit([](const auto& l) -> const std::string& { return l.name; }, ls);
    const std::vector<std::string>& inputs =
        std::visit([](const auto& l) -> const std::vector<std::string>& { return l.inputs; }, ls);
    const std::string where = LayerLabel(i, layer_name);
    if (!inputs.empty() && options.schema_minor < 5) {
      return Status::Error(where + ": named inputs need schema 1.5; writing 1." +
                           std::to_string(options.schema_minor));
    }
    std::vector<int> read;  // channels of each input
    for (const std::string& name : inputs.empty() ? std::vector<std::string>{""} : inputs) {
      const auto found = channels_of.find(name);
      if (found == channels_of.end()) {
        return Status::Error(where + ": reads '" + name +
                             "', which is neither the input nor an earlier layer");
      }
      read.push_back(found->second);
    }
    const auto names = inputs.empty() ? 0 : b.CreateVectorOfStrings(inputs);
    writers::LayerWriting lw{w,      options.schema_minor, where, read, inputs.size(), names, 0,
                             read[0]};
    if (Status st = std::visit([&lw](const auto& l) { return writers::Write(l, lw); }, ls);
        !st.ok()) {
      return st;
    }
    out.layers.push_back(lw.layer);
    out.channels = lw.channels;
    channels_of[layer_name] = lw.channels;
    channels_of[""] = lw.channels;
  }
  return out;
}

Status CheckOutput(const OutputSpec& output, int channels) {
  if (output.channels != channels) {
    return Status::Error("output.channels is " + std::to_string(output.channels) +
                         " but the last layer produces " + std::to_string(channels));
  }
  if (!output.channel_names.empty() && static_cast<int>(output.channel_names.size()) != channels) {
    return Status::Error("output.channel_names has " + std::to_string(output.channel_names.size()) +
                         " names for an output of " + std::to_string(channels) +
                         " channels; give one per channel or none");
  }
  return Status::Ok();
}

Result<flatbuffers::Offset<fb::InputDesc>> WriteInput(flatbuffers::FlatBufferBuilder& b,
                                                      const InputSpec& in,
                                                      const SerializeOptions& options) {
  std::vector<fb::ImageSlot> order;
  for (ImageSlot s : in.image_order) {
    if (vocabulary::IsRgbdSlot(s) && options.schema_minor < 11) {
      return Status::Error("input: RGB-D frames (image slot " +
                           std::string(vocabulary::ImageSlotName(s)) +
                           ") need schema 1.11; writing 1." + std::to_string(options.schema_minor));
    }
    order.push_back(ToSchema(s));
  }
  return fb::CreateInputDesc(
      b, b.CreateString(in.name), in.channels, b.CreateVector(order),
      in.color_order == ColorOrder::kBGR ? fb::ColorOrder::BGR : fb::ColorOrder::RGB, in.scale,
      b.CreateVector(in.mean.data(), 3), b.CreateVector(in.std.data(), 3), in.traced_height,
      in.traced_width, in.depth_mean, in.depth_std, in.depth_invalid);
}

flatbuffers::Offset<fb::OutputDesc> WriteOutput(flatbuffers::FlatBufferBuilder& b,
                                                const OutputSpec& out,
                                                const SerializeOptions& options) {
  std::vector<flatbuffers::Offset<flatbuffers::String>> names;
  for (const auto& n : out.channel_names) names.push_back(b.CreateString(n));
  // Before 1.2 the field held a fixed text, which 1.0 files keep.
  const std::string units = options.schema_minor < 2 ? "training-camera scene units (baseline = 1)"
                            : out.units.empty()      ? "unknown"
                                                     : out.units;
  return fb::CreateOutputDesc(b, b.CreateString(out.name), out.channels, b.CreateVector(names),
                              b.CreateString(units));
}

fb::TrainingState TrainingStateOf(const ModelSpec& spec, const SerializeOptions& options) {
  if (options.schema_minor < 2) return fb::TrainingState::Unknown;
  if (spec.training == TrainingState::kTrained) return fb::TrainingState::Trained;
  if (spec.training == TrainingState::kUntrained) return fb::TrainingState::Untrained;
  return fb::TrainingState::Unknown;
}

}  // namespace

Result<std::vector<uint8_t>> SerializeModel(const ModelSpec& spec,
                                            const SerializeOptions& options) {
  if (Status s = CheckSpec(spec, options); !s.ok()) return s;
  writers::TensorWriter w(spec.weight_type);
  auto& b = w.builder();
  Result<WrittenLayers> written = WriteLayers(w, spec, options);
  if (!written.ok()) return written.status();
  if (Status s = CheckOutput(spec.output, written->channels); !s.ok()) return s;

  const auto layers_offset = b.CreateVector(written->layers);
  const ProducerSpec& ps = spec.producer;
  const auto producer = fb::CreateProducer(
      b, b.CreateString(ps.exporter_version.empty() ? ExporterVersion() : ps.exporter_version),
      b.CreateString(ps.source_format), b.CreateString(ps.source_file),
      b.CreateString(ps.source_sha256));
  Result<flatbuffers::Offset<fb::InputDesc>> input = WriteInput(b, spec.input, options);
  if (!input.ok()) return input.status();
  if (spec.calibration && options.schema_minor < 3) {
    return Status::Error("a calibration record needs schema 1.3; writing 1." +
                         std::to_string(options.schema_minor));
  }
  const auto output = WriteOutput(b, spec.output, options);
  const auto camera = fb::CreateCamera(b, spec.camera.focal_px, spec.camera.baseline,
                                       spec.camera.cx, spec.camera.cy);
  const fb::Version version(static_cast<uint16_t>(kSchemaVersionMajor),
                            static_cast<uint16_t>(options.schema_minor));
  // 1.1: file_crc32c is written with a non-default placeholder (so that the field is stored) and
  // patched once the buffer is finished.
  const bool file_checksum = options.schema_minor >= 1;
  const auto calibration = spec.calibration ? AddCalibration(b, *spec.calibration) : 0;
  const auto model = fb::CreateModel(
      b, &version, b.CreateString(spec.name), producer, *input, output, camera, layers_offset,
      w.crc(), file_checksum ? 0xFFFFFFFFu : 0u, TrainingStateOf(spec, options), calibration);
  fb::FinishModelBuffer(b, model);
  std::vector<uint8_t> file(b.GetBufferPointer(), b.GetBufferPointer() + b.GetSize());
  if (file_checksum) {
    if (Status s = UpdateFileChecksum(file); !s.ok()) return s;
  }
  return file;
}

}  // namespace sfrt::exporter
