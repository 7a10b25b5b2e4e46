#include "writers/layer_writer.h"

#include <bit>
#include <cmath>
#include <cstring>

#include "sfrt/crc32c.h"

namespace sfrt::exporter::writers {
namespace {

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

}  // namespace

flatbuffers::Offset<fb::Tensor> TensorWriter::AddTensor(const std::vector<float>& values,
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

flatbuffers::Offset<fb::Tensor> TensorWriter::AddInt8Tensor(const std::vector<int8_t>& values,
                                                            std::initializer_list<int> shape) {
  const auto* bytes = reinterpret_cast<const uint8_t*>(values.data());
  crc_ = Crc32c(crc_, bytes, values.size());
  const auto shape_offset = builder_.CreateVector(std::vector<int>(shape));
  builder_.ForceVectorAlignment(values.size(), 1, kTensorAlignment);
  const auto data_offset = builder_.CreateVector(bytes, values.size());
  return fb::CreateTensor(builder_, fb::DataType::Int8, shape_offset, data_offset);
}

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

Status LayerWriting::Requires(int minor, const std::string& what) const {
  if (schema_minor >= minor) return Status::Ok();
  return Fail(what + " schema 1." + std::to_string(minor) + "; writing 1." +
              std::to_string(schema_minor));
}

Status LayerWriting::Fail(const std::string& what) const {
  return Status::Error(where + ": " + what);
}

void LayerWriting::Emit(const std::string& name, fb::LayerOp op, flatbuffers::Offset<void> table) {
  auto& b = w.builder();
  layer = fb::CreateLayer(b, b.CreateString(name), op, table, names);
}

LayerSpec SpecOfLayer(const LayerDesc& layer) {
  // Indexed by LayerKind, as the runtime's table of kinds (runtime/src/ops/registry.cc).
  static constexpr std::array<LayerSpec (*)(const LayerDesc&), kLayerKindCount> kSpecOf = {
      ConvSpecOf,          UpsampleSpecOf, CropSpecOf,   ConcatSpecOf,        AddSpecOf,
      ConvTransposeSpecOf, PoolSpecOf,     ResizeSpecOf, ChannelAffineSpecOf,
  };
  return kSpecOf[static_cast<size_t>(layer.kind)](layer);
}

}  // namespace sfrt::exporter::writers
