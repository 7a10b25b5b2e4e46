// ChannelAffine: out[c] = act(in[c] * scale[c] + shift[c]) (schema 1.7, float32), the form a
// batch normalisation or a per-channel scale takes; the only kind that takes Elu, Sigmoid, Tanh
// and Clip.
#include <cmath>
#include <string>

#include "kernels/ref/affine_ref.h"
#include "ops/layer_op.h"

namespace sfrt::ops {
namespace {

Status Parse(LayerReader& r, LayerDesc& layer, int* out_channels) {
  const schema::ChannelAffine* a = r.stored().op_as_ChannelAffine();
  layer.kind = LayerKind::kChannelAffine;
  ChannelAffineParams& p = layer.affine;
  if (Status s = r.CheckArity(layer, "a ChannelAffine", 1, 1); !s.ok()) return s;
  p.channels = r.ChannelsRead(layer.inputs[0]);
  if (Status s = r.TakeTensor(a->scale(), "scale", {p.channels}, &p.scale); !s.ok()) return s;
  if (Status s = r.TakeTensor(a->shift(), "shift", {p.channels}, &p.shift); !s.ok()) return s;
  if (Status s =
          r.TakeActivation(a->activation(), a->leaky_slope(), &p.activation, &p.leaky_slope, true);
      !s.ok()) {
    return s;
  }
  p.elu_alpha = a->elu_alpha();
  p.clip_min = a->clip_min();
  p.clip_max = a->clip_max();
  if (!std::isfinite(p.elu_alpha)) return r.Fail("elu_alpha is not finite");
  if (p.activation == Activation::kClip && !(p.clip_min <= p.clip_max)) {
    return r.Fail("clip range is " + std::to_string(p.clip_min) + ".." +
                  std::to_string(p.clip_max) + "; clip_min must be at most clip_max");
  }
  *out_channels = p.channels;
  return Status::Ok();
}

uint64_t Parameters(const LayerDesc& layer) {
  return 2 * static_cast<uint64_t>(layer.affine.channels);
}

// The geometry's params leave its scales and shifts out (sfrt inspect shows "-" for it);
// LayerParameterCount and Model::parameter_count count them.
Status Geometry(const LayerDesc&, const GeometryInputs& in, LayerGeometry& g) {
  g.output = in.first;
  return Status::Ok();
}

void Rows(const LayerRows& rows, int begin, int end) {
  ref::ChannelAffineRows(rows.inputs[0], rows.layer->affine, rows.out, begin, end);
}

std::string Describe(const LayerDesc& layer, LayerText detail) {
  if (detail == LayerText::kBrief) return "scale+shift";
  const ChannelAffineParams& a = layer.affine;
  return "scale+shift per channel" + ActivationSuffix(a.activation, a.leaky_slope, &a);
}

}  // namespace

const LayerOp kChannelAffineOp = {
    .kind = LayerKind::kChannelAffine,
    .name = "ChannelAffine",
    .float32_only = true,
    .stored = {schema::LayerOp::ChannelAffine, schema::LayerOp::NONE},
    .parse = Parse,
    .geometry = Geometry,
    .parameters = Parameters,
    .rows = Rows,
    .rows_kernel = "ref::ChannelAffineRows",
    .describe = Describe,
    .padding = NoPadding,
};

}  // namespace sfrt::ops
