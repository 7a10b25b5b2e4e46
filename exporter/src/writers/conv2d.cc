// Conv2D's writer: float32, bf16 or int8 (with its phase kernels), under Conv2DV2 when dilated or
// grouped (schema 1.8).
#include "writers/layer_writer.h"

namespace sfrt::exporter::writers {
namespace {

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

// What the file's version must be for the fields in use, and the channels and counts.
Status Check(const ConvSpec& c, const LayerWriting& out, size_t want) {
  if (c.padding_rule == PaddingRule::kSameLower) {
    if (Status s = out.Requires(7, "padding rule SameLower needs"); !s.ok()) return s;
  }
  if (c.dilation_h != 1 || c.dilation_w != 1 || c.groups != 1) {
    if (Status s = out.Requires(8, "dilation or groups other than 1 need"); !s.ok()) return s;
  }
  if (c.in_channels != out.read[0]) {
    return out.Fail("in_channels is " + std::to_string(c.in_channels) + " but its input has " +
                    std::to_string(out.read[0]));
  }
  if (c.groups < 1 || c.in_channels % c.groups != 0 || c.out_channels % c.groups != 0) {
    return out.Fail("groups is " + std::to_string(c.groups) + "; must divide in_channels (" +
                    std::to_string(c.in_channels) + ") and out_channels (" +
                    std::to_string(c.out_channels) + ")");
  }
  const bool int8 = c.precision == Precision::kInt8;
  if (int8) {
    if (Status s = out.Requires(3, "precision int8 needs"); !s.ok()) return s;
  }
  if (c.precision == Precision::kBFloat16) {
    if (Status s = out.Requires(4, "precision bf16 needs"); !s.ok()) return s;
  }
  if (int8) {
    if (std::string problem = Int8CountProblem(c, want); !problem.empty()) return out.Fail(problem);
  } else if (c.weights_hwio.size() != want ||
             c.bias.size() != static_cast<size_t>(c.out_channels)) {
    return out.Fail("holds " + std::to_string(c.weights_hwio.size()) + " weights and " +
                    std::to_string(c.bias.size()) + " biases; needs " + std::to_string(want) +
                    " and " + std::to_string(c.out_channels));
  }
  return Status::Ok();
}

// Phase kernels: only on an int8 layer, with their counts.
Status CheckPhases(const ConvSpec& c, const LayerWriting& out) {
  const size_t want_phases = 16 * static_cast<size_t>(c.in_channels) * c.out_channels;
  if (c.precision != Precision::kInt8 || c.phase_weights_q.size() != want_phases ||
      c.phase_scales.size() != 4 * static_cast<size_t>(c.out_channels)) {
    return out.Fail("phase kernels need precision int8, " + std::to_string(want_phases) +
                    " phase weights and " + std::to_string(4 * c.out_channels) +
                    " phase scales; has " + std::to_string(c.phase_weights_q.size()) + " and " +
                    std::to_string(c.phase_scales.size()));
  }
  return Status::Ok();
}

}  // namespace

Status Write(const ConvSpec& c, LayerWriting& out) {
  const int group_in = c.groups > 0 ? c.in_channels / c.groups : 0;
  const size_t want = static_cast<size_t>(c.kernel_h) * c.kernel_w * group_in * c.out_channels;
  if (Status s = Check(c, out, want); !s.ok()) return s;
  const bool int8 = c.precision == Precision::kInt8;
  TensorWriter& w = out.w;
  auto& b = w.builder();
  const auto weights =
      int8 ? w.AddInt8Tensor(c.weights_q, {c.kernel_h, c.kernel_w, group_in, c.out_channels})
           : w.AddTensor(c.weights_hwio, {c.kernel_h, c.kernel_w, group_in, c.out_channels});
  const auto bias = w.AddTensor(c.bias, {c.out_channels});
  // After the bias, as the loader checksums them.
  const bool phases = !c.phase_weights_q.empty() || !c.phase_scales.empty();
  if (phases) {
    if (Status s = CheckPhases(c, out); !s.ok()) return s;
  }
  const auto phase_weights =
      phases ? w.AddInt8Tensor(c.phase_weights_q, {4, 2, 2, c.in_channels, c.out_channels}) : 0;
  const fb::Padding pads(c.pads.top, c.pads.left, c.pads.bottom, c.pads.right);
  // Float32 layers leave the 1.3 fields out: their tables are as before 1.3.
  const fb::QuantParams input_quant(c.input_quant.scale, c.input_quant.zero_point);
  const fb::QuantParams output_quant(c.output_quant.scale, c.output_quant.zero_point);
  const auto conv = fb::CreateConv2D(
      b, c.in_channels, c.out_channels, c.kernel_h, c.kernel_w, c.stride_h, c.stride_w,
      ToSchema(c.padding_rule), &pads, ToSchema(c.activation), c.leaky_slope, weights, bias,
      ToSchema(c.precision), int8 ? b.CreateVector(c.weight_scales) : 0,
      int8 ? &input_quant : nullptr, int8 ? &output_quant : nullptr, phase_weights,
      phases ? b.CreateVector(c.phase_scales) : 0, c.dilation_h, c.dilation_w, c.groups);
  const bool v2 = c.dilation_h != 1 || c.dilation_w != 1 || c.groups != 1;
  out.Emit(c.name, v2 ? fb::LayerOp::Conv2DV2 : fb::LayerOp::Conv2D, conv.Union());
  out.channels = c.out_channels;
  return Status::Ok();
}

LayerSpec ConvSpecOf(const LayerDesc& layer) {
  const ConvParams& p = layer.conv;
  ConvSpec c;
  c.name = layer.name;
  c.in_channels = p.in_channels;
  c.out_channels = p.out_channels;
  c.kernel_h = p.kernel_h;
  c.kernel_w = p.kernel_w;
  c.stride_h = p.stride_h;
  c.stride_w = p.stride_w;
  c.dilation_h = p.dilation_h;
  c.dilation_w = p.dilation_w;
  c.groups = p.groups;
  c.padding_rule = p.padding_rule;
  c.pads = p.pads;
  c.activation = p.activation;
  c.leaky_slope = p.leaky_slope;
  const size_t count = static_cast<size_t>(p.kernel_h) * p.kernel_w * (p.in_channels / p.groups) *
                       static_cast<size_t>(p.out_channels);
  c.bias.assign(p.bias, p.bias + p.out_channels);
  c.precision = p.precision;
  if (p.precision == Precision::kInt8) {
    c.weights_q.assign(p.weights_q, p.weights_q + count);
    c.weight_scales.assign(p.weight_scales, p.weight_scales + p.out_channels);
    c.input_quant = p.input_quant;
    c.output_quant = p.output_quant;
    if (p.phase_weights_q != nullptr) {
      c.phase_weights_q.assign(p.phase_weights_q, p.phase_weights_q + 16 * count / 9);
      c.phase_scales.assign(p.phase_scales, p.phase_scales + 4 * p.out_channels);
    }
  } else {
    c.weights_hwio.assign(p.weights, p.weights + count);
  }
  return c;
}

}  // namespace sfrt::exporter::writers
