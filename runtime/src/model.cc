#include "sfrt/model.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string_view>
#include <unordered_map>

#include "ops/layer_op.h"
#include "sfrt/crc32c.h"
#include "sfrt/layer_kinds.h"
#include "sfrt/model_limits.h"
#include "sfrt/vocabulary/stereo_input.h"
#include "sfrt_model_generated.h"

namespace sfrt {

static_assert(std::endian::native == std::endian::little,
              "the model file is little-endian and is used in place");

namespace fb = ::sfrt::schema;
static_assert(static_cast<int>(fb::VersionProbe::VT_VERSION) ==
                      static_cast<int>(fb::Model::VT_VERSION) &&
                  static_cast<int>(fb::VersionProbe::VT_FILE_CRC32C) ==
                      static_cast<int>(fb::Model::VT_FILE_CRC32C),
              "VersionProbe must keep Model's field numbers");

// How the model's bytes are held. Exactly one of the members is in use.
struct Model::Storage {
  void* mapping = nullptr;  // munmap on destruction
  size_t mapping_size = 0;
  void* owned = nullptr;  // std::free on destruction (64-byte aligned copy)

  ~Storage() {
    if (mapping != nullptr) munmap(mapping, mapping_size);
    std::free(owned);
  }
};

namespace {

constexpr size_t kTensorAlignment = 64;
// Limits that keep a hostile file from making verification or planning pathological; the
// importers check the same table (sfrt/model_limits.h).
using model_limits::kMaxChannels;
using model_limits::kMaxLayers;

std::string Hex32(uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "0x%08x", v);
  return buf;
}

std::string Str(const flatbuffers::String* s) { return s != nullptr ? s->str() : std::string(); }

// "a,b,c".
std::string Join(const std::vector<std::string>& words) {
  std::string text;
  for (const std::string& w : words) text += (text.empty() ? "" : ",") + w;
  return text;
}

// The file's image slot as the vocabulary spells it (its names are string literals, so data()
// ends in a NUL); null for a value the schema does not know.
const char* ImageSlotName(fb::ImageSlot s) {
  using vocabulary::ImageSlot;
  switch (s) {
    case fb::ImageSlot::Left0:
      return vocabulary::ImageSlotName(ImageSlot::kLeft0).data();
    case fb::ImageSlot::Right0:
      return vocabulary::ImageSlotName(ImageSlot::kRight0).data();
    case fb::ImageSlot::Left1:
      return vocabulary::ImageSlotName(ImageSlot::kLeft1).data();
    case fb::ImageSlot::Right1:
      return vocabulary::ImageSlotName(ImageSlot::kRight1).data();
    case fb::ImageSlot::Color0:
      return vocabulary::ImageSlotName(ImageSlot::kColor0).data();
    case fb::ImageSlot::Depth0:
      return vocabulary::ImageSlotName(ImageSlot::kDepth0).data();
    case fb::ImageSlot::Color1:
      return vocabulary::ImageSlotName(ImageSlot::kColor1).data();
    case fb::ImageSlot::Depth1:
      return vocabulary::ImageSlotName(ImageSlot::kDepth1).data();
  }
  return nullptr;
}

// Collects one-line errors prefixed by the model's label.
class Checker {
 public:
  explicit Checker(const std::string& label) : label_(label) {}
  Status Fail(const std::string& what) const { return Status::Error(label_ + ": " + what); }

