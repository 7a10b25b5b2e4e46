// Upsample: nearest-neighbour upsampling by integer factors. A nearest-2x upsampling that a
// convolution reads is fused into it by Session::Plan (the phase rule, kernels/conv_job.h).
#include <string>

#include "kernels/ref/resample_ref.h"
#include "ops/layer_op.h"
#include "sfrt/model_limits.h"

namespace sfrt::ops {
namespace {

Status Parse(LayerReader& r, LayerDesc& layer, int* out_channels) {
  const schema::Upsample* u = r.stored().op_as_Upsample();
  layer.kind = LayerKind::kUpsample;
  layer.upsample = {u->factor_h(), u->factor_w()};
  if (Status s = r.CheckArity(layer, "an Upsample", 1, 1); !s.ok()) return s;
  *out_channels = r.ChannelsRead(layer.inputs[0]);
  constexpr int kMax = model_limits::kMaxUpsample;
  if (u->factor_h() < 1 || u->factor_h() > kMax || u->factor_w() < 1 || u->factor_w() > kMax) {
    return r.Fail("upsampling factor is " + std::to_string(u->factor_h()) + "x" +
                  std::to_string(u->factor_w()) + "; each must be in 1.." + std::to_string(kMax));
  }
  return Status::Ok();
}

uint64_t Parameters(const LayerDesc&) { return 0; }

Status Geometry(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g) {
  const UpsampleParams& u = layer.upsample;
  const TensorShape& cur = in.first;
  if (cur.height > kMaxTensorSide / u.factor_h || cur.width > kMaxTensorSide / u.factor_w) {
    return Status::Error(Quote(layer, in.index) + ": upsampling " + std::to_string(cur.height) +
                         "x" + std::to_string(cur.width) + " by " + std::to_string(u.factor_h) +
                         "x" + std::to_string(u.factor_w) +
                         " exceeds the largest supported side, " + std::to_string(kMaxTensorSide));
  }
  g.output = {cur.height * u.factor_h, cur.width * u.factor_w, cur.channels};
  return Status::Ok();
}

void Rows(const LayerRows& rows, int begin, int end) {
  const UpsampleParams& u = rows.layer->upsample;
  ref::UpsampleNearestRows(rows.inputs[0], u.factor_h, u.factor_w, rows.out, begin, end);
}

std::string Describe(const LayerDesc& layer, LayerText detail) {
  const UpsampleParams& u = layer.upsample;
  const std::string factor = u.factor_h == u.factor_w
                                 ? "x" + std::to_string(u.factor_h)
                                 : std::to_string(u.factor_h) + "x" + std::to_string(u.factor_w);
  return "upsample " + factor + (detail == LayerText::kFull ? " nearest" : "");
}

}  // namespace

const LayerOp kUpsampleOp = {
    .kind = LayerKind::kUpsample,
    .name = "Upsample",
    .float32_only = false,
    .stored = {schema::LayerOp::Upsample, schema::LayerOp::NONE},
    .parse = Parse,
    .geometry = Geometry,
    .parameters = Parameters,
    .rows = Rows,
    .rows_kernel = "ref::UpsampleNearest",
    .describe = Describe,
    .padding = NoPadding,
};

}  // namespace sfrt::ops
