// Conv2D: a convolution in float32, int8 or bf16 (ConvParams). Its SIMD, Winograd, int8 and bf16
// steps, and the fusion of the nearest-2x upsampling before it, are planned by Session::Plan.
#include <cmath>
#include <string>
#include <tuple>

#include "kernels/ref/conv2d_ref.h"
#include "ops/layer_op.h"
#include "sfrt/model_limits.h"

namespace sfrt::ops {
namespace {

Status TakeQuant(const LayerReader& r, const char* field, const schema::QuantParams* q,
                 QuantParams* out) {
  if (q == nullptr) return r.Fail(std::string("precision is int8 but ") + field + " is missing");
  if (!(q->scale() > 0.0f) || !std::isfinite(q->scale())) {
    return r.Fail(std::string(field) + ".scale is " + std::to_string(q->scale()) +
                  "; must be positive and finite");
  }
  if (q->zero_point() < 0 || q->zero_point() > 255) {
    return r.Fail(std::string(field) + ".zero_point is " + std::to_string(q->zero_point()) +
                  "; must be in 0..255");
  }
  *out = {q->scale(), q->zero_point()};
  return Status::Ok();
}

// The quantisation fields of an int8 convolution (schema 1.3).
Status TakeInt8Params(const LayerReader& r, const schema::Conv2D& c, ConvParams& p) {
  const auto* scales = c.weight_scales();
  if (scales == nullptr || scales->size() != static_cast<unsigned>(p.out_channels)) {
    return r.Fail("weight_scales holds " + std::to_string(scales == nullptr ? 0 : scales->size()) +
                  " values; an int8 layer needs one per output channel (" +
                  std::to_string(p.out_channels) + ")");
  }
  for (unsigned o = 0; o < scales->size(); ++o) {
    const float v = scales->Get(o);
    if (!(v > 0.0f) || !std::isfinite(v)) {
      return r.Fail("weight_scales[" + std::to_string(o) + "] is " + std::to_string(v) +
                    "; must be positive and finite");
    }
  }
  // FlatBuffers vectors of float are little-endian and 4-byte aligned: usable in place.
  p.weight_scales = scales->data();
  if (Status s = TakeQuant(r, "input_quant", c.input_quant(), &p.input_quant); !s.ok()) return s;
  return TakeQuant(r, "output_quant", c.output_quant(), &p.output_quant);
}

// The phase kernels of an int8 convolution that reads a nearest-2x upsampling (schema 1.3), which
// only such a convolution may have (the rule ReadsNearest2xUpsampling states).
Status TakePhaseWeights(LayerReader& r, const schema::Conv2D& c, int input, ConvParams& p) {
  if (p.precision != Precision::kInt8) {
    return r.Fail("phase_weights are given but the layer's precision is not int8");
  }
  if (ReadsNearest2xUpsampling(r.earlier(), input) < 0 || p.kernel_h != 3 || p.kernel_w != 3 ||
      p.stride_h != 1 || p.stride_w != 1) {
    return r.Fail(
        "phase_weights are given, but only a 3x3 stride-1 convolution that reads a nearest-2x "
        "upsampling (with or without a crop between) has phases");
  }
  const float* unused = nullptr;
  if (Status s =
          r.TakeTensor(c.phase_weights(), "phase_weights", {4, 2, 2, p.in_channels, p.out_channels},
                       &unused, &p.phase_weights_q);
      !s.ok()) {
    return s;
  }
  if (p.phase_weights_q == nullptr) return r.Fail("phase_weights.dtype is not int8");
  const auto* scales = c.phase_scales();
  const unsigned want = 4u * static_cast<unsigned>(p.out_channels);
  if (scales == nullptr || scales->size() != want) {
    return r.Fail("phase_scales holds " + std::to_string(scales == nullptr ? 0 : scales->size()) +
                  " values; " + std::to_string(want) + " (4 phases x output channels) are needed");
  }
  for (unsigned i = 0; i < want; ++i) {
    const float v = scales->Get(i);
    if (!(v > 0.0f) || !std::isfinite(v)) {
      return r.Fail("phase_scales[" + std::to_string(i) + "] is " + std::to_string(v) +
                    "; must be positive and finite");
    }
  }
  p.phase_scales = scales->data();
  return Status::Ok();
}

// The window: sizes, strides, dilations, groups, padding rule and explicit pads.
Status TakeWindow(const LayerReader& r, const schema::Conv2D& c, bool v2, ConvParams& p) {
  if (Status s = r.CheckWindow("kernel", p.kernel_h, p.kernel_w, p.stride_h, p.stride_w); !s.ok()) {
    return s;
  }
  if (Status s = r.CheckDilation(p.dilation_h, p.dilation_w, v2, "Conv2D"); !s.ok()) return s;
  if (p.groups < 1 || p.in_channels % p.groups != 0 || p.out_channels % p.groups != 0) {
    return r.Fail("groups is " + std::to_string(p.groups) +
                  "; must be at least 1 and divide in_channels (" + std::to_string(p.in_channels) +
                  ") and out_channels (" + std::to_string(p.out_channels) + ")");
  }
  if (!v2 && p.groups != 1) {
    return r.Fail("groups is " + std::to_string(p.groups) +
                  " in a layer stored as op Conv2D; a grouped one is stored as Conv2DV2 "
                  "(a miswritten file)");
  }
  if (Status s = r.TakePaddingRule(c.padding_rule(), &p.padding_rule); !s.ok()) return s;
  if (const schema::Padding* pads = c.pads()) {
    p.pads = {pads->top(), pads->left(), pads->bottom(), pads->right()};
  }
  const int extent_h = DilatedExtent(p.kernel_h, p.dilation_h);
  const int extent_w = DilatedExtent(p.kernel_w, p.dilation_w);
  for (const auto& [amount, side, limit] :
       {std::tuple{p.pads.top, "top", extent_h}, std::tuple{p.pads.bottom, "bottom", extent_h},
        std::tuple{p.pads.left, "left", extent_w}, std::tuple{p.pads.right, "right", extent_w}}) {
    if (amount < 0 || amount > model_limits::MaxPad(limit)) {
      return r.Fail(std::string("pads.") + side + " is " + std::to_string(amount) +
                    "; must be in 0.." + std::to_string(model_limits::MaxPad(limit)));
    }
  }
  return Status::Ok();
}

// The precision and, for int8, its quantisation; a dilated or grouped convolution is fp32 only.
Status TakePrecision(LayerReader& r, const schema::Conv2D& c, ConvParams& p) {
  switch (c.precision()) {
    case schema::Precision::Float32:
      p.precision = Precision::kFloat32;
      break;
    case schema::Precision::Int8:
      p.precision = Precision::kInt8;
      break;
    case schema::Precision::BFloat16:
      p.precision = Precision::kBFloat16;
      r.NoteBf16();
      break;
    default:
      return r.Fail("precision is value " + std::to_string(static_cast<int>(c.precision())) +
                    ", which this runtime (schema " + std::to_string(kSchemaVersionMajor) + "." +
                    std::to_string(kSchemaVersionMinor) +
                    ") does not know; it runs fp32, int8 and bf16");
  }
  if (p.precision != Precision::kFloat32 && !UndilatedUngrouped(p)) {
    return r.Fail(std::string("precision is ") + PrecisionName(p.precision) +
                  ", but a dilated or grouped convolution runs in fp32 only");
  }
  if (p.precision == Precision::kInt8) {
    if (Status s = TakeInt8Params(r, c, p); !s.ok()) return s;
    r.NoteInt8();
  }
  return Status::Ok();
}

Status Parse(LayerReader& r, LayerDesc& layer, int* out_channels) {
  const bool v2 = r.stored().op_type() == schema::LayerOp::Conv2DV2;
  const schema::Conv2D* c = v2 ? r.stored().op_as_Conv2DV2() : r.stored().op_as_Conv2D();
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
  if (Status s = r.CheckArity(layer, "a Conv2D", 1, 1); !s.ok()) return s;
  if (Status s = r.CheckChannels(p.in_channels, r.ChannelsRead(layer.inputs[0]), p.out_channels);
      !s.ok()) {
    return s;
  }
  if (Status s = TakeWindow(r, *c, v2, p); !s.ok()) return s;
  if (Status s = r.TakeActivation(c->activation(), c->leaky_slope(), &p.activation, &p.leaky_slope);
      !s.ok()) {
    return s;
  }
  if (Status s = TakePrecision(r, *c, p); !s.ok()) return s;
  const bool int8 = p.precision == Precision::kInt8;
  if (Status s = r.TakeTensor(c->weights(), "weights",
                              {p.kernel_h, p.kernel_w, p.in_channels / p.groups, p.out_channels},
                              &p.weights, int8 ? &p.weights_q : nullptr);
      !s.ok()) {
    return s;
  }
  if (int8 && p.weights_q == nullptr) {
    return r.Fail("precision is int8 but weights.dtype is not int8");
  }
  if (!int8 && (c->weight_scales() != nullptr || c->input_quant() != nullptr ||
                c->output_quant() != nullptr)) {
    return r.Fail(std::string("quantisation fields are given but the layer's precision is ") +
                  PrecisionName(p.precision) + ", not int8");
  }
  if (Status s = r.TakeTensor(c->bias(), "bias", {p.out_channels}, &p.bias); !s.ok()) return s;
  if (c->phase_weights() != nullptr || c->phase_scales() != nullptr) {
    if (Status s = TakePhaseWeights(r, *c, layer.inputs[0], p); !s.ok()) return s;
  }
  *out_channels = p.out_channels;
  return Status::Ok();
}

uint64_t Parameters(const LayerDesc& layer) {
  const ConvParams& c = layer.conv;
  return static_cast<uint64_t>(c.kernel_h) * c.kernel_w *
             static_cast<uint64_t>(c.in_channels / c.groups) *
             static_cast<uint64_t>(c.out_channels) +
         static_cast<uint64_t>(c.out_channels);
}

Status Geometry(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g) {
  const ConvParams& c = layer.conv;
  const TensorShape& cur = in.first;
  const int oh =
      ConvOutputSize(cur.height, DilatedExtent(c.kernel_h, c.dilation_h), c.stride_h,
                     c.padding_rule, c.pads.top, c.pads.bottom, &g.pads.top, &g.pads.bottom);
  const int ow =
      ConvOutputSize(cur.width, DilatedExtent(c.kernel_w, c.dilation_w), c.stride_w, c.padding_rule,
                     c.pads.left, c.pads.right, &g.pads.left, &g.pads.right);
  if (oh <= 0 || ow <= 0) {
    return Status::Error(Quote(layer, in.index) + ": input " + std::to_string(cur.height) + "x" +
                         std::to_string(cur.width) + " is smaller than its " +
                         std::to_string(c.kernel_h) + "x" + std::to_string(c.kernel_w) +
                         " kernel with its padding");
  }
  g.output = {oh, ow, c.out_channels};
  g.params = Parameters(layer);
  g.macs = static_cast<uint64_t>(g.output.elements()) * c.kernel_h * c.kernel_w *
           static_cast<uint64_t>(c.in_channels / c.groups);
  return Status::Ok();
}

// The reference kernel on output rows [begin, end): the same call on a view of those rows, with
// the top padding shifted so that every row reads the input rows it did before.
void Rows(const LayerRows& rows, int begin, int end) {
  TensorView out = rows.out;
  out.data = rows.out.pixel(begin, 0);
  out.height = end - begin;
  Padding pads = rows.geometry->pads;
  pads.top -= begin * rows.layer->conv.stride_h;
  ref::Conv2d(rows.inputs[0], rows.layer->conv, pads, out);
}

std::string Describe(const LayerDesc& layer, LayerText detail) {
  const ConvParams& c = layer.conv;
  std::string op = "conv " + std::to_string(c.kernel_h) + "x" + std::to_string(c.kernel_w) + "/s" +
                   std::to_string(c.stride_h);
  if (c.stride_w != c.stride_h) op += "x" + std::to_string(c.stride_w);
  if (detail == LayerText::kBrief) {
    if (c.dilation_h != 1 || c.dilation_w != 1) op += " dil" + std::to_string(c.dilation_h);
    if (c.groups > 1) op += c.groups == c.in_channels ? " dw" : " g" + std::to_string(c.groups);
    return op;
  }
  op += DilationSuffix(c.dilation_h, c.dilation_w);
  if (c.groups > 1) {
    op += c.groups == c.in_channels ? " depthwise" : " groups " + std::to_string(c.groups);
  }
  return op + ActivationSuffix(c.activation, c.leaky_slope);
}

std::string PaddingText(const LayerDesc& layer, const LayerGeometry& g) {
  return PadsText(g.pads) + " " + PaddingRuleName(layer.conv.padding_rule);
}

}  // namespace

const LayerOp kConv2DOp = {
    .kind = LayerKind::kConv2D,
    .name = "Conv2D",
    .float32_only = false,
    .stored = {schema::LayerOp::Conv2D, schema::LayerOp::Conv2DV2},
    .parse = Parse,
    .geometry = Geometry,
    .parameters = Parameters,
    .rows = Rows,
    .rows_kernel = "ref::Conv2d",
    .describe = Describe,
    .padding = PaddingText,
};

}  // namespace sfrt::ops