 private:
  const std::string& label_;
};

// Layer `index`'s inputs as indices (kModelInput or an earlier layer) from the names the file
// gives; none given: the previous layer (layer 0: the input), the form of files before 1.5.
Status ResolveInputs(const Checker& check, const std::string& where,
                     const flatbuffers::Vector<flatbuffers::Offset<flatbuffers::String>>* names,
                     unsigned index, const std::unordered_map<std::string, int>& tensor_named,
                     int ambiguous, const std::string& input_name, std::vector<int>& inputs) {
  if (names == nullptr || names->size() == 0) {
    inputs.assign(1, static_cast<int>(index) - 1);
    return Status::Ok();
  }
  if (names->size() > static_cast<unsigned>(model_limits::kMaxLayers)) {
    return check.Fail(where + ": names " + std::to_string(names->size()) + " inputs; at most " +
                      std::to_string(model_limits::kMaxLayers) + " are supported");
  }
  for (unsigned k = 0; k < names->size(); ++k) {
    const std::string name = names->Get(k) == nullptr ? "" : names->Get(k)->str();
    const auto found = tensor_named.find(name);
    if (found == tensor_named.end()) {
      return check.Fail(where + ": inputs[" + std::to_string(k) + "] is '" + name +
                        "', which is neither the model input ('" + input_name +
                        "') nor a layer before it (a layer comes after the layers it reads)");
    }
    if (found->second == ambiguous) {
      return check.Fail(where + ": inputs[" + std::to_string(k) + "] is '" + name +
                        "', which names more than one earlier tensor");
    }
    inputs.push_back(found->second);
  }
  return Status::Ok();
}

// The graph as a whole: every layer's output but the last is read. Fills the consumer counts and
// whether the graph is a chain. int8 and bf16 convolutions may sit anywhere: in a graph, or beside
// a float32-only op (Float32OnlyKind), they read and write float32 tensors (Session, reference.h).
Status CheckGraph(const Checker& check, const std::vector<LayerDesc>& layers,
                  std::vector<int>& consumers, bool& is_chain) {
  consumers.assign(layers.size(), 0);
  is_chain = true;
  for (size_t i = 0; i < layers.size(); ++i) {
    for (int t : layers[i].inputs) {
      if (t != kModelInput) ++consumers[static_cast<size_t>(t)];
    }
    if (layers[i].inputs != std::vector<int>{static_cast<int>(i) - 1}) is_chain = false;
  }
  for (size_t i = 0; i + 1 < layers.size(); ++i) {
    if (consumers[i] == 0) {
      return check.Fail("layer " + std::to_string(i) + " '" + layers[i].name +
                        "': no layer reads its output (only the last layer's output leaves "
                        "the model)");
    }
  }
  return Status::Ok();
}

// Steps 1 and 2 of verification: size, identifier, schema version (through the one-field probe,
// before trusting the rest of the layout) and the whole-file checksum.
Status CheckHeader(const Checker& check, const uint8_t* data, size_t size,
                   const LoadOptions& options, ModelMetadata& metadata) {
  // 1. Size and identifier.
  if (size < 8) {
    return check.Fail("file is " + std::to_string(size) +
                      " bytes, too small to be a model file (truncated?)");
  }
  if (size > FLATBUFFERS_MAX_BUFFER_SIZE) {
    return check.Fail("file is " + std::to_string(size) + " bytes, above the 2 GiB format limit");
  }
  if (!flatbuffers::BufferHasIdentifier(data, fb::ModelIdentifier())) {
    std::string found;
    for (int i = 4; i < 8; ++i) {
      const char c = static_cast<char>(data[i]);
      found += (c >= 0x20 && c < 0x7F) ? std::string(1, c) : "\\x" + Hex32(data[i]).substr(8);
    }
    return check.Fail("not an sfrt model file: file identifier is '" + found + "', expected '" +
                      fb::ModelIdentifier() + "'");
  }

  // 2. Version, through the one-field probe, before trusting the rest of the layout.
  {
    flatbuffers::Verifier probe_verifier(data, size);
    if (!probe_verifier.VerifyBuffer<fb::VersionProbe>(fb::ModelIdentifier())) {
      return check.Fail("corrupt model file: its header does not verify (truncated or damaged)");
    }
    const fb::Version* v = flatbuffers::GetRoot<fb::VersionProbe>(data)->version();
    metadata.schema_major = v->major();
    metadata.schema_minor = v->minor();
    if (v->major() != kSchemaVersionMajor) {
      return check.Fail("model file has schema version " + std::to_string(v->major()) + "." +
                        std::to_string(v->minor()) + " but this runtime reads version " +
                        std::to_string(kSchemaVersionMajor) + ".x only; export the model again" +
                        (v->major() > kSchemaVersionMajor ? " with this sfrt or upgrade sfrt"
                                                          : " with this sfrt"));
    }
    // 2b. The whole-file checksum (schema 1.1), before anything else in the file is read. It is
    // checked whenever the field is present, whatever the minor version says, so that damage to
    // the version itself is caught too.
    const auto* root =
        reinterpret_cast<const flatbuffers::Table*>(flatbuffers::GetRoot<fb::VersionProbe>(data));
    if (const uint8_t* field = root->GetAddressOf(fb::VersionProbe::VT_FILE_CRC32C)) {
      const size_t offset = static_cast<size_t>(field - data);
      const uint32_t recorded = flatbuffers::ReadScalar<uint32_t>(field);
      metadata.file_crc32c = recorded;
      if (options.verify_checksum) {
        static constexpr uint8_t kZeros[4] = {0, 0, 0, 0};
        uint32_t crc = Crc32c(0, data, offset);
        crc = Crc32c(crc, kZeros, sizeof(kZeros));
        crc = Crc32c(crc, data + offset + 4, size - offset - 4);
        if (crc != recorded) {
          return check.Fail("file checksum mismatch: the file records CRC-32C " + Hex32(recorded) +
                            " but its " + std::to_string(size) + " bytes give " + Hex32(crc) +
                            " (truncated or damaged)");
        }
      }
    } else if (v->minor() >= 1) {
      return check.Fail("model file has schema version " + std::to_string(v->major()) + "." +
                        std::to_string(v->minor()) +
                        " but no file checksum (field file_crc32c); the file is damaged");
    }
  }
  return Status::Ok();
}

// The input's image slots (schema 1.4; RGB-D 1.11): known, none twice, never a mix of stereo
// images and RGB-D frames, and as many channels as the input has.
Status ReadImageOrder(const Checker& check, const fb::InputDesc& in, InputDesc& input) {
  int image_channels = 0;
  int rgbd_slots = 0;
  std::array<bool, vocabulary::kImageSlots> seen{};
  for (auto slot : *in.image_order()) {
    const char* name = ImageSlotName(static_cast<fb::ImageSlot>(slot));
    if (name == nullptr) {
      return check.Fail("input.image_order holds unknown image slot " +
                        std::to_string(static_cast<int>(slot)));
    }
    const vocabulary::ImageSlot word = *vocabulary::ImageSlotFromName(name);
    if (seen[static_cast<size_t>(word)]) {
      return check.Fail(std::string("input.image_order names ") + name + " twice");
    }
    seen[static_cast<size_t>(word)] = true;
    input.image_order.push_back(name);
    image_channels += vocabulary::SlotChannels(word);
    rgbd_slots += vocabulary::IsRgbdSlot(word) ? 1 : 0;
  }
  const int slots = static_cast<int>(input.image_order.size());
  if (rgbd_slots != 0 && rgbd_slots != slots) {
    return check.Fail("input.image_order mixes stereo images and RGB-D frames (" +
                      Join(input.image_order) + ")");
  }
  if (rgbd_slots != 0 && rgbd_slots != 4) {
    return check.Fail("input.image_order names " + std::to_string(rgbd_slots) +
                      " of the RGB-D frames' slots (" + Join(input.image_order) +
                      "); must name color0, depth0, color1 and depth1");
  }
  if (slots != 0 && image_channels != input.channels) {
    return check.Fail("input.image_order names " + std::to_string(slots) + " images (" +
                      std::to_string(image_channels) + " channels) but input.channels is " +
                      std::to_string(input.channels));
  }
  return Status::Ok();
}

// The input: its name, channels, image slots, colour order and normalisation.
Status ReadInput(const Checker& check, const fb::InputDesc* in, InputDesc& input) {
  if (in == nullptr) return check.Fail("field 'input' is missing");
  input.name = Str(in->name());
  input.channels = in->channels();
  if (input.channels <= 0 || input.channels > kMaxChannels) {
    return check.Fail("input.channels is " + std::to_string(input.channels) + "; must be in 1.." +
                      std::to_string(kMaxChannels));
  }
  if (in->image_order() != nullptr) {
    if (Status s = ReadImageOrder(check, *in, input); !s.ok()) return s;
  }
  switch (in->color_order()) {
    case fb::ColorOrder::BGR:
      input.color_order = vocabulary::ColorOrderName(vocabulary::ColorOrder::kBGR);
      break;
    case fb::ColorOrder::RGB:
      input.color_order = vocabulary::ColorOrderName(vocabulary::ColorOrder::kRGB);
      break;
    default:
      return check.Fail("input.color_order is unknown value " +
                        std::to_string(static_cast<int>(in->color_order())));
  }
  input.scale = in->scale();
  if (!std::isfinite(input.scale) || input.scale == 0.0f) {
    return check.Fail("input.scale is " + std::to_string(input.scale) +
                      "; must be finite, non-zero");
  }
  for (const auto& [vec, dst, field] :
       {std::tuple{in->mean(), input.mean, "mean"}, std::tuple{in->std(), input.std, "std"}}) {
    if (vec == nullptr || vec->size() == 0) continue;
    if (vec->size() != 3) {
      return check.Fail(std::string("input.") + field + " has " + std::to_string(vec->size()) +
                        " values; must have 3 (one per colour channel) or none");
    }
    for (int c = 0; c < 3; ++c) dst[c] = vec->Get(c);
  }
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(input.mean[c]) || !std::isfinite(input.std[c]) || input.std[c] == 0.0f) {
      return check.Fail("input.mean/std[" + std::to_string(c) + "] must be finite, std non-zero");
    }
  }
  input.traced_height = in->traced_height();
  input.traced_width = in->traced_width();
  input.depth_mean = in->depth_mean();
  input.depth_std = in->depth_std();
  input.depth_invalid = in->depth_invalid();
  if (!std::isfinite(input.depth_mean) || !std::isfinite(input.depth_std) ||
      input.depth_std == 0.0f || !std::isfinite(input.depth_invalid)) {
    return check.Fail("input.depth_mean, depth_std, depth_invalid are " +
                      std::to_string(input.depth_mean) + ", " + std::to_string(input.depth_std) +
                      ", " + std::to_string(input.depth_invalid) +
                      "; must be finite, depth_std non-zero");
  }
  return Status::Ok();
}

