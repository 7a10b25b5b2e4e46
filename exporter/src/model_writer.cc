#include "sfrt/exporter/model_writer.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <map>

#include "sfrt/crc32c.h"
#include "sfrt/model.h"
#include "sfrt_model_generated.h"

namespace sfrt::exporter {
namespace {

namespace fb = ::sfrt::schema;
constexpr size_t kTensorAlignment = 64;

// IEEE 754 binary32 -> binary16, round to nearest even; overflow gives infinity.
uint16_t FloatToHalf(float f) {
  const uint32_t x = std::bit_cast<uint32_t>(f);
  const uint16_t sign = static_cast<uint16_t>((x >> 16) & 0x8000u);
  const uint32_t abs = x & 0x7FFFFFFFu;
  if (abs >= 0x7F800000u) {  // inf or NaN (keep NaN quiet)
    return sign | 0x7C00u | (abs > 0x7F800000u ? 0x200u : 0u);
  }
  if (abs >= 0x477FF000u) return sign | 0x7C00u;  // rounds to >= 65520: infinity
  if (abs < 0x38800000u) {                        // below the smallest normal half: subnormal
    // value = abs_float; half subnormal unit is 2^-24.
    const float scaled = std::bit_cast<float>(abs) * 16777216.0f;  // * 2^24, exact
    return sign | static_cast<uint16_t>(std::nearbyint(scaled));   // ties to even (default mode)
  }
  const uint32_t rounded = abs + 0x0FFFu + ((abs >> 13) & 1u);  // round to nearest even
  return sign | static_cast<uint16_t>((rounded - 0x38000000u) >> 13);
}

class Writer {
 public:
  explicit Writer(WeightType type) : type_(type) {}

  flatbuffers::Offset<fb::Tensor> AddTensor(const std::vector<float>& values,
                                            std::initializer_list<int> shape) {
    const size_t elem = type_ == WeightType::kFloat32 ? 4 : 2;
    std::vector<uint8_t> bytes(values.size() * elem);
    if (type_ == WeightType::kFloat32) {
      std::memcpy(bytes.data(), values.data(), bytes.size());
    } else {
      for (size_t i = 0; i < values.size(); ++i) {
        const uint16_t h = FloatToHalf(values[i]);
        std::memcpy(bytes.data() + 2 * i, &h, 2);
      }
    }
    crc_ = Crc32c(crc_, bytes.data(), bytes.size());
    const auto shape_offset = builder_.CreateVector(std::vector<int>(shape));
    builder_.ForceVectorAlignment(bytes.size(), 1, kTensorAlignment);
    const auto data_offset = builder_.CreateVector(bytes);
    return fb::CreateTensor(
        builder_, type_ == WeightType::kFloat32 ? fb::DataType::Float32 : fb::DataType::Float16,
        shape_offset, data_offset);
  }

  // Int8 weights (schema 1.3): the bytes as they are, aligned and checksummed like the others.
  flatbuffers::Offset<fb::Tensor> AddInt8Tensor(const std::vector<int8_t>& values,
                                                std::initializer_list<int> shape) {
    const auto* bytes = reinterpret_cast<const uint8_t*>(values.data());
    crc_ = Crc32c(crc_, bytes, values.size());
    const auto shape_offset = builder_.CreateVector(std::vector<int>(shape));
    builder_.ForceVectorAlignment(values.size(), 1, kTensorAlignment);
    const auto data_offset = builder_.CreateVector(bytes, values.size());
    return fb::CreateTensor(builder_, fb::DataType::Int8, shape_offset, data_offset);
  }

  flatbuffers::FlatBufferBuilder& builder() { return builder_; }
  uint32_t crc() const { return crc_; }

