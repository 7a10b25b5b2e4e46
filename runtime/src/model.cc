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

#include "sfrt/crc32c.h"
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
using model_limits::kMaxDilation;
using model_limits::kMaxKernel;
using model_limits::kMaxLayers;
using model_limits::kMaxResizeDen;
using model_limits::kMaxResizeNum;
using model_limits::kMaxResizeRoi;
using model_limits::kMaxStride;
using model_limits::kMaxUpsample;

std::string Hex32(uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "0x%08x", v);
  return buf;
}

std::string Str(const flatbuffers::String* s) { return s != nullptr ? s->str() : std::string(); }

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

Status CheckQuant(const Checker& check, const std::string& where, const char* field,
                  const fb::QuantParams* q, QuantParams* out) {
  if (q == nullptr) return check.Fail(where + ": precision is int8 but " + field + " is missing");
  if (!(q->scale() > 0.0f) || !std::isfinite(q->scale())) {
    return check.Fail(where + ": " + field + ".scale is " + std::to_string(q->scale()) +
                      "; must be positive and finite");
  }
  if (q->zero_point() < 0 || q->zero_point() > 255) {
    return check.Fail(where + ": " + field + ".zero_point is " + std::to_string(q->zero_point()) +
                      "; must be in 0..255");
  }
  *out = {q->scale(), q->zero_point()};
  return Status::Ok();
}

// The quantisation fields of an int8 convolution (schema 1.3).
Status TakeInt8Params(const Checker& check, const std::string& where, const fb::Conv2D& c,
                      ConvParams& p) {
  const auto* scales = c.weight_scales();
  if (scales == nullptr || scales->size() != static_cast<unsigned>(p.out_channels)) {
    return check.Fail(where + ": weight_scales holds " +
                      std::to_string(scales == nullptr ? 0 : scales->size()) +
                      " values; an int8 layer needs one per output channel (" +
                      std::to_string(p.out_channels) + ")");
  }
  for (unsigned o = 0; o < scales->size(); ++o) {
    const float v = scales->Get(o);
    if (!(v > 0.0f) || !std::isfinite(v)) {
      return check.Fail(where + ": weight_scales[" + std::to_string(o) + "] is " +
                        std::to_string(v) + "; must be positive and finite");
    }
  }
  // FlatBuffers vectors of float are little-endian and 4-byte aligned: usable in place.
  p.weight_scales = scales->data();
  if (Status s = CheckQuant(check, where, "input_quant", c.input_quant(), &p.input_quant);
      !s.ok()) {
    return s;
  }
  return CheckQuant(check, where, "output_quant", c.output_quant(), &p.output_quant);
}

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

// A layer's activation as the file states it. Elu, Sigmoid, Tanh and Clip (schema 1.8) only
// when `all_kinds` (a ChannelAffine, whose parameters hold theirs).
Status TakeActivation(const Checker& check, const std::string& where, fb::Activation stored,
                      float slope, Activation* activation, float* leaky_slope,
                      bool all_kinds = false) {
  switch (stored) {
    case fb::Activation::None:
      *activation = Activation::kNone;
      break;
    case fb::Activation::Relu:
      *activation = Activation::kRelu;
      break;
    case fb::Activation::LeakyRelu:
      *activation = Activation::kLeakyRelu;
      break;
    case fb::Activation::Elu:
      *activation = Activation::kElu;
      break;
    case fb::Activation::Sigmoid:
      *activation = Activation::kSigmoid;
      break;
    case fb::Activation::Tanh:
      *activation = Activation::kTanh;
      break;
    case fb::Activation::Clip:
      *activation = Activation::kClip;
      break;
    default:
      return check.Fail(where + ": activation is unknown value " +
                        std::to_string(static_cast<int>(stored)));
  }
  if (!all_kinds && *activation != Activation::kNone && *activation != Activation::kRelu &&
      *activation != Activation::kLeakyRelu) {
    return check.Fail(where + ": activation is " + ActivationName(*activation) +
                      ", which only a ChannelAffine layer takes (others: none, relu, leaky-relu)");
  }
  *leaky_slope = slope;
  if (!std::isfinite(slope)) return check.Fail(where + ": leaky_slope is not finite");
  return Status::Ok();
}

// A convolution's (or transposed convolution's) channels: in_channels as its input has them,
// out_channels in range.
Status CheckChannels(const Checker& check, const std::string& where, int in_channels, int input_has,
                     int out_channels) {
  if (in_channels != input_has) {
    return check.Fail(where + ": in_channels is " + std::to_string(in_channels) +
                      " but its input has " + std::to_string(input_has) + " channels");
  }
  if (out_channels <= 0 || out_channels > kMaxChannels) {
    return check.Fail(where + ": out_channels is " + std::to_string(out_channels) +
                      "; must be in 1.." + std::to_string(kMaxChannels));
  }
  return Status::Ok();
}

// A kernel's or pooling window's sides and strides against the loader's limits; `what` names
// the window in the message ("kernel", "window").
Status CheckWindow(const Checker& check, const std::string& where, const char* what, int kh, int kw,
                   int sh, int sw) {
  if (kh < 1 || kh > kMaxKernel || kw < 1 || kw > kMaxKernel) {
    return check.Fail(where + ": " + what + " is " + std::to_string(kh) + "x" + std::to_string(kw) +
                      "; each side must be in 1.." + std::to_string(kMaxKernel));
  }
  if (sh < 1 || sh > kMaxStride || sw < 1 || sw > kMaxStride) {
    return check.Fail(where + ": stride is " + std::to_string(sh) + "x" + std::to_string(sw) +
                      "; each must be in 1.." + std::to_string(kMaxStride));
  }
  return Status::Ok();
}

