// Add: out = act(a + b), two tensors of one shape (schema 1.5), in float32.
#include <string>

#include "kernels/ref/merge_ref.h"
#include "ops/layer_op.h"

namespace sfrt::ops {
namespace {

Status Parse(LayerReader& r, LayerDesc& layer, int* out_channels) {
  const schema::Add* a = r.stored().op_as_Add();
  layer.kind = LayerKind::kAdd;
  if (Status s = r.CheckArity(layer, "an Add", 2, 2); !s.ok()) return s;
  const int ca = r.ChannelsRead(layer.inputs[0]);
  const int cb = r.ChannelsRead(layer.inputs[1]);
  if (ca != cb) {
    return r.Fail("adds tensors of " + std::to_string(ca) + " and " + std::to_string(cb) +
                  " channels; both must have the same");
  }
  if (Status s = r.TakeActivation(a->activation(), a->leaky_slope(), &layer.add.activation,
                                  &layer.add.leaky_slope);
      !s.ok()) {
    return s;
  }
  *out_channels = ca;
  return Status::Ok();
}

uint64_t Parameters(const LayerDesc&) { return 0; }

Status Geometry(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g) {
  const TensorShape other = in.Of(layer.inputs[1]);
  if (!(other == in.first)) {
    return Status::Error(Quote(layer, in.index) + ": adds a " + SizeText(in.first) +
                         " tensor to a " + SizeText(other) + " one; both must have the same shape");
  }
  g.output = in.first;
  return Status::Ok();
}

void Rows(const LayerRows& rows, int begin, int end) {
  ref::AddRows(rows.inputs[0], rows.inputs[1], rows.layer->add, rows.out, begin, end);
}

std::string Describe(const LayerDesc& layer, LayerText detail) {
  if (detail == LayerText::kBrief) return "add";
  return "add" + ActivationSuffix(layer.add.activation, layer.add.leaky_slope);
}

}  // namespace

const LayerOp kAddOp = {
    .kind = LayerKind::kAdd,
    .name = "Add",
    .float32_only = true,
    .stored = {schema::LayerOp::Add, schema::LayerOp::NONE},
    .parse = Parse,
    .geometry = Geometry,
    .parameters = Parameters,
    .rows = Rows,
    .rows_kernel = "ref::AddRows",
    .describe = Describe,
    .padding = NoPadding,
};

}  // namespace sfrt::ops