// What the file says about itself beside the input and the layers: its name and producer, the
// output, the training camera, the weights' checksum, whether it was trained.
void ReadDescription(const fb::Model* m, ModelMetadata& metadata) {
  metadata.name = Str(m->name());
  if (const fb::Producer* p = m->producer()) {
    metadata.exporter_version = Str(p->exporter_version());
    metadata.source_format = Str(p->source_format());
    metadata.source_file = Str(p->source_file());
    metadata.source_sha256 = Str(p->source_sha256());
  }
  if (const fb::OutputDesc* out = m->output()) {
    metadata.output.name = Str(out->name());
    metadata.output.channels = out->channels();
    metadata.output.units = Str(out->units());
    metadata.output.units_declared = metadata.schema_minor >= 2;
    if (out->channel_names() != nullptr) {
      for (const auto* s : *out->channel_names()) metadata.output.channel_names.push_back(Str(s));
    }
  }
  if (const fb::Camera* cam = m->camera()) {
    metadata.camera = {cam->focal_px(), cam->baseline(), cam->cx(), cam->cy()};
  }
  metadata.weights_crc32c = m->weights_crc32c();
  // A value from a later minor version that this runtime does not know reads as unknown.
  switch (m->training()) {
    case fb::TrainingState::Trained:
      metadata.training = TrainingState::kTrained;
      break;
    case fb::TrainingState::Untrained:
      metadata.training = TrainingState::kUntrained;
      break;
    default:
      metadata.training = TrainingState::kUnknown;
      break;
  }
}

