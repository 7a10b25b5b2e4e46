// Pool2D: max, average or argmax pooling (schema 1.6, float32; PoolParams).
#include <string>

#include "kernels/ref/pool_ref.h"
#include "ops/layer_op.h"

namespace sfrt::ops {
namespace {

Status TakeKind(const LayerReader& r, schema::PoolKind stored, PoolKind* kind) {
  switch (stored) {
    case schema::PoolKind::Max:
      *kind = PoolKind::kMax;
      return Status::Ok();
    case schema::PoolKind::Average:
      *kind = PoolKind::kAverage;
      return Status::Ok();
    case schema::PoolKind::ArgMax:
      *kind = PoolKind::kArgMax;
      return Status::Ok();
  }
  return r.Fail("pool kind is unknown value " + std::to_string(static_cast<int>(stored)));
}

Status Parse(LayerReader& r, LayerDesc& layer, int* out_channels) {
  const bool v2 = r.stored().op_type() == schema::LayerOp::Pool2DV2;
  const schema::Pool2D* c = v2 ? r.stored().op_as_Pool2DV2() : r.stored().op_as_Pool2D();
  layer.kind = LayerKind::kPool2D;
  PoolParams& p = layer.pool;
  if (Status s = r.CheckArity(layer, "a Pool2D", 1, 1); !s.ok()) return s;
  if (Status s = TakeKind(r, c->kind(), &p.kind); !s.ok()) return s;
  p.kernel_h = c->kernel_h();
  p.kernel_w = c->kernel_w();
  p.stride_h = c->stride_h();
  p.stride_w = c->stride_w();
  p.dilation_h = c->dilation_h();
  p.dilation_w = c->dilation_w();
  if (Status s = r.CheckWindow("window", p.kernel_h, p.kernel_w, p.stride_h, p.stride_w); !s.ok()) {
    return s;
  }
  if (Status s = r.CheckDilation(p.dilation_h, p.dilation_w, v2, "Pool2D"); !s.ok()) return s;
  if (Status s = r.TakePaddingRule(c->padding_rule(), &p.padding_rule); !s.ok()) return s;
  if (const schema::Padding* pads = c->pads()) {
    p.pads = {pads->top(), pads->left(), pads->bottom(), pads->right()};
  }
  if (Status s = r.CheckPadsBelowKernel(p.pads, DilatedExtent(p.kernel_h, p.dilation_h),
                                        DilatedExtent(p.kernel_w, p.dilation_w));
      !s.ok()) {
    return s;
  }
  p.ceil_mode = c->ceil_mode();
  p.count_include_pad = c->count_include_pad();
  p.indices_column_major = c->indices_column_major();
  if (p.indices_column_major && p.kind != PoolKind::kArgMax) {
    return r.Fail("indices_column_major is set on a pool that is not argmax");
  }
  *out_channels = r.ChannelsRead(layer.inputs[0]);
  return Status::Ok();
}

uint64_t Parameters(const LayerDesc&) { return 0; }

Status Geometry(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g) {
  const PoolParams& p = layer.pool;
  const TensorShape& cur = in.first;
  const int oh = PoolOutputSize(cur.height, DilatedExtent(p.kernel_h, p.dilation_h), p.stride_h,
                                p.padding_rule, p.pads.top, p.pads.bottom, p.ceil_mode, &g.pads.top,
                                &g.pads.bottom);
  const int ow =
      PoolOutputSize(cur.width, DilatedExtent(p.kernel_w, p.dilation_w), p.stride_w, p.padding_rule,
                     p.pads.left, p.pads.right, p.ceil_mode, &g.pads.left, &g.pads.right);
  if (oh <= 0 || ow <= 0) {
    return Status::Error(Quote(layer, in.index) + ": input " + std::to_string(cur.height) + "x" +
                         std::to_string(cur.width) + " is smaller than its " +
                         std::to_string(p.kernel_h) + "x" + std::to_string(p.kernel_w) +
                         " window with its padding");
  }
  if (p.kind == PoolKind::kArgMax && cur.elements() > (size_t{1} << 24)) {
    return Status::Error(Quote(layer, in.index) + ": an argmax pool over " + SizeText(cur) +
                         " values: float32 holds their indices exactly up to 2^24 only");
  }
  g.output = {oh, ow, cur.channels};
  return Status::Ok();
}

void Rows(const LayerRows& rows, int begin, int end) {
  ref::PoolRows(rows.inputs[0], rows.layer->pool, rows.geometry->pads, rows.out, begin, end);
}

std::string Describe(const LayerDesc& layer, LayerText detail) {
  const PoolParams& p = layer.pool;
  std::string op = std::string(p.kind == PoolKind::kMax       ? "maxpool "
                               : p.kind == PoolKind::kAverage ? "avgpool "
                                                              : "argmax-pool ") +
                   std::to_string(p.kernel_h) + "x" + std::to_string(p.kernel_w) + "/s" +
                   std::to_string(p.stride_h);
  if (detail == LayerText::kBrief) return op;
  if (p.stride_w != p.stride_h) op += "x" + std::to_string(p.stride_w);
  op += DilationSuffix(p.dilation_h, p.dilation_w);
  if (p.ceil_mode) op += " ceil";
  if (p.kind == PoolKind::kAverage && p.count_include_pad) op += " count-pads";
  if (p.kind == PoolKind::kArgMax && p.indices_column_major) op += " column-major";
  return op;
}

std::string PaddingText(const LayerDesc& layer, const LayerGeometry& g) {
  return PadsText(g.pads) + " " + PaddingRuleName(layer.pool.padding_rule);
}

}  // namespace

const LayerOp kPool2DOp = {
    .kind = LayerKind::kPool2D,
    .name = "Pool2D",
    .float32_only = true,
    .stored = {schema::LayerOp::Pool2D, schema::LayerOp::Pool2DV2},
    .parse = Parse,
    .geometry = Geometry,
    .parameters = Parameters,
    .rows = Rows,
    .rows_kernel = "ref::PoolRows",
    .describe = Describe,
    .padding = PaddingText,
};

}  // namespace sfrt::ops
