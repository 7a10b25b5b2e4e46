#include "ops/layer_reader.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <tuple>

#include "sfrt/crc32c.h"
#include "sfrt/model_limits.h"

namespace sfrt::ops {
namespace {

constexpr size_t kTensorAlignment = 64;

// IEEE 754 binary16 -> binary32, exact for every input.
float HalfToFloat(uint16_t h) {
  const uint32_t sign = static_cast<uint32_t>(h & 0x8000u) << 16;
  const uint32_t exponent = (h >> 10) & 0x1Fu;
  uint32_t mantissa = h & 0x3FFu;
  uint32_t bits;
  if (exponent == 0x1F) {  // inf or NaN
    bits = sign | 0x7F800000u | (mantissa << 13);
  } else if (exponent != 0) {  // normal
    bits = sign | ((exponent + 112) << 23) | (mantissa << 13);
  } else if (mantissa == 0) {  // zero
    bits = sign;
  } else {  // subnormal: renormalise
    int e = -1;
    do {
      ++e;
      mantissa <<= 1;
    } while ((mantissa & 0x400u) == 0);
    bits = sign | static_cast<uint32_t>(112 - e) << 23 | ((mantissa & 0x3FFu) << 13);
  }
  return std::bit_cast<float>(bits);
}

// "1,2,3".
std::string ShapeText(std::initializer_list<int> shape) {
  std::string text;
  for (int d : shape) text += (text.empty() ? "" : ",") + std::to_string(d);
  return text;
}

}  // namespace

Status LayerReader::Fail(const std::string& what) const {
  return Status::Error(label_ + ": " + where_ + ": " + what);
}

Status LayerReader::CheckArity(const LayerDesc& layer, const char* op, int least, int most) const {
  const int n = static_cast<int>(layer.inputs.size());
  if (n >= least && n <= most) return Status::Ok();
  const std::string wanted =
      least == most ? std::to_string(least) : std::to_string(least) + " or more";
  return Fail(std::string(op) + " reads " + wanted + " tensor" + (most == 1 ? "" : "s") +
              "; inputs names " + std::to_string(n));
}

Status LayerReader::CheckChannels(int in_channels, int input_has, int out_channels) const {
  if (in_channels != input_has) {
    return Fail("in_channels is " + std::to_string(in_channels) + " but its input has " +
                std::to_string(input_has) + " channels");
  }
  if (out_channels <= 0 || out_channels > model_limits::kMaxChannels) {
    return Fail("out_channels is " + std::to_string(out_channels) + "; must be in 1.." +
                std::to_string(model_limits::kMaxChannels));
  }
  return Status::Ok();
}

Status LayerReader::CheckWindow(const char* what, int kh, int kw, int sh, int sw) const {
  using model_limits::kMaxKernel;
  using model_limits::kMaxStride;
  if (kh < 1 || kh > kMaxKernel || kw < 1 || kw > kMaxKernel) {
    return Fail(std::string(what) + " is " + std::to_string(kh) + "x" + std::to_string(kw) +
                "; each side must be in 1.." + std::to_string(kMaxKernel));
  }
  if (sh < 1 || sh > kMaxStride || sw < 1 || sw > kMaxStride) {
    return Fail("stride is " + std::to_string(sh) + "x" + std::to_string(sw) +
                "; each must be in 1.." + std::to_string(kMaxStride));
  }
  return Status::Ok();
}

Status LayerReader::CheckDilation(int dh, int dw, bool v2, const char* op) const {
  using model_limits::kMaxDilation;
  if (dh < 1 || dh > kMaxDilation || dw < 1 || dw > kMaxDilation) {
    return Fail("dilation is " + std::to_string(dh) + "x" + std::to_string(dw) +
                "; each must be in 1.." + std::to_string(kMaxDilation));
  }
  if (!v2 && (dh != 1 || dw != 1)) {
    return Fail("dilation is " + std::to_string(dh) + "x" + std::to_string(dw) +
                " in a layer stored as op " + op + "; a dilated one is stored as " + op +
                "V2 (a miswritten file)");
  }
  return Status::Ok();
}

Status LayerReader::CheckPadsBelowKernel(const Padding& pads, int kh, int kw) const {
  for (const auto& [amount, side, kernel] :
       {std::tuple{pads.top, "top", kh}, std::tuple{pads.bottom, "bottom", kh},
        std::tuple{pads.left, "left", kw}, std::tuple{pads.right, "right", kw}}) {
    if (amount < 0 || amount >= kernel) {
      return Fail(std::string("pads.") + side + " is " + std::to_string(amount) +
                  "; must be in 0.." + std::to_string(kernel - 1));
    }
  }
  return Status::Ok();
}

Status LayerReader::TakeActivation(schema::Activation stored, float slope, Activation* activation,
                                   float* leaky_slope, bool all_kinds) const {
  switch (stored) {
    case schema::Activation::None:
      *activation = Activation::kNone;
      break;
    case schema::Activation::Relu:
      *activation = Activation::kRelu;
      break;
    case schema::Activation::LeakyRelu:
      *activation = Activation::kLeakyRelu;
      break;
    case schema::Activation::Elu:
      *activation = Activation::kElu;
      break;
    case schema::Activation::Sigmoid:
      *activation = Activation::kSigmoid;
      break;
    case schema::Activation::Tanh:
      *activation = Activation::kTanh;
      break;
    case schema::Activation::Clip:
      *activation = Activation::kClip;
      break;
    default:
      return Fail("activation is unknown value " + std::to_string(static_cast<int>(stored)));
  }
  if (!all_kinds && *activation != Activation::kNone && *activation != Activation::kRelu &&
      *activation != Activation::kLeakyRelu) {
    return Fail(std::string("activation is ") + ActivationName(*activation) +
                ", which only a ChannelAffine layer takes (others: none, relu, leaky-relu)");
  }
  *leaky_slope = slope;
  if (!std::isfinite(slope)) return Fail("leaky_slope is not finite");
  return Status::Ok();
}

Status LayerReader::TakePaddingRule(schema::PaddingRule stored, PaddingRule* rule) const {
  switch (stored) {
    case schema::PaddingRule::Explicit:
      *rule = PaddingRule::kExplicit;
      return Status::Ok();
    case schema::PaddingRule::SameUpper:
      *rule = PaddingRule::kSameUpper;
      return Status::Ok();
    case schema::PaddingRule::SameLower:
      *rule = PaddingRule::kSameLower;
      return Status::Ok();
  }
  return Fail("padding_rule is unknown value " + std::to_string(static_cast<int>(stored)));
}

Status LayerReader::TakeTensor(const schema::Tensor* t, const char* field,
                               std::initializer_list<int> shape, const float** dst,
                               const int8_t** int8_dst) {
  const std::string f = field;
  if (t == nullptr || t->data() == nullptr) return Fail(f + " is missing");
  size_t count = 1;
  for (int d : shape) count *= static_cast<size_t>(d);
  const std::string want_shape = ShapeText(shape);
  std::string got_shape;
  bool shape_ok = t->shape() != nullptr && t->shape()->size() == shape.size();
  if (t->shape() != nullptr) {
    unsigned k = 0;
    for (int d : *t->shape()) {
      got_shape += (got_shape.empty() ? "" : ",") + std::to_string(d);
      if (shape_ok && d != *(shape.begin() + k)) shape_ok = false;
      ++k;
    }
  }
  if (!shape_ok) return Fail(f + ".shape is (" + got_shape + "); expected (" + want_shape + ")");
  size_t elem = 0;
  switch (t->dtype()) {
    case schema::DataType::Float32:
      elem = 4;
      break;
    case schema::DataType::Float16:
      elem = 2;
      break;
    case schema::DataType::Int8:
      if (int8_dst == nullptr) {
        return Fail(f + ".dtype is int8, which only the weights of an int8 layer may be");
      }
      elem = 1;
      break;
    default:
      return Fail(f + ".dtype is unknown value " + std::to_string(static_cast<int>(t->dtype())));
  }
  const size_t bytes = t->data()->size();
  if (bytes != count * elem) {
    return Fail(f + ".data holds " + std::to_string(bytes) + " bytes; shape (" + want_shape +
                ") of " +
                (elem == 4   ? "float32"
                 : elem == 2 ? "float16"
                             : "int8") +
                " needs " + std::to_string(count * elem));
  }
  const uint8_t* at = t->data()->data();
  if (static_cast<size_t>(at - weights_.file) % kTensorAlignment != 0) {
    return Fail(f + ".data starts at file offset " + std::to_string(at - weights_.file) +
                ", not a multiple of 64 as the format requires");
  }
  if (weights_.verify_checksum) weights_.crc = Crc32c(weights_.crc, at, bytes);
  if (elem == 1) {
    *int8_dst = reinterpret_cast<const int8_t*>(at);
  } else if (elem == 4) {
    *dst = reinterpret_cast<const float*>(at);
  } else {
    weights_.saw_fp16 = true;
    std::vector<float>& wide = weights_.widened->emplace_back(count);
    for (size_t k = 0; k < count; ++k) {
      uint16_t h;
      std::memcpy(&h, at + 2 * k, 2);
      wide[k] = HalfToFloat(h);
    }
    *dst = wide.data();
  }
  return Status::Ok();
}

}  // namespace sfrt::ops