// The layers, each parsed and checked by its kind's unit (ops/layer_op.h), in file order; every
// input resolved to an earlier layer or the model input. Returns the last layer's channels.
Status ReadLayers(const Checker& check, const std::string& label, const fb::Model* m,
                  ops::WeightStore& weights, ModelMetadata& metadata,
                  std::vector<LayerDesc>& layers, int* last_channels) {
  const InputDesc& input = metadata.input;
  if (m->layers() == nullptr || m->layers()->size() == 0) {
    return check.Fail("the model has no layers");
  }
  if (m->layers()->size() > static_cast<unsigned>(kMaxLayers)) {
    return check.Fail("the model has " + std::to_string(m->layers()->size()) + " layers; at most " +
                      std::to_string(kMaxLayers) + " are supported");
  }
  layers.reserve(m->layers()->size());
  std::vector<int> channels_of;  // output channels per layer
  channels_of.reserve(m->layers()->size());
  // The names Layer.inputs may use: the model input's and the earlier layers'.
  constexpr int kAmbiguous = -2;
  std::unordered_map<std::string, int> tensor_named;
  tensor_named[input.name] = kModelInput;
  for (unsigned i = 0; i < m->layers()->size(); ++i) {
    const fb::Layer* fl = m->layers()->Get(i);
    LayerDesc layer;
    layer.name = Str(fl->name());
    if (layer.name.empty()) layer.name = "#" + std::to_string(i);
    const std::string where = "layer " + std::to_string(i) + " '" + layer.name + "'";
    if (Status s = ResolveInputs(check, where, fl->inputs(), i, tensor_named, kAmbiguous,
                                 input.name, layer.inputs);
        !s.ok()) {
      return s;
    }
    // The verifier accepts a union whose type is set but whose table is absent.
    if (fl->op_type() != fb::LayerOp::NONE && fl->op() == nullptr) {
      return check.Fail(where + ": op type " + std::to_string(static_cast<int>(fl->op_type())) +
                        " has no op table (damaged file)");
    }
    const ops::LayerOp* op = ops::OpStoredAs(fl->op_type());
    if (op == nullptr) {
      return check.Fail(where + ": op type " + std::to_string(static_cast<int>(fl->op_type())) +
                        " is missing or unknown to this runtime");
    }
    ops::LayerReader reader(label, where, *fl, layers, channels_of, input.channels, weights,
                            metadata);
    int channels = 0;
    if (Status s = op->parse(reader, layer, &channels); !s.ok()) return s;
    channels_of.push_back(channels);
    auto [named, fresh] = tensor_named.emplace(layer.name, static_cast<int>(i));
    if (!fresh) named->second = kAmbiguous;
    layers.push_back(std::move(layer));
  }
  *last_channels = channels_of.back();
  return Status::Ok();
}