// Dilations (schema 1.8): each in 1..kMaxDilation, and 1 unless the layer is stored under its
// op's V2 union member (`v2`), which readers before 1.8 refuse rather than ignore the field.
Status CheckDilation(const Checker& check, const std::string& where, int dh, int dw, bool v2,
                     const char* op) {
  if (dh < 1 || dh > kMaxDilation || dw < 1 || dw > kMaxDilation) {
    return check.Fail(where + ": dilation is " + std::to_string(dh) + "x" + std::to_string(dw) +
                      "; each must be in 1.." + std::to_string(kMaxDilation));
  }
  if (!v2 && (dh != 1 || dw != 1)) {
    return check.Fail(where + ": dilation is " + std::to_string(dh) + "x" + std::to_string(dw) +
                      " in a layer stored as op " + op + "; a dilated one is stored as " + op +
                      "V2 (a miswritten file)");
  }
  return Status::Ok();
}

// Pads of a transposed convolution or a pooling: each at least 0 and below its kernel side
// (the dilated extent).
Status CheckPadsBelowKernel(const Checker& check, const std::string& where, const Padding& pads,
                            int kh, int kw) {
  for (const auto& [amount, side, kernel] :
       {std::tuple{pads.top, "top", kh}, std::tuple{pads.bottom, "bottom", kh},
        std::tuple{pads.left, "left", kw}, std::tuple{pads.right, "right", kw}}) {
    if (amount < 0 || amount >= kernel) {
      return check.Fail(where + ": pads." + side + " is " + std::to_string(amount) +
                        "; must be in 0.." + std::to_string(kernel - 1));
    }
  }
  return Status::Ok();
}

// How many inputs `op` reads: [least, most].
Status CheckArity(const Checker& check, const std::string& where, const char* op,
                  const std::vector<int>& inputs, int least, int most) {
  const int n = static_cast<int>(inputs.size());
  if (n >= least && n <= most) return Status::Ok();
  const std::string wanted =
      least == most ? std::to_string(least) : std::to_string(least) + " or more";
  return check.Fail(where + ": " + op + " reads " + wanted + " tensor" + (most == 1 ? "" : "s") +
                    "; inputs names " + std::to_string(n));
}