 private:
  WeightType type_;
  flatbuffers::FlatBufferBuilder builder_{1 << 20};
  uint32_t crc_ = 0;
};

fb::PaddingRule ToSchema(PaddingRule r) {
  switch (r) {
    case PaddingRule::kSameUpper:
      return fb::PaddingRule::SameUpper;
    case PaddingRule::kSameLower:
      return fb::PaddingRule::SameLower;
    case PaddingRule::kExplicit:
      break;
  }
  return fb::PaddingRule::Explicit;
}

fb::Activation ToSchema(Activation a) {
  switch (a) {
    case Activation::kNone:
      return fb::Activation::None;
    case Activation::kRelu:
      return fb::Activation::Relu;
    case Activation::kLeakyRelu:
      return fb::Activation::LeakyRelu;
    case Activation::kElu:
      return fb::Activation::Elu;
    case Activation::kSigmoid:
      return fb::Activation::Sigmoid;
    case Activation::kTanh:
      return fb::Activation::Tanh;
    case Activation::kClip:
      return fb::Activation::Clip;
  }
  return fb::Activation::None;
}

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

fb::Precision ToSchema(Precision p) {
  switch (p) {
    case Precision::kInt8:
      return fb::Precision::Int8;
    case Precision::kBFloat16:
      return fb::Precision::BFloat16;
    case Precision::kFloat32:
      break;
  }
  return fb::Precision::Float32;
}

// The counts an int8 convolution's fields must have; empty when they do.
std::string Int8CountProblem(const ConvSpec& c, size_t want) {
  if (!c.weights_hwio.empty()) {
    return "precision is int8 but weights_hwio holds " + std::to_string(c.weights_hwio.size()) +
           " float weights (an int8 layer stores weights_q only)";
  }
  if (c.weights_q.size() != want || c.bias.size() != static_cast<size_t>(c.out_channels) ||
      c.weight_scales.size() != static_cast<size_t>(c.out_channels)) {
    return "holds " + std::to_string(c.weights_q.size()) + " int8 weights, " +
           std::to_string(c.weight_scales.size()) + " weight scales and " +
           std::to_string(c.bias.size()) + " biases; needs " + std::to_string(want) + ", " +
           std::to_string(c.out_channels) + " and " + std::to_string(c.out_channels);
  }
  return "";
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

Result<std::vector<uint8_t>> SerializeModel(const ModelSpec& spec,
                                            const SerializeOptions& options) {
  if (options.schema_minor < 0 || options.schema_minor > kSchemaVersionMinor) {
    return Status::Error("schema version 1." + std::to_string(options.schema_minor) +
                         " cannot be written; this exporter writes 1.0 to 1." +
                         std::to_string(kSchemaVersionMinor));
  }
  if (spec.layers.empty()) return Status::Error("model '" + spec.name + "' has no layers");
  if (spec.input.channels <= 0) {
    return Status::Error("input.channels is " + std::to_string(spec.input.channels));
  }
  Writer w(spec.weight_type);
  auto& b = w.builder();

  // Tensors are written in layer order, weights then bias, which defines the checksum order.
  std::vector<flatbuffers::Offset<fb::Layer>> layers;
  // Output channels by tensor name; the previous layer's under "" (what an empty `inputs` reads).
  std::map<std::string, int> channels_of{{spec.input.name, spec.input.channels},
                                         {"", spec.input.channels}};
  int channels = spec.input.channels;
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
    channels = read[0];
    const auto names = inputs.empty() ? 0 : b.CreateVectorOfStrings(inputs);
    const auto* conv_spec = std::get_if<ConvSpec>(&ls);
    const auto* pool_spec = std::get_if<PoolSpec>(&ls);
    const bool same_lower =
        (conv_spec != nullptr && conv_spec->padding_rule == PaddingRule::kSameLower) ||
        (pool_spec != nullptr && pool_spec->padding_rule == PaddingRule::kSameLower);
    if (same_lower && options.schema_minor < 7) {
      return Status::Error(where + ": padding rule SameLower needs schema 1.7; writing 1." +
                           std::to_string(options.schema_minor));
    }
    // Schema 1.8 fields in use: the layer goes under its op's V2 union member (which readers
    // before 1.8 refuse rather than ignore the fields).
    const auto* deconv_spec = std::get_if<ConvTransposeSpec>(&ls);
    const bool v2 =
        (conv_spec != nullptr &&
         (conv_spec->dilation_h != 1 || conv_spec->dilation_w != 1 || conv_spec->groups != 1)) ||
        (pool_spec != nullptr && (pool_spec->dilation_h != 1 || pool_spec->dilation_w != 1)) ||
        (deconv_spec != nullptr && (deconv_spec->dilation_h != 1 || deconv_spec->dilation_w != 1));
    if (v2 && options.schema_minor < 8) {
      return Status::Error(where + ": dilation or groups other than 1 need schema 1.8; writing 1." +
                           std::to_string(options.schema_minor));
    }
    const auto* affine_spec = std::get_if<ChannelAffineSpec>(&ls);
    if (affine_spec != nullptr && options.schema_minor < 8 &&
        affine_spec->activation != Activation::kNone &&
        affine_spec->activation != Activation::kRelu &&
        affine_spec->activation != Activation::kLeakyRelu) {
      return Status::Error(where + ": activation " + ActivationName(affine_spec->activation) +
                           " needs schema 1.8; writing 1." + std::to_string(options.schema_minor));
    }
    if (const auto* c = std::get_if<ConvSpec>(&ls)) {
      if (c->in_channels != channels) {
        return Status::Error(where + ": in_channels is " + std::to_string(c->in_channels) +
                             " but its input has " + std::to_string(channels));
      }
      if (c->groups < 1 || c->in_channels % c->groups != 0 || c->out_channels % c->groups != 0) {
        return Status::Error(where + ": groups is " + std::to_string(c->groups) +
                             "; must divide in_channels (" + std::to_string(c->in_channels) +
                             ") and out_channels (" + std::to_string(c->out_channels) + ")");
      }
      const int group_in = c->in_channels / c->groups;
      const size_t want =
          static_cast<size_t>(c->kernel_h) * c->kernel_w * group_in * c->out_channels;
      const bool int8 = c->precision == Precision::kInt8;
      if (int8 && options.schema_minor < 3) {
        return Status::Error(where + ": precision int8 needs schema 1.3; writing 1." +
                             std::to_string(options.schema_minor));
      }
      if (c->precision == Precision::kBFloat16 && options.schema_minor < 4) {
        return Status::Error(where + ": precision bf16 needs schema 1.4; writing 1." +
                             std::to_string(options.schema_minor));
      }
      if (int8) {
        if (std::string problem = Int8CountProblem(*c, want); !problem.empty()) {
          return Status::Error(where + ": " + problem);
        }
      } else if (c->weights_hwio.size() != want ||
                 c->bias.size() != static_cast<size_t>(c->out_channels)) {
        return Status::Error(where + ": holds " + std::to_string(c->weights_hwio.size()) +
                             " weights and " + std::to_string(c->bias.size()) + " biases; needs " +
                             std::to_string(want) + " and " + std::to_string(c->out_channels));
      }
      const auto weights =
          int8
              ? w.AddInt8Tensor(c->weights_q, {c->kernel_h, c->kernel_w, group_in, c->out_channels})
              : w.AddTensor(c->weights_hwio, {c->kernel_h, c->kernel_w, group_in, c->out_channels});
      const auto bias = w.AddTensor(c->bias, {c->out_channels});
      // After the bias, as the loader checksums them.
      const bool phases = !c->phase_weights_q.empty() || !c->phase_scales.empty();
      if (phases) {
        const size_t want_phases = 16 * static_cast<size_t>(c->in_channels) * c->out_channels;
        if (!int8 || c->phase_weights_q.size() != want_phases ||
            c->phase_scales.size() != 4 * static_cast<size_t>(c->out_channels)) {
          return Status::Error(where + ": phase kernels need precision int8, " +
                               std::to_string(want_phases) + " phase weights and " +
                               std::to_string(4 * c->out_channels) + " phase scales; has " +
                               std::to_string(c->phase_weights_q.size()) + " and " +
                               std::to_string(c->phase_scales.size()));
        }
      }
      const auto phase_weights =
          phases ? w.AddInt8Tensor(c->phase_weights_q, {4, 2, 2, c->in_channels, c->out_channels})
                 : 0;
      const fb::Padding pads(c->pads.top, c->pads.left, c->pads.bottom, c->pads.right);
      // Float32 layers leave the 1.3 fields out: their tables are as before 1.3.
      const fb::QuantParams input_quant(c->input_quant.scale, c->input_quant.zero_point);
      const fb::QuantParams output_quant(c->output_quant.scale, c->output_quant.zero_point);
      const auto conv = fb::CreateConv2D(
          b, c->in_channels, c->out_channels, c->kernel_h, c->kernel_w, c->stride_h, c->stride_w,
          ToSchema(c->padding_rule), &pads, ToSchema(c->activation), c->leaky_slope, weights, bias,
          ToSchema(c->precision), int8 ? b.CreateVector(c->weight_scales) : 0,
          int8 ? &input_quant : nullptr, int8 ? &output_quant : nullptr, phase_weights,
          phases ? b.CreateVector(c->phase_scales) : 0, c->dilation_h, c->dilation_w, c->groups);
      layers.push_back(fb::CreateLayer(b, b.CreateString(c->name),
                                       v2 ? fb::LayerOp::Conv2DV2 : fb::LayerOp::Conv2D,
                                       conv.Union(), names));
      channels = c->out_channels;
    } else if (const auto* u = std::get_if<UpsampleSpec>(&ls)) {
      const auto up = fb::CreateUpsample(b, u->factor_h, u->factor_w);
      layers.push_back(
          fb::CreateLayer(b, b.CreateString(u->name), fb::LayerOp::Upsample, up.Union(), names));
    } else if (const auto* cat = std::get_if<ConcatSpec>(&ls)) {
      if (options.schema_minor < 5) {
        return Status::Error(where + ": Concat needs schema 1.5; writing 1." +
                             std::to_string(options.schema_minor));
      }
      channels = 0;
      for (int part : read) channels += part;
      layers.push_back(fb::CreateLayer(b, b.CreateString(cat->name), fb::LayerOp::Concat,
                                       fb::CreateConcat(b).Union(), names));
    } else if (const auto* add = std::get_if<AddSpec>(&ls)) {
      if (options.schema_minor < 5) {
        return Status::Error(where + ": Add needs schema 1.5; writing 1." +
                             std::to_string(options.schema_minor));
      }
      layers.push_back(fb::CreateLayer(
          b, b.CreateString(add->name), fb::LayerOp::Add,
          fb::CreateAdd(b, ToSchema(add->activation), add->leaky_slope).Union(), names));
    } else if (const auto* d = std::get_if<ConvTransposeSpec>(&ls)) {
      if (options.schema_minor < 6) {
        return Status::Error(where + ": ConvTranspose2D needs schema 1.6; writing 1." +
                             std::to_string(options.schema_minor));
      }
      if (d->in_channels != channels) {
        return Status::Error(where + ": in_channels is " + std::to_string(d->in_channels) +
                             " but its input has " + std::to_string(channels));
      }
      const size_t want =
          static_cast<size_t>(d->kernel_h) * d->kernel_w * d->in_channels * d->out_channels;
      if (d->weights_hwio.size() != want ||
          d->bias.size() != static_cast<size_t>(d->out_channels)) {
        return Status::Error(where + ": holds " + std::to_string(d->weights_hwio.size()) +
                             " weights and " + std::to_string(d->bias.size()) + " biases; needs " +
                             std::to_string(want) + " and " + std::to_string(d->out_channels));
      }
      const auto weights =
          w.AddTensor(d->weights_hwio, {d->kernel_h, d->kernel_w, d->in_channels, d->out_channels});
      const auto bias = w.AddTensor(d->bias, {d->out_channels});
      const fb::Padding pads(d->pads.top, d->pads.left, d->pads.bottom, d->pads.right);
      const auto deconv = fb::CreateConvTranspose2D(
          b, d->in_channels, d->out_channels, d->kernel_h, d->kernel_w, d->stride_h, d->stride_w,
          &pads, d->output_padding_h, d->output_padding_w, ToSchema(d->activation), d->leaky_slope,
          weights, bias, d->dilation_h, d->dilation_w);
      layers.push_back(
          fb::CreateLayer(b, b.CreateString(d->name),
                          v2 ? fb::LayerOp::ConvTranspose2DV2 : fb::LayerOp::ConvTranspose2D,
                          deconv.Union(), names));
      channels = d->out_channels;
    } else if (const auto* affine = std::get_if<ChannelAffineSpec>(&ls)) {
      if (options.schema_minor < 7) {
        return Status::Error(where + ": ChannelAffine needs schema 1.7; writing 1." +
                             std::to_string(options.schema_minor));
      }
      if (affine->scale.size() != static_cast<size_t>(channels) ||
          affine->shift.size() != static_cast<size_t>(channels)) {
        return Status::Error(where + ": holds " + std::to_string(affine->scale.size()) +
                             " scales and " + std::to_string(affine->shift.size()) +
                             " shifts; its input has " + std::to_string(channels) + " channels");
      }
      const auto scale = w.AddTensor(affine->scale, {channels});
      const auto shift = w.AddTensor(affine->shift, {channels});
      const auto op = fb::CreateChannelAffine(b, scale, shift, ToSchema(affine->activation),
                                              affine->leaky_slope, affine->elu_alpha,
                                              affine->clip_min, affine->clip_max);
      layers.push_back(fb::CreateLayer(b, b.CreateString(affine->name), fb::LayerOp::ChannelAffine,
                                       op.Union(), names));
    } else if (const auto* resize = std::get_if<ResizeSpec>(&ls)) {
      if (options.schema_minor < 7) {
        return Status::Error(where + ": Resize needs schema 1.7; writing 1." +
                             std::to_string(options.schema_minor));
      }
      const ResizeParams& r = resize->params;
      if (r.coordinates == ResizeCoordinates::kTfCropAndResize && options.schema_minor < 9) {
        return Status::Error(where +
                             ": Resize coordinates tf_crop_and_resize need schema 1.9; "
                             "writing 1." +
                             std::to_string(options.schema_minor));
      }
      static_assert(static_cast<int>(ResizeMode::kCubic) ==
                    static_cast<int>(fb::ResizeMode::Cubic));
      static_assert(static_cast<int>(ResizeCoordinates::kTfCropAndResize) ==
                    static_cast<int>(fb::ResizeCoordinates::TfCropAndResize));
      static_assert(static_cast<int>(NearestRounding::kCeil) ==
                    static_cast<int>(fb::NearestRounding::Ceil));
      const auto op = fb::CreateResize(
          b, static_cast<fb::ResizeMode>(r.mode), static_cast<fb::ResizeCoordinates>(r.coordinates),
          static_cast<fb::NearestRounding>(r.nearest), r.scale_num_h, r.scale_den_h, r.scale_num_w,
          r.scale_den_w, r.cubic_coeff_a, r.exclude_outside, r.roi_start_h, r.roi_start_w,
          r.roi_end_h, r.roi_end_w, r.extrapolation_value);
      layers.push_back(
          fb::CreateLayer(b, b.CreateString(resize->name), fb::LayerOp::Resize, op.Union(), names));
    } else if (const auto* pool = std::get_if<PoolSpec>(&ls)) {
      if (options.schema_minor < 6) {
        return Status::Error(where + ": Pool2D needs schema 1.6; writing 1." +
                             std::to_string(options.schema_minor));
      }
      if (pool->kind == PoolKind::kArgMax && options.schema_minor < 10) {
        return Status::Error(where + ": Pool2D kind argmax needs schema 1.10; writing 1." +
                             std::to_string(options.schema_minor));
      }
      const fb::Padding pads(pool->pads.top, pool->pads.left, pool->pads.bottom, pool->pads.right);
      const auto op =
          fb::CreatePool2D(b,
                           pool->kind == PoolKind::kMax       ? fb::PoolKind::Max
                           : pool->kind == PoolKind::kAverage ? fb::PoolKind::Average
                                                              : fb::PoolKind::ArgMax,
                           pool->kernel_h, pool->kernel_w, pool->stride_h, pool->stride_w,
                           ToSchema(pool->padding_rule), &pads, pool->ceil_mode,
                           pool->count_include_pad, pool->dilation_h, pool->dilation_w,
                           pool->kind == PoolKind::kArgMax && pool->indices_column_major);
      layers.push_back(fb::CreateLayer(b, b.CreateString(pool->name),
                                       v2 ? fb::LayerOp::Pool2DV2 : fb::LayerOp::Pool2D, op.Union(),
                                       names));
    } else {
      const auto& cr = std::get<CropSpec>(ls);
      if (cr.rule == CropRule::kToSecondInput && (options.schema_minor < 5 || inputs.size() != 2)) {
        return Status::Error(where +
                             ": a crop to its second input's size needs schema 1.5 and two "
                             "inputs; has " +
                             std::to_string(inputs.size()) + ", writing 1." +
                             std::to_string(options.schema_minor));
      }
      const fb::Padding amounts(cr.amounts.top, cr.amounts.left, cr.amounts.bottom,
                                cr.amounts.right);
      const auto crop =
          fb::CreateCrop(b,
                         cr.rule == CropRule::kToInputSize     ? fb::CropRule::ToInputSize
                         : cr.rule == CropRule::kToSecondInput ? fb::CropRule::ToSecondInput
                                                               : fb::CropRule::Explicit,
                         &amounts, cr.excess_rows_from_top ? fb::RowSide::Top : fb::RowSide::Bottom,
                         cr.excess_cols_from_left ? fb::ColSide::Left : fb::ColSide::Right);
      layers.push_back(
          fb::CreateLayer(b, b.CreateString(cr.name), fb::LayerOp::Crop, crop.Union(), names));
    }
    channels_of[layer_name] = channels;
    channels_of[""] = channels;
  }
  if (spec.output.channels != channels) {
    return Status::Error("output.channels is " + std::to_string(spec.output.channels) +
                         " but the last layer produces " + std::to_string(channels));
  }
  if (!spec.output.channel_names.empty() &&
      static_cast<int>(spec.output.channel_names.size()) != channels) {
    return Status::Error("output.channel_names has " +
                         std::to_string(spec.output.channel_names.size()) +
                         " names for an output of " + std::to_string(channels) +
                         " channels; give one per channel or none");
  }

  const auto layers_offset = b.CreateVector(layers);
  const ProducerSpec& ps = spec.producer;
  const auto producer = fb::CreateProducer(
      b, b.CreateString(ps.exporter_version.empty() ? ExporterVersion() : ps.exporter_version),
      b.CreateString(ps.source_format), b.CreateString(ps.source_file),
      b.CreateString(ps.source_sha256));
  std::vector<fb::ImageSlot> order;
  for (ImageSlot s : spec.input.image_order) {
    if (vocabulary::IsRgbdSlot(s) && options.schema_minor < 11) {
      return Status::Error("input: RGB-D frames (image slot " +
                           std::string(vocabulary::ImageSlotName(s)) +
                           ") need schema 1.11; writing 1." + std::to_string(options.schema_minor));
    }
    order.push_back(ToSchema(s));
  }
  const auto input = fb::CreateInputDesc(
      b, b.CreateString(spec.input.name), spec.input.channels, b.CreateVector(order),
      spec.input.color_order == ColorOrder::kBGR ? fb::ColorOrder::BGR : fb::ColorOrder::RGB,
      spec.input.scale, b.CreateVector(spec.input.mean.data(), 3),
      b.CreateVector(spec.input.std.data(), 3), spec.input.traced_height, spec.input.traced_width,
      spec.input.depth_mean, spec.input.depth_std, spec.input.depth_invalid);
  std::vector<flatbuffers::Offset<flatbuffers::String>> names;
  for (const auto& n : spec.output.channel_names) names.push_back(b.CreateString(n));
  // Before 1.2 the field held a fixed text, which 1.0 files keep.
  const std::string units = options.schema_minor < 2 ? "training-camera scene units (baseline = 1)"
                            : spec.output.units.empty() ? "unknown"
                                                        : spec.output.units;
  const auto output =
      fb::CreateOutputDesc(b, b.CreateString(spec.output.name), spec.output.channels,
                           b.CreateVector(names), b.CreateString(units));
  const auto camera = fb::CreateCamera(b, spec.camera.focal_px, spec.camera.baseline,
                                       spec.camera.cx, spec.camera.cy);
  const fb::Version version(static_cast<uint16_t>(kSchemaVersionMajor),
                            static_cast<uint16_t>(options.schema_minor));
  // 1.1: file_crc32c is written with a non-default placeholder (so that the field is stored) and
  // patched once the buffer is finished.
  const bool file_checksum = options.schema_minor >= 1;
  const fb::TrainingState training =
      options.schema_minor < 2                     ? fb::TrainingState::Unknown
      : spec.training == TrainingState::kTrained   ? fb::TrainingState::Trained
      : spec.training == TrainingState::kUntrained ? fb::TrainingState::Untrained
                                                   : fb::TrainingState::Unknown;
  if (spec.calibration && options.schema_minor < 3) {
    return Status::Error("a calibration record needs schema 1.3; writing 1." +
                         std::to_string(options.schema_minor));
  }
  const auto calibration = spec.calibration ? AddCalibration(b, *spec.calibration) : 0;
  const auto model = fb::CreateModel(b, &version, b.CreateString(spec.name), producer, input,
                                     output, camera, layers_offset, w.crc(),
                                     file_checksum ? 0xFFFFFFFFu : 0u, training, calibration);
  fb::FinishModelBuffer(b, model);
  std::vector<uint8_t> file(b.GetBufferPointer(), b.GetBufferPointer() + b.GetSize());
  if (file_checksum) {
    if (Status s = UpdateFileChecksum(file); !s.ok()) return s;
  }
  return file;
}

}  // namespace sfrt::exporter