// In a chain with int8 tensors between layers, an int8 convolution that feeds an int8
// convolution (through upsamplings and crops) hands it bytes quantised with its output_quant: the
// reader must read them with the same parameters. (Between float32 tensors each int8 convolution
// quantises its own input.)
Status CheckInt8Handovers(const Checker& check, const std::vector<LayerDesc>& layers) {
  for (size_t i = 0, prev = layers.size(); i < layers.size(); ++i) {
    if (layers[i].kind != LayerKind::kConv2D) continue;
    if (prev < layers.size()) {
      const ConvParams& a = layers[prev].conv;
      const ConvParams& b = layers[i].conv;
      if (a.precision == Precision::kInt8 && b.precision == Precision::kInt8 &&
          !(a.output_quant == b.input_quant)) {
        return check.Fail("layer " + std::to_string(i) + " '" + layers[i].name +
                          "': input_quant (scale " + std::to_string(b.input_quant.scale) +
                          ", zero_point " + std::to_string(b.input_quant.zero_point) +
                          ") differs from the output_quant of layer '" + layers[prev].name +
                          "' (scale " + std::to_string(a.output_quant.scale) + ", zero_point " +
                          std::to_string(a.output_quant.zero_point) + ") that feeds it");
      }
    }
    prev = i;
  }
  return Status::Ok();
}

CalibrationDesc ReadCalibration(const fb::Calibration* cal) {
  CalibrationDesc c;
  c.method = Str(cal->method());
  c.data_sha256 = Str(cal->data_sha256());
  c.frames = cal->frames();
  c.height = cal->height();
  c.width = cal->width();
  c.output_max_rel = cal->output_max_rel();
  c.output_rms_rel = cal->output_rms_rel();
  if (cal->layers() != nullptr) {
    for (const fb::LayerError* e : *cal->layers()) {
      c.layers.push_back({Str(e->layer()),
                          e->precision() == fb::Precision::Int8       ? Precision::kInt8
                          : e->precision() == fb::Precision::BFloat16 ? Precision::kBFloat16
                                                                      : Precision::kFloat32,
                          e->relative_rms()});
    }
  }
  return c;
}

}  // namespace

