#include "sfrt/model_notes.h"

#include <cstdio>
#include <string_view>

namespace sfrt::tools {
namespace {

constexpr char kNotStated[] = "unknown";

bool UnitsStated(const ModelMetadata& meta) {
  return meta.output.units_declared && !meta.output.units.empty() &&
         meta.output.units != kNotStated;
}

}  // namespace

const char* TrainingStateName(TrainingState state) {
  switch (state) {
    case TrainingState::kTrained:
      return "trained";
    case TrainingState::kUntrained:
      return "untrained";
    case TrainingState::kUnknown:
      break;
  }
  return "unknown";
}

std::string UnitsText(const ModelMetadata& meta) {
  if (UnitsStated(meta)) return meta.output.units;
  if (!meta.output.units_declared) {
    return "unknown (schema " + std::to_string(meta.schema_major) + "." +
           std::to_string(meta.schema_minor) +
           " files do not state units; sfrt export MODEL.sfrt -o NEW.sfrt --units UNITS records "
           "them)";
  }
  return "unknown (not stated when exported; sfrt export --units records them)";
}

std::string BaselineText(const ModelMetadata& meta) {
  char number[32];
  std::snprintf(number, sizeof(number), "%g", static_cast<double>(meta.camera.baseline));
  return UnitsStated(meta) ? std::string(number) + " " + meta.output.units : std::string(number);
}

std::string UntrainedNotice(const std::string& path, TrainingState state) {
  if (state != TrainingState::kUntrained) return "";
  return "note: " + path +
         " is marked untrained (its weights were never trained): its output is "
         "not scene flow";
}

uint64_t StoredParameterBytes(const Model& model) {
  const uint64_t wide = model.metadata().weight_type == WeightType::kFloat16 ? 2 : 4;
  uint64_t bytes = 0;
  for (const LayerDesc& layer : model.layers()) {
    if (layer.kind == LayerKind::kConvTranspose2D) {  // float32 or float16, as stored
      const ConvTransposeParams& d = layer.deconv;
      bytes += (static_cast<uint64_t>(d.kernel_h) * d.kernel_w * d.in_channels * d.out_channels +
                static_cast<uint64_t>(d.out_channels)) *
               wide;
      continue;
    }
    if (layer.kind == LayerKind::kChannelAffine) {
      bytes += 2 * static_cast<uint64_t>(layer.affine.channels) * wide;
      continue;
    }
    if (layer.kind != LayerKind::kConv2D) continue;
    const ConvParams& c = layer.conv;
    const uint64_t weights = static_cast<uint64_t>(c.kernel_h) * c.kernel_w *
                             (c.in_channels / c.groups) * static_cast<uint64_t>(c.out_channels);
    const uint64_t outs = static_cast<uint64_t>(c.out_channels);
    bytes += c.precision == Precision::kInt8 ? weights + outs * 4 + outs * wide
                                             : (weights + outs) * wide;
    // The phase kernels of an int8 convolution after an upsampling: 4 x 2x2 taps, 4 scales.
    if (c.phase_weights_q != nullptr) {
      bytes += 16 * static_cast<uint64_t>(c.in_channels) * outs + 4 * outs * 4;
    }
  }
  return bytes;
}

std::string Int8LayersText(const Model& model) {
  int convs = 0;
  int int8 = 0;
  for (const LayerDesc& layer : model.layers()) {
    if (layer.kind != LayerKind::kConv2D) continue;
    ++convs;
    int8 += layer.conv.precision == Precision::kInt8;
  }
  if (int8 == 0) return "";
  return "int8 in " + std::to_string(int8) + " of " + std::to_string(convs) +
         " convolutions (int8 weights with a scale per output channel, uint8 activations)";
}

std::string ErrorText(double value) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2e", value);
  return buf;
}

std::string PrecisionFallbackNotice(const Model& model, Isa isa) {
  if (isa == Isa::kAuto) isa = BestIsa();
  if (isa == Isa::kRef) return "";
  int int8 = 0, bf16 = 0;
  for (const LayerDesc& layer : model.layers()) {
    if (layer.kind != LayerKind::kConv2D) continue;
    int8 += layer.conv.precision == Precision::kInt8;
    bf16 += layer.conv.precision == Precision::kBFloat16;
  }
  auto line = [&](int n, const char* precision, const char* needs) {
    return "note: " + std::to_string(n) + " " + precision + " convolution" +
           (n == 1 ? " runs" : "s run") + " on the scalar reference kernel: " + IsaName(isa) +
           " has no " + precision + " kernels on this CPU (" + needs +
           "); a float32 model is faster here";
  };
  std::string notice;
  if (int8 > 0 && !Int8KernelsAvailable(isa)) {
    notice = line(int8, PrecisionName(Precision::kInt8),
                  "avx512 needs AVX-512 VNNI, neon the dot-product extension");
  }
  if (bf16 > 0 && !Bf16KernelsAvailable(isa)) {
    if (!notice.empty()) notice += "\n";
    notice += line(bf16, PrecisionName(Precision::kBFloat16),
                   "avx512 needs AVX512_BF16, neon the BF16 extension");
  }
  return notice;
}

std::string ForcedIsaPrecisionProblem(const Model& model, Isa forced) {
  if (forced == Isa::kAuto || forced == Isa::kRef) return "";
  int int8 = 0, bf16 = 0;
  for (const LayerDesc& layer : model.layers()) {
    if (layer.kind != LayerKind::kConv2D) continue;
    int8 += layer.conv.precision == Precision::kInt8;
    bf16 += layer.conv.precision == Precision::kBFloat16;
  }
  auto problem = [&](int n, const char* precision, const char* needs) {
    return "the model's " + std::to_string(n) + " " + precision + " convolution" +
           (n == 1 ? " has" : "s have") + " no " + IsaName(forced) + " kernels on this CPU (" +
           needs +
           "): drop --isa (and SFRT_ISA) to let sfrt choose, or force ref to run them on "
           "the reference kernel";
  };
  if (int8 > 0 && !Int8KernelsAvailable(forced)) {
    return problem(int8, PrecisionName(Precision::kInt8),
                   "avx512 needs AVX-512 VNNI, neon the dot-product extension");
  }
  if (bf16 > 0 && !Bf16KernelsAvailable(forced)) {
    return problem(bf16, PrecisionName(Precision::kBFloat16),
                   "avx512 needs AVX512_BF16, neon the BF16 extension");
  }
  return "";
}

}  // namespace sfrt::tools
