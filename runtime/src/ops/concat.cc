// Concat: the inputs' channels stacked in order (schema 1.5). Between int8 or bf16 convolutions a
// session keeps it in that precision and may place its inputs in their slices in place
// (Session::PlanReducedTensors, Session::PlaceConcatInputs).
#include <string>

#include "kernels/ref/merge_ref.h"
#include "ops/layer_op.h"
#include "sfrt/model_limits.h"

namespace sfrt::ops {
namespace {

Status Parse(LayerReader& r, LayerDesc& layer, int* out_channels) {
  layer.kind = LayerKind::kConcat;
  if (Status s = r.CheckArity(layer, "a Concat", 2, model_limits::kMaxLayers); !s.ok()) return s;
  int64_t total = 0;
  for (int t : layer.inputs) total += r.ChannelsRead(t);
  if (total > model_limits::kMaxChannels) {
    return r.Fail("concatenates " + std::to_string(total) + " channels; at most " +
                  std::to_string(model_limits::kMaxChannels) + " are supported");
  }
  *out_channels = static_cast<int>(total);
  return Status::Ok();
}

uint64_t Parameters(const LayerDesc&) { return 0; }

Status Geometry(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g) {
  const TensorShape& cur = in.first;
  g.output = cur;
  for (size_t k = 1; k < layer.inputs.size(); ++k) {
    const TensorShape other = in.Of(layer.inputs[k]);
    if (other.height != cur.height || other.width != cur.width) {
      return Status::Error(Quote(layer, in.index) + ": concatenates a " + SizeText(cur) +
                           " tensor with a " + SizeText(other) +
                           " one; all its inputs must have the same height and width");
    }
    g.output.channels += other.channels;
  }
  return Status::Ok();
}

void Rows(const LayerRows& rows, int begin, int end) {
  ref::ConcatRows(rows.inputs, rows.input_count, rows.out, begin, end);
}

std::string Describe(const LayerDesc& layer, LayerText detail) {
  return detail == LayerText::kBrief ? "concat " + std::to_string(layer.inputs.size())
                                     : "concat channels";
}

}  // namespace

const LayerOp kConcatOp = {
    .kind = LayerKind::kConcat,
    .name = "Concat",
    .float32_only = true,
    .stored = {schema::LayerOp::Concat, schema::LayerOp::NONE},
    .parse = Parse,
    .geometry = Geometry,
    .parameters = Parameters,
    .rows = Rows,
    .rows_kernel = "ref::ConcatRows",
    .describe = Describe,
    .padding = NoPadding,
};

}  // namespace sfrt::ops