bool InputDesc::is_rgbd() const {
  for (const std::string& slot : image_order) {
    const std::optional<vocabulary::ImageSlot> word = vocabulary::ImageSlotFromName(slot);
    if (word && vocabulary::IsRgbdSlot(*word)) return true;
  }
  return false;
}

const char* ResizeModeName(ResizeMode mode) {
  switch (mode) {
    case ResizeMode::kNearest:
      return "nearest";
    case ResizeMode::kLinear:
      return "linear";
    case ResizeMode::kCubic:
      return "cubic";
  }
  return "?";
}

const char* ResizeCoordinatesName(ResizeCoordinates coordinates) {
  switch (coordinates) {
    case ResizeCoordinates::kHalfPixel:
      return "half_pixel";
    case ResizeCoordinates::kPytorchHalfPixel:
      return "pytorch_half_pixel";
    case ResizeCoordinates::kAlignCorners:
      return "align_corners";
    case ResizeCoordinates::kAsymmetric:
      return "asymmetric";
    case ResizeCoordinates::kTfHalfPixelForNn:
      return "tf_half_pixel_for_nn";
    case ResizeCoordinates::kTfCropAndResize:
      return "tf_crop_and_resize";
  }
  return "?";
}

const char* NearestRoundingName(NearestRounding rounding) {
  switch (rounding) {
    case NearestRounding::kRoundPreferFloor:
      return "round_prefer_floor";
    case NearestRounding::kRoundPreferCeil:
      return "round_prefer_ceil";
    case NearestRounding::kFloor:
      return "floor";
    case NearestRounding::kCeil:
      return "ceil";
  }
  return "?";
}

const char* PaddingRuleName(PaddingRule rule) {
  switch (rule) {
    case PaddingRule::kExplicit:
      return "explicit";
    case PaddingRule::kSameUpper:
      return "same-upper";
    case PaddingRule::kSameLower:
      return "same-lower";
  }
  return "?";
}

const char* ActivationName(Activation activation) {
  switch (activation) {
    case Activation::kNone:
      return "none";
    case Activation::kRelu:
      return "relu";
    case Activation::kLeakyRelu:
      return "leaky-relu";
    case Activation::kElu:
      return "elu";
    case Activation::kSigmoid:
      return "sigmoid";
    case Activation::kTanh:
      return "tanh";
    case Activation::kClip:
      return "clip";
  }
  return "?";
}

std::string PrecisionSummary(const ModelMetadata& metadata) {
  if (metadata.has_int8 && metadata.has_bf16) return "int8+bf16+fp32";
  if (metadata.has_int8) return "int8 (some layers fp32)";
  if (metadata.has_bf16) return "bf16 (some layers fp32)";
  return metadata.weight_type == WeightType::kFloat16 ? "fp32 (fp16 weights)" : "fp32";
}

Model::~Model() = default;

size_t Model::parameter_count() const {
  size_t n = 0;
  for (const LayerDesc& l : layers_) n += static_cast<size_t>(LayerParameterCount(l));
  return n;
}

Result<std::shared_ptr<const Model>> Model::LoadFile(const std::string& path,
                                                     const LoadOptions& options) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Status::Error(path + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int err = errno;
    ::close(fd);
    return Status::Error(path + ": cannot stat: " + std::strerror(err));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    return Status::Error(path + ": not a regular file");
  }
  const size_t size = static_cast<size_t>(st.st_size);
  if (size == 0) {
    ::close(fd);
    return Status::Error(path + ": file is empty (0 bytes); not a model file");
  }
  void* mapping = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
  const int map_errno = errno;
  ::close(fd);
  if (mapping == MAP_FAILED)
    return Status::Error(path + ": cannot mmap: " + std::strerror(map_errno));

  std::shared_ptr<Model> model(new Model());
  model->storage_ = std::make_unique<Storage>();
  model->storage_->mapping = mapping;
  model->storage_->mapping_size = size;
  model->data_ = static_cast<const uint8_t*>(mapping);
  model->size_ = size;
  Status s = model->Parse(options, path);
  if (!s.ok()) return s;
  return std::shared_ptr<const Model>(std::move(model));
}