// A Resize table's fields, each range and enum value checked (the layer named in errors).
Status ParseResize(const Checker& check, const std::string& where, const fb::Resize& r,
                   ResizeParams& p) {
  switch (r.mode()) {
    case fb::ResizeMode::Nearest:
      p.mode = ResizeMode::kNearest;
      break;
    case fb::ResizeMode::Linear:
      p.mode = ResizeMode::kLinear;
      break;
    case fb::ResizeMode::Cubic:
      p.mode = ResizeMode::kCubic;
      break;
    default:
      return check.Fail(where + ": resize mode is unknown value " +
                        std::to_string(static_cast<int>(r.mode())));
  }
  switch (r.coordinates()) {
    case fb::ResizeCoordinates::HalfPixel:
      p.coordinates = ResizeCoordinates::kHalfPixel;
      break;
    case fb::ResizeCoordinates::PytorchHalfPixel:
      p.coordinates = ResizeCoordinates::kPytorchHalfPixel;
      break;
    case fb::ResizeCoordinates::AlignCorners:
      p.coordinates = ResizeCoordinates::kAlignCorners;
      break;
    case fb::ResizeCoordinates::Asymmetric:
      p.coordinates = ResizeCoordinates::kAsymmetric;
      break;
    case fb::ResizeCoordinates::TfHalfPixelForNn:
      p.coordinates = ResizeCoordinates::kTfHalfPixelForNn;
      break;
    case fb::ResizeCoordinates::TfCropAndResize:
      p.coordinates = ResizeCoordinates::kTfCropAndResize;
      break;
    default:
      return check.Fail(where + ": resize coordinates is unknown value " +
                        std::to_string(static_cast<int>(r.coordinates())));
  }
  switch (r.nearest()) {
    case fb::NearestRounding::RoundPreferFloor:
      p.nearest = NearestRounding::kRoundPreferFloor;
      break;
    case fb::NearestRounding::RoundPreferCeil:
      p.nearest = NearestRounding::kRoundPreferCeil;
      break;
    case fb::NearestRounding::Floor:
      p.nearest = NearestRounding::kFloor;
      break;
    case fb::NearestRounding::Ceil:
      p.nearest = NearestRounding::kCeil;
      break;
    default:
      return check.Fail(where + ": resize nearest rounding is unknown value " +
                        std::to_string(static_cast<int>(r.nearest())));
  }
  p.scale_num_h = r.scale_num_h();
  p.scale_den_h = r.scale_den_h();
  p.scale_num_w = r.scale_num_w();
  p.scale_den_w = r.scale_den_w();
  for (const auto& [num, den, axis] : {std::tuple{p.scale_num_h, p.scale_den_h, "h"},
                                       std::tuple{p.scale_num_w, p.scale_den_w, "w"}}) {
    if (num < 1 || num > kMaxResizeNum || den < 1 || den > kMaxResizeDen ||
        num > den * kMaxUpsample) {
      return check.Fail(
          where + ": scale_" + axis + " is " + std::to_string(num) + "/" + std::to_string(den) +
          "; numerator must be in 1.." + std::to_string(kMaxResizeNum) + ", denominator in 1.." +
          std::to_string(kMaxResizeDen) + ", the ratio at most " + std::to_string(kMaxUpsample));
    }
  }
  p.cubic_coeff_a = r.cubic_coeff_a();
  if (!std::isfinite(p.cubic_coeff_a)) {
    return check.Fail(where + ": cubic_coeff_a is " + std::to_string(p.cubic_coeff_a) +
                      "; must be finite");
  }
  p.exclude_outside = r.exclude_outside();
  p.roi_start_h = r.roi_start_h();
  p.roi_start_w = r.roi_start_w();
  p.roi_end_h = r.roi_end_h();
  p.roi_end_w = r.roi_end_w();
  p.extrapolation_value = r.extrapolation_value();
  for (const auto& [value, field] :
       {std::pair{p.roi_start_h, "roi_start_h"}, std::pair{p.roi_start_w, "roi_start_w"},
        std::pair{p.roi_end_h, "roi_end_h"}, std::pair{p.roi_end_w, "roi_end_w"}}) {
    if (!(std::fabs(value) <= kMaxResizeRoi)) {
      return check.Fail(where + ": " + field + " is " + std::to_string(value) +
                        "; must be finite and within -" +
                        std::to_string(static_cast<int>(kMaxResizeRoi)) + ".." +
                        std::to_string(static_cast<int>(kMaxResizeRoi)));
    }
  }
  if (!std::isfinite(p.extrapolation_value)) {
    return check.Fail(where + ": extrapolation_value is " + std::to_string(p.extrapolation_value) +
                      "; must be finite");
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

// The phase kernels of an int8 convolution that reads a nearest-2x upsampling (schema 1.3).
// `earlier`: the layers before it; `input` the one it reads (kModelInput: the model input);
// take_tensor checks and CRCs a tensor as for the weights.
template <typename TakeTensor>
Status TakePhaseWeights(const Checker& check, const std::string& where, const fb::Conv2D& c,
                        const std::vector<LayerDesc>& earlier, int input, ConvParams& p,
                        TakeTensor& take_tensor) {
  if (p.precision != Precision::kInt8) {
    return check.Fail(where + ": phase_weights are given but the layer's precision is not int8");
  }
  int k = input;
  if (k >= 0 && earlier[static_cast<size_t>(k)].kind == LayerKind::kCrop) {
    k = earlier[static_cast<size_t>(k)].inputs[0];
  }
  const bool after_upsample = k >= 0 &&
                              earlier[static_cast<size_t>(k)].kind == LayerKind::kUpsample &&
                              earlier[static_cast<size_t>(k)].upsample.factor_h == 2 &&
                              earlier[static_cast<size_t>(k)].upsample.factor_w == 2;
  if (!after_upsample || p.kernel_h != 3 || p.kernel_w != 3 || p.stride_h != 1 || p.stride_w != 1) {
    return check.Fail(where +
                      ": phase_weights are given, but only a 3x3 stride-1 convolution that reads "
                      "a nearest-2x upsampling (with or without a crop between) has phases");
  }
  const float* unused = nullptr;
  if (Status s = take_tensor(c.phase_weights(), "phase_weights",
                             {4, 2, 2, p.in_channels, p.out_channels}, &unused, &p.phase_weights_q);
      !s.ok()) {
    return s;
  }
  if (p.phase_weights_q == nullptr) {
    return check.Fail(where + ": phase_weights.dtype is not int8");
  }
  const auto* scales = c.phase_scales();
  const unsigned want = 4u * static_cast<unsigned>(p.out_channels);
  if (scales == nullptr || scales->size() != want) {
    return check.Fail(where + ": phase_scales holds " +
                      std::to_string(scales == nullptr ? 0 : scales->size()) + " values; " +
                      std::to_string(want) + " (4 phases x output channels) are needed");
  }
  for (unsigned i = 0; i < want; ++i) {
    const float v = scales->Get(i);
    if (!(v > 0.0f) || !std::isfinite(v)) {
      return check.Fail(where + ": phase_scales[" + std::to_string(i) + "] is " +
                        std::to_string(v) + "; must be positive and finite");
    }
  }
  p.phase_scales = scales->data();
  return Status::Ok();
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

const char* PrecisionName(Precision precision) {
  switch (precision) {
    case Precision::kFloat32:
      return "fp32";
    case Precision::kInt8:
      return "int8";
    case Precision::kBFloat16:
      return "bf16";
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
  for (const LayerDesc& l : layers_) {
    if (l.kind == LayerKind::kConv2D) {
      const ConvParams& c = l.conv;
      n += static_cast<size_t>(c.kernel_h) * c.kernel_w * (c.in_channels / c.groups) *
               c.out_channels +
           static_cast<size_t>(c.out_channels);
    } else if (l.kind == LayerKind::kConvTranspose2D) {
      const ConvTransposeParams& c = l.deconv;
      n += static_cast<size_t>(c.kernel_h) * c.kernel_w * c.in_channels * c.out_channels +
           static_cast<size_t>(c.out_channels);
    } else if (l.kind == LayerKind::kChannelAffine) {
      n += 2 * static_cast<size_t>(l.affine.channels);
    }
  }
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
  // 1. Size and identifier.
  if (size_ < 8) {
    return check.Fail("file is " + std::to_string(size_) +
                      " bytes, too small to be a model file (truncated?)");
  }
  if (size_ > FLATBUFFERS_MAX_BUFFER_SIZE) {
    return check.Fail("file is " + std::to_string(size_) + " bytes, above the 2 GiB format limit");
  }
  if (!flatbuffers::BufferHasIdentifier(data_, fb::ModelIdentifier())) {
    std::string found;
    for (int i = 4; i < 8; ++i) {
      const char c = static_cast<char>(data_[i]);
      found += (c >= 0x20 && c < 0x7F) ? std::string(1, c) : "\\x" + Hex32(data_[i]).substr(8);
    }
    return check.Fail("not an sfrt model file: file identifier is '" + found + "', expected '" +
                      fb::ModelIdentifier() + "'");
  }

  // 2. Version, through the one-field probe, before trusting the rest of the layout.
  {
    flatbuffers::Verifier probe_verifier(data_, size_);
    if (!probe_verifier.VerifyBuffer<fb::VersionProbe>(fb::ModelIdentifier())) {
      return check.Fail("corrupt model file: its header does not verify (truncated or damaged)");
    }
    const fb::Version* v = flatbuffers::GetRoot<fb::VersionProbe>(data_)->version();
    metadata_.schema_major = v->major();
    metadata_.schema_minor = v->minor();
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
        reinterpret_cast<const flatbuffers::Table*>(flatbuffers::GetRoot<fb::VersionProbe>(data_));
    if (const uint8_t* field = root->GetAddressOf(fb::VersionProbe::VT_FILE_CRC32C)) {
      const size_t offset = static_cast<size_t>(field - data_);
      const uint32_t recorded = flatbuffers::ReadScalar<uint32_t>(field);
      metadata_.file_crc32c = recorded;
      if (options.verify_checksum) {
        static constexpr uint8_t kZeros[4] = {0, 0, 0, 0};
        uint32_t crc = Crc32c(0, data_, offset);
        crc = Crc32c(crc, kZeros, sizeof(kZeros));
        crc = Crc32c(crc, data_ + offset + 4, size_ - offset - 4);
        if (crc != recorded) {
          return check.Fail("file checksum mismatch: the file records CRC-32C " + Hex32(recorded) +
                            " but its " + std::to_string(size_) + " bytes give " + Hex32(crc) +
                            " (truncated or damaged)");
        }
      }
    } else if (v->minor() >= 1) {
      return check.Fail("model file has schema version " + std::to_string(v->major()) + "." +
                        std::to_string(v->minor()) +
                        " but no file checksum (field file_crc32c); the file is damaged");
    }
  }

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

  // 4. Metadata.
  metadata_.name = Str(m->name());
  if (const fb::Producer* p = m->producer()) {
    metadata_.exporter_version = Str(p->exporter_version());
    metadata_.source_format = Str(p->source_format());
    metadata_.source_file = Str(p->source_file());
    metadata_.source_sha256 = Str(p->source_sha256());
  }
  const fb::InputDesc* in = m->input();
  if (in == nullptr) return check.Fail("field 'input' is missing");
  InputDesc& input = metadata_.input;
  input.name = Str(in->name());
  input.channels = in->channels();
  if (input.channels <= 0 || input.channels > kMaxChannels) {
    return check.Fail("input.channels is " + std::to_string(input.channels) + "; must be in 1.." +
                      std::to_string(kMaxChannels));
  }
  if (in->image_order() != nullptr) {
    int image_channels = 0;
    int rgbd_slots = 0;
    std::array<bool, vocabulary::kImageSlots> seen{};
    for (auto slot : *in->image_order()) {
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
  if (const fb::OutputDesc* out = m->output()) {
    metadata_.output.name = Str(out->name());
    metadata_.output.channels = out->channels();
    metadata_.output.units = Str(out->units());
    metadata_.output.units_declared = metadata_.schema_minor >= 2;
    if (out->channel_names() != nullptr) {
      for (const auto* s : *out->channel_names()) metadata_.output.channel_names.push_back(Str(s));
    }
  }
  if (const fb::Camera* cam = m->camera()) {
    metadata_.camera = {cam->focal_px(), cam->baseline(), cam->cx(), cam->cy()};
  }
  metadata_.weights_crc32c = m->weights_crc32c();
  // A value from a later minor version that this runtime does not know reads as unknown.
  switch (m->training()) {
    case fb::TrainingState::Trained:
      metadata_.training = TrainingState::kTrained;
      break;
    case fb::TrainingState::Untrained:
      metadata_.training = TrainingState::kUntrained;
      break;
    default:
      metadata_.training = TrainingState::kUnknown;
      break;
  }

  // 5. Layers: the chain, parameters and weights.
  if (m->layers() == nullptr || m->layers()->size() == 0)
    return check.Fail("the model has no layers");
  if (m->layers()->size() > static_cast<unsigned>(kMaxLayers)) {
    return check.Fail("the model has " + std::to_string(m->layers()->size()) + " layers; at most " +
                      std::to_string(kMaxLayers) + " are supported");
  }
  uint32_t crc = 0;
  bool saw_fp16 = false;
  const size_t layer_count = m->layers()->size();
  layers_.reserve(layer_count);
  std::vector<int> channels_of;  // output channels per layer
  channels_of.reserve(layer_count);
  auto channels_read = [&](int tensor) {
    return tensor == kModelInput ? input.channels : channels_of[static_cast<size_t>(tensor)];
  };
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

    // Checks one weight tensor and returns fp32 data for it (in place, or widened), or, for an
    // Int8 tensor (allowed only where int8_dst is given), its bytes in place.
    auto take_tensor = [&](const fb::Tensor* t, const char* field, std::initializer_list<int> shape,
                           const float** dst, const int8_t** int8_dst = nullptr) -> Status {
      const std::string tf = where + ": " + field;
      if (t == nullptr || t->data() == nullptr) return check.Fail(tf + " is missing");
      size_t count = 1;
      std::string want_shape;
      for (int d : shape) {
        count *= static_cast<size_t>(d);
        want_shape += (want_shape.empty() ? "" : ",") + std::to_string(d);
      }
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
      if (!shape_ok) {
        return check.Fail(tf + ".shape is (" + got_shape + "); expected (" + want_shape + ")");
      }
      size_t elem = 0;
      switch (t->dtype()) {
        case fb::DataType::Float32:
          elem = 4;
          break;
        case fb::DataType::Float16:
          elem = 2;
          break;
        case fb::DataType::Int8:
          if (int8_dst == nullptr) {
            return check.Fail(tf +
                              ".dtype is int8, which only the weights of an int8 layer "
                              "may be");
          }
          elem = 1;
          break;
        default:
          return check.Fail(tf + ".dtype is unknown value " +
                            std::to_string(static_cast<int>(t->dtype())));
      }
      const size_t bytes = t->data()->size();
      if (bytes != count * elem) {
        return check.Fail(tf + ".data holds " + std::to_string(bytes) + " bytes; shape (" +
                          want_shape + ") of " +
                          (elem == 4   ? "float32"
                           : elem == 2 ? "float16"
                                       : "int8") +
                          " needs " + std::to_string(count * elem));
      }
      const uint8_t* bytes_ptr = t->data()->data();
      if (static_cast<size_t>(bytes_ptr - data_) % kTensorAlignment != 0) {
        return check.Fail(tf + ".data starts at file offset " + std::to_string(bytes_ptr - data_) +
                          ", not a multiple of 64 as the format requires");
      }
      if (options.verify_checksum) crc = Crc32c(crc, bytes_ptr, bytes);
      if (elem == 1) {
        *int8_dst = reinterpret_cast<const int8_t*>(bytes_ptr);
      } else if (elem == 4) {
        *dst = reinterpret_cast<const float*>(bytes_ptr);
      } else {
        saw_fp16 = true;
        std::vector<float>& wide = widened_.emplace_back(count);
        for (size_t k = 0; k < count; ++k) {
          uint16_t h;
          std::memcpy(&h, bytes_ptr + 2 * k, 2);
          wide[k] = HalfToFloat(h);
        }
        *dst = wide.data();
      }
      return Status::Ok();
    };

    // The verifier accepts a union whose type is set but whose table is absent.
    if (fl->op_type() != fb::LayerOp::NONE && fl->op() == nullptr) {
      return check.Fail(where + ": op type " + std::to_string(static_cast<int>(fl->op_type())) +
                        " has no op table (damaged file)");
    }
    switch (fl->op_type()) {
      case fb::LayerOp::Conv2D:
      case fb::LayerOp::Conv2DV2: {
        const bool v2 = fl->op_type() == fb::LayerOp::Conv2DV2;
        const fb::Conv2D* c = v2 ? fl->op_as_Conv2DV2() : fl->op_as_Conv2D();
        layer.kind = LayerKind::kConv2D;
        ConvParams& p = layer.conv;
        p.in_channels = c->in_channels();
        p.out_channels = c->out_channels();
        p.kernel_h = c->kernel_h();
        p.kernel_w = c->kernel_w();
        p.stride_h = c->stride_h();
        p.stride_w = c->stride_w();
        p.dilation_h = c->dilation_h();
        p.dilation_w = c->dilation_w();
        p.groups = c->groups();
        if (Status s = CheckArity(check, where, "a Conv2D", layer.inputs, 1, 1); !s.ok()) return s;
        if (Status s = CheckChannels(check, where, p.in_channels, channels_read(layer.inputs[0]),
                                     p.out_channels);
            !s.ok()) {
          return s;
        }
        if (Status s =
                CheckWindow(check, where, "kernel", p.kernel_h, p.kernel_w, p.stride_h, p.stride_w);
            !s.ok()) {
          return s;
        }
        if (Status s = CheckDilation(check, where, p.dilation_h, p.dilation_w, v2, "Conv2D");
            !s.ok()) {
          return s;
        }
        if (p.groups < 1 || p.in_channels % p.groups != 0 || p.out_channels % p.groups != 0) {
          return check.Fail(where + ": groups is " + std::to_string(p.groups) +
                            "; must be at least 1 and divide in_channels (" +
                            std::to_string(p.in_channels) + ") and out_channels (" +
                            std::to_string(p.out_channels) + ")");
        }
        if (!v2 && p.groups != 1) {
          return check.Fail(where + ": groups is " + std::to_string(p.groups) +
                            " in a layer stored as op Conv2D; a grouped one is stored as Conv2DV2 "
                            "(a miswritten file)");
        }
        switch (c->padding_rule()) {
          case fb::PaddingRule::Explicit:
            p.padding_rule = PaddingRule::kExplicit;
            break;
          case fb::PaddingRule::SameUpper:
            p.padding_rule = PaddingRule::kSameUpper;
            break;
          case fb::PaddingRule::SameLower:
            p.padding_rule = PaddingRule::kSameLower;
            break;
          default:
            return check.Fail(where + ": padding_rule is unknown value " +
                              std::to_string(static_cast<int>(c->padding_rule())));
        }
        if (const fb::Padding* pads = c->pads()) {
          p.pads = {pads->top(), pads->left(), pads->bottom(), pads->right()};
        }
        const int extent_h = DilatedExtent(p.kernel_h, p.dilation_h);
        const int extent_w = DilatedExtent(p.kernel_w, p.dilation_w);
        for (const auto& [amount, side, limit] : {std::tuple{p.pads.top, "top", extent_h},
                                                  std::tuple{p.pads.bottom, "bottom", extent_h},
                                                  std::tuple{p.pads.left, "left", extent_w},
                                                  std::tuple{p.pads.right, "right", extent_w}}) {
          if (amount < 0 || amount > model_limits::MaxPad(limit)) {
            return check.Fail(where + ": pads." + side + " is " + std::to_string(amount) +
                              "; must be in 0.." + std::to_string(model_limits::MaxPad(limit)));
          }
        }
        if (Status s = TakeActivation(check, where, c->activation(), c->leaky_slope(),
                                      &p.activation, &p.leaky_slope);
            !s.ok()) {
          return s;
        }
        switch (c->precision()) {
          case fb::Precision::Float32:
            p.precision = Precision::kFloat32;
            break;
          case fb::Precision::Int8:
            p.precision = Precision::kInt8;
            break;
          case fb::Precision::BFloat16:
            p.precision = Precision::kBFloat16;
            metadata_.has_bf16 = true;
            break;
          default:
            return check.Fail(
                where + ": precision is value " + std::to_string(static_cast<int>(c->precision())) +
                ", which this runtime (schema " + std::to_string(kSchemaVersionMajor) + "." +
                std::to_string(kSchemaVersionMinor) +
                ") does not know; it runs fp32, int8 and bf16");
        }
        if (p.precision != Precision::kFloat32 &&
            (p.dilation_h != 1 || p.dilation_w != 1 || p.groups != 1)) {
          return check.Fail(where + ": precision is " + PrecisionName(p.precision) +
                            ", but a dilated or grouped convolution runs in fp32 only");
        }
        if (p.precision == Precision::kInt8) {
          if (Status s = TakeInt8Params(check, where, *c, p); !s.ok()) return s;
          metadata_.has_int8 = true;
        }
        if (Status s =
                take_tensor(c->weights(), "weights",
                            {p.kernel_h, p.kernel_w, p.in_channels / p.groups, p.out_channels},
                            &p.weights, p.precision == Precision::kInt8 ? &p.weights_q : nullptr);
            !s.ok()) {
          return s;
        }
        if (p.precision == Precision::kInt8 && p.weights_q == nullptr) {
          return check.Fail(where + ": precision is int8 but weights.dtype is not int8");
        }
        if (p.precision != Precision::kInt8 &&
            (c->weight_scales() != nullptr || c->input_quant() != nullptr ||
             c->output_quant() != nullptr)) {
          return check.Fail(where +
                            ": quantisation fields are given but the layer's precision is " +
                            PrecisionName(p.precision) + ", not int8");
        }
        if (Status s = take_tensor(c->bias(), "bias", {p.out_channels}, &p.bias); !s.ok()) return s;
        if (c->phase_weights() != nullptr || c->phase_scales() != nullptr) {
          if (Status s =
                  TakePhaseWeights(check, where, *c, layers_, layer.inputs[0], p, take_tensor);
              !s.ok()) {
            return s;
          }
        }
        channels_of.push_back(p.out_channels);
        break;
      }
      case fb::LayerOp::Upsample: {
        const fb::Upsample* u = fl->op_as_Upsample();
        layer.kind = LayerKind::kUpsample;
        layer.upsample = {u->factor_h(), u->factor_w()};
        if (Status s = CheckArity(check, where, "an Upsample", layer.inputs, 1, 1); !s.ok()) {
          return s;
        }
        channels_of.push_back(channels_read(layer.inputs[0]));
        if (u->factor_h() < 1 || u->factor_h() > kMaxUpsample || u->factor_w() < 1 ||
            u->factor_w() > kMaxUpsample) {
          return check.Fail(where + ": upsampling factor is " + std::to_string(u->factor_h()) +
                            "x" + std::to_string(u->factor_w()) + "; each must be in 1.." +
                            std::to_string(kMaxUpsample));
        }
        break;
      }
      case fb::LayerOp::Crop: {
        const fb::Crop* c = fl->op_as_Crop();
        layer.kind = LayerKind::kCrop;
        CropParams& p = layer.crop;
        channels_of.push_back(channels_read(layer.inputs[0]));
        switch (c->rule()) {
          case fb::CropRule::Explicit:
            p.rule = CropRule::kExplicit;
            break;
          case fb::CropRule::ToInputSize:
            p.rule = CropRule::kToInputSize;
            break;
          case fb::CropRule::ToSecondInput:
            p.rule = CropRule::kToSecondInput;
            break;
          default:
            return check.Fail(where + ": crop rule is unknown value " +
                              std::to_string(static_cast<int>(c->rule())));
        }
        if (const fb::Padding* a = c->amounts())
          p.amounts = {a->top(), a->left(), a->bottom(), a->right()};
        if (p.amounts.top < 0 || p.amounts.left < 0 || p.amounts.bottom < 0 ||
            p.amounts.right < 0) {
          return check.Fail(where + ": crop amounts must not be negative");
        }
        if (p.rule == CropRule::kToSecondInput) {
          if (Status s =
                  CheckArity(check, where, "a Crop to its second input's size", layer.inputs, 2, 2);
              !s.ok()) {
            return s;
          }
        } else if (Status s = CheckArity(check, where, "a Crop", layer.inputs, 1, 1); !s.ok()) {
          return s;
        }
        p.excess_rows_from_top = c->excess_rows_from() == fb::RowSide::Top;
        p.excess_cols_from_left = c->excess_cols_from() == fb::ColSide::Left;
        break;
      }
      case fb::LayerOp::Concat: {
        layer.kind = LayerKind::kConcat;
        if (Status s = CheckArity(check, where, "a Concat", layer.inputs, 2, kMaxLayers); !s.ok()) {
          return s;
        }
        int64_t total = 0;
        for (int t : layer.inputs) total += channels_read(t);
        if (total > kMaxChannels) {
          return check.Fail(where + ": concatenates " + std::to_string(total) +
                            " channels; at most " + std::to_string(kMaxChannels) +
                            " are supported");
        }
        channels_of.push_back(static_cast<int>(total));
        break;
      }
      case fb::LayerOp::Add: {
        const fb::Add* a = fl->op_as_Add();
        layer.kind = LayerKind::kAdd;
        if (Status s = CheckArity(check, where, "an Add", layer.inputs, 2, 2); !s.ok()) return s;
        const int ca = channels_read(layer.inputs[0]);
        const int cb = channels_read(layer.inputs[1]);
        if (ca != cb) {
          return check.Fail(where + ": adds tensors of " + std::to_string(ca) + " and " +
                            std::to_string(cb) + " channels; both must have the same");
        }
        if (Status s = TakeActivation(check, where, a->activation(), a->leaky_slope(),
                                      &layer.add.activation, &layer.add.leaky_slope);
            !s.ok()) {
          return s;
        }
        channels_of.push_back(ca);
        break;
      }
      case fb::LayerOp::ConvTranspose2D:
      case fb::LayerOp::ConvTranspose2DV2: {
        const bool v2 = fl->op_type() == fb::LayerOp::ConvTranspose2DV2;
        const fb::ConvTranspose2D* c =
            v2 ? fl->op_as_ConvTranspose2DV2() : fl->op_as_ConvTranspose2D();
        layer.kind = LayerKind::kConvTranspose2D;
        ConvTransposeParams& p = layer.deconv;
        p.in_channels = c->in_channels();
        p.out_channels = c->out_channels();
        p.kernel_h = c->kernel_h();
        p.kernel_w = c->kernel_w();
        p.stride_h = c->stride_h();
        p.stride_w = c->stride_w();
        p.output_padding_h = c->output_padding_h();
        p.output_padding_w = c->output_padding_w();
        p.dilation_h = c->dilation_h();
        p.dilation_w = c->dilation_w();
        if (Status s = CheckArity(check, where, "a ConvTranspose2D", layer.inputs, 1, 1); !s.ok()) {
          return s;
        }
        if (Status s = CheckChannels(check, where, p.in_channels, channels_read(layer.inputs[0]),
                                     p.out_channels);
            !s.ok()) {
          return s;
        }
        if (Status s =
                CheckWindow(check, where, "kernel", p.kernel_h, p.kernel_w, p.stride_h, p.stride_w);
            !s.ok()) {
          return s;
        }
        if (Status s =
                CheckDilation(check, where, p.dilation_h, p.dilation_w, v2, "ConvTranspose2D");
            !s.ok()) {
          return s;
        }
        if (const fb::Padding* pads = c->pads()) {
          p.pads = {pads->top(), pads->left(), pads->bottom(), pads->right()};
        }
        if (Status s =
                CheckPadsBelowKernel(check, where, p.pads, DilatedExtent(p.kernel_h, p.dilation_h),
                                     DilatedExtent(p.kernel_w, p.dilation_w));
            !s.ok()) {
          return s;
        }
        if (p.output_padding_h < 0 || p.output_padding_h >= p.stride_h || p.output_padding_w < 0 ||
            p.output_padding_w >= p.stride_w) {
          return check.Fail(where + ": output padding is " + std::to_string(p.output_padding_h) +
                            "x" + std::to_string(p.output_padding_w) +
                            "; each must be at least 0 and less than its stride (" +
                            std::to_string(p.stride_h) + "x" + std::to_string(p.stride_w) + ")");
        }
        if (Status s = TakeActivation(check, where, c->activation(), c->leaky_slope(),
                                      &p.activation, &p.leaky_slope);
            !s.ok()) {
          return s;
        }
        if (Status s =
                take_tensor(c->weights(), "weights",
                            {p.kernel_h, p.kernel_w, p.in_channels, p.out_channels}, &p.weights);
            !s.ok()) {
          return s;
        }
        if (Status s = take_tensor(c->bias(), "bias", {p.out_channels}, &p.bias); !s.ok()) return s;
        channels_of.push_back(p.out_channels);
        break;
      }
      case fb::LayerOp::Pool2D:
      case fb::LayerOp::Pool2DV2: {
        const bool v2 = fl->op_type() == fb::LayerOp::Pool2DV2;
        const fb::Pool2D* c = v2 ? fl->op_as_Pool2DV2() : fl->op_as_Pool2D();
        layer.kind = LayerKind::kPool2D;
        PoolParams& p = layer.pool;
        if (Status s = CheckArity(check, where, "a Pool2D", layer.inputs, 1, 1); !s.ok()) return s;
        switch (c->kind()) {
          case fb::PoolKind::Max:
            p.kind = PoolKind::kMax;
            break;
          case fb::PoolKind::Average:
            p.kind = PoolKind::kAverage;
            break;
          case fb::PoolKind::ArgMax:
            p.kind = PoolKind::kArgMax;
            break;
          default:
            return check.Fail(where + ": pool kind is unknown value " +
                              std::to_string(static_cast<int>(c->kind())));
        }
        p.kernel_h = c->kernel_h();
        p.kernel_w = c->kernel_w();
        p.stride_h = c->stride_h();
        p.stride_w = c->stride_w();
        p.dilation_h = c->dilation_h();
        p.dilation_w = c->dilation_w();
        if (Status s =
                CheckWindow(check, where, "window", p.kernel_h, p.kernel_w, p.stride_h, p.stride_w);
            !s.ok()) {
          return s;
        }
        if (Status s = CheckDilation(check, where, p.dilation_h, p.dilation_w, v2, "Pool2D");
            !s.ok()) {
          return s;
        }
        switch (c->padding_rule()) {
          case fb::PaddingRule::Explicit:
            p.padding_rule = PaddingRule::kExplicit;
            break;
          case fb::PaddingRule::SameUpper:
            p.padding_rule = PaddingRule::kSameUpper;
            break;
          case fb::PaddingRule::SameLower:
            p.padding_rule = PaddingRule::kSameLower;
            break;
          default:
            return check.Fail(where + ": padding_rule is unknown value " +
                              std::to_string(static_cast<int>(c->padding_rule())));
        }
        if (const fb::Padding* pads = c->pads()) {
          p.pads = {pads->top(), pads->left(), pads->bottom(), pads->right()};
        }
        if (Status s =
                CheckPadsBelowKernel(check, where, p.pads, DilatedExtent(p.kernel_h, p.dilation_h),
                                     DilatedExtent(p.kernel_w, p.dilation_w));
            !s.ok()) {
          return s;
        }
        p.ceil_mode = c->ceil_mode();
        p.count_include_pad = c->count_include_pad();
        p.indices_column_major = c->indices_column_major();
        if (p.indices_column_major && p.kind != PoolKind::kArgMax) {
          return check.Fail(where + ": indices_column_major is set on a pool that is not argmax");
        }
        channels_of.push_back(channels_read(layer.inputs[0]));
        break;
      }
      case fb::LayerOp::ChannelAffine: {
        const fb::ChannelAffine* a = fl->op_as_ChannelAffine();
        layer.kind = LayerKind::kChannelAffine;
        ChannelAffineParams& p = layer.affine;
        if (Status s = CheckArity(check, where, "a ChannelAffine", layer.inputs, 1, 1); !s.ok()) {
          return s;
        }
        p.channels = channels_read(layer.inputs[0]);
        if (Status s = take_tensor(a->scale(), "scale", {p.channels}, &p.scale); !s.ok()) return s;
        if (Status s = take_tensor(a->shift(), "shift", {p.channels}, &p.shift); !s.ok()) return s;
        if (Status s = TakeActivation(check, where, a->activation(), a->leaky_slope(),
                                      &p.activation, &p.leaky_slope, true);
            !s.ok()) {
          return s;
        }
        p.elu_alpha = a->elu_alpha();
        p.clip_min = a->clip_min();
        p.clip_max = a->clip_max();
        if (!std::isfinite(p.elu_alpha)) return check.Fail(where + ": elu_alpha is not finite");
        if (p.activation == Activation::kClip && !(p.clip_min <= p.clip_max)) {
          return check.Fail(where + ": clip range is " + std::to_string(p.clip_min) + ".." +
                            std::to_string(p.clip_max) + "; clip_min must be at most clip_max");
        }
        channels_of.push_back(p.channels);
        break;
      }
      case fb::LayerOp::Resize: {
        const fb::Resize* r = fl->op_as_Resize();
        layer.kind = LayerKind::kResize;
        if (Status s = CheckArity(check, where, "a Resize", layer.inputs, 1, 1); !s.ok()) return s;
        if (Status s = ParseResize(check, where, *r, layer.resize); !s.ok()) return s;
        channels_of.push_back(channels_read(layer.inputs[0]));
        break;
      }
      default:
        return check.Fail(where + ": op type " + std::to_string(static_cast<int>(fl->op_type())) +
                          " is missing or unknown to this runtime");
    }
    auto [named, fresh] = tensor_named.emplace(layer.name, static_cast<int>(i));
    if (!fresh) named->second = kAmbiguous;
    layers_.push_back(std::move(layer));
  }
  if (Status s = CheckGraph(check, layers_, consumers_, is_chain_); !s.ok()) return s;
  float32_between_layers_ =
      !is_chain_ || std::any_of(layers_.begin(), layers_.end(),
                                [](const LayerDesc& l) { return Float32OnlyKind(l.kind); });
  const int channels = channels_of.back();
  if (metadata_.output.channels == 0) metadata_.output.channels = channels;
  if (metadata_.output.channels != channels) {
    return check.Fail("output.channels is " + std::to_string(metadata_.output.channels) +
                      " but the last layer produces " + std::to_string(channels));
  }
  metadata_.weight_type = saw_fp16 ? WeightType::kFloat16 : WeightType::kFloat32;

  // In a chain, an int8 convolution that feeds an int8 convolution (through upsamplings and
  // crops) hands it bytes quantised with its output_quant: the reader must read them with the
  // same parameters. (Between float32 tensors each int8 convolution quantises its own input.)
  for (size_t i = 0, prev = layers_.size(); i < layers_.size() && !float32_between_layers_; ++i) {
    if (layers_[i].kind != LayerKind::kConv2D) continue;
    if (prev < layers_.size()) {
      const ConvParams& a = layers_[prev].conv;
      const ConvParams& b = layers_[i].conv;
      if (a.precision == Precision::kInt8 && b.precision == Precision::kInt8 &&
          !(a.output_quant == b.input_quant)) {
        return check.Fail("layer " + std::to_string(i) + " '" + layers_[i].name +
                          "': input_quant (scale " + std::to_string(b.input_quant.scale) +
                          ", zero_point " + std::to_string(b.input_quant.zero_point) +
                          ") differs from the output_quant of layer '" + layers_[prev].name +
                          "' (scale " + std::to_string(a.output_quant.scale) + ", zero_point " +
                          std::to_string(a.output_quant.zero_point) + ") that feeds it");
      }
    }
    prev = i;
  }
  if (const fb::Calibration* cal = m->calibration()) {
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
    metadata_.calibration = std::move(c);
  }

  // 6. Checksum last, over exactly the bytes the layers use.
  if (options.verify_checksum && crc != metadata_.weights_crc32c) {
    return check.Fail("weights checksum mismatch: the file records CRC-32C " +
                      Hex32(metadata_.weights_crc32c) + " but the weights give " + Hex32(crc) +
                      " (the weights are damaged)");
  }
  return Status::Ok();
}

}  // namespace sfrt