Result<std::shared_ptr<const Model>> Model::LoadBuffer(const void* data, size_t size,
                                                       BufferOwnership ownership,
                                                       const LoadOptions& options,
                                                       const std::string& label) {
  if (data == nullptr || size == 0) {
    return Status::Error(label + ": buffer is empty (0 bytes); not a model file");
  }
  std::shared_ptr<Model> model(new Model());
  model->storage_ = std::make_unique<Storage>();
  if (ownership == BufferOwnership::kCopy) {
    const size_t rounded = (size + kTensorAlignment - 1) / kTensorAlignment * kTensorAlignment;
    void* copy = std::aligned_alloc(kTensorAlignment, rounded);
    if (copy == nullptr) return Status::Error(label + ": out of memory copying the model");
    std::memcpy(copy, data, size);
    model->storage_->owned = copy;
    model->data_ = static_cast<const uint8_t*>(copy);
  } else {
    if (reinterpret_cast<uintptr_t>(data) % kTensorAlignment != 0) {
      return Status::Error(label +
                           ": a borrowed model buffer must be 64-byte aligned (weights are"
                           " used in place); load it with BufferOwnership::kCopy instead");
    }
    model->data_ = static_cast<const uint8_t*>(data);
  }
  model->size_ = size;
  Status s = model->Parse(options, label);
  if (!s.ok()) return s;
  return std::shared_ptr<const Model>(std::move(model));
}

Status Model::Parse(const LoadOptions& options, const std::string& label) {
  const Checker check(label);
  if (Status s = CheckHeader(check, data_, size_, options, metadata_); !s.ok()) return s;

  // 3. The whole structure.
  flatbuffers::Verifier::Options vopts;
  vopts.max_depth = 16;
  vopts.max_tables = 1'000'000;
  flatbuffers::Verifier verifier(data_, size_, vopts);
  if (!fb::VerifyModelBuffer(verifier)) {
    return check.Fail(
        "corrupt model file: FlatBuffers verification failed (truncated or damaged structure)");
  }
  const fb::Model* m = fb::GetModel(data_);

  // 4. What the file says about itself, and the input.
  ReadDescription(m, metadata_);
  if (Status s = ReadInput(check, m->input(), metadata_.input); !s.ok()) return s;

  // 5. The layers, the graph they make, the output they give.
  ops::WeightStore weights{data_, options.verify_checksum, 0, false, &widened_};
  int channels = 0;
  if (Status s = ReadLayers(check, label, m, weights, metadata_, layers_, &channels); !s.ok()) {
    return s;
  }
  if (Status s = CheckGraph(check, layers_, consumers_, is_chain_); !s.ok()) return s;
  float32_between_layers_ =
      !is_chain_ || std::any_of(layers_.begin(), layers_.end(),
                                [](const LayerDesc& l) { return Float32OnlyKind(l.kind); });
  if (metadata_.output.channels == 0) metadata_.output.channels = channels;
  if (metadata_.output.channels != channels) {
    return check.Fail("output.channels is " + std::to_string(metadata_.output.channels) +
                      " but the last layer produces " + std::to_string(channels));
  }
  metadata_.weight_type = weights.saw_fp16 ? WeightType::kFloat16 : WeightType::kFloat32;
  if (!float32_between_layers_) {
    if (Status s = CheckInt8Handovers(check, layers_); !s.ok()) return s;
  }
  if (const fb::Calibration* cal = m->calibration()) metadata_.calibration = ReadCalibration(cal);

  // 6. Checksum last, over exactly the bytes the layers use.
  if (options.verify_checksum && weights.crc != metadata_.weights_crc32c) {
    return check.Fail("weights checksum mismatch: the file records CRC-32C " +
                      Hex32(metadata_.weights_crc32c) + " but the weights give " +
                      Hex32(weights.crc) + " (the weights are damaged)");
  }
  return Status::Ok();
}

}  // namespace sfrt
