// Pool2D's writer (schema 1.6; dilated: Pool2DV2, 1.8; argmax: 1.10).
#include "writers/layer_writer.h"

namespace sfrt::exporter::writers {

Status Write(const PoolSpec& pool, LayerWriting& out) {
  if (pool.padding_rule == PaddingRule::kSameLower) {
    if (Status s = out.Requires(7, "padding rule SameLower needs"); !s.ok()) return s;
  }
  const bool v2 = pool.dilation_h != 1 || pool.dilation_w != 1;
  if (v2) {
    if (Status s = out.Requires(8, "dilation or groups other than 1 need"); !s.ok()) return s;
  }
  if (Status s = out.Requires(6, "Pool2D needs"); !s.ok()) return s;
  if (pool.kind == PoolKind::kArgMax) {
    if (Status s = out.Requires(10, "Pool2D kind argmax needs"); !s.ok()) return s;
  }
  const fb::Padding pads(pool.pads.top, pool.pads.left, pool.pads.bottom, pool.pads.right);
  const auto op = fb::CreatePool2D(out.w.builder(),
                                   pool.kind == PoolKind::kMax       ? fb::PoolKind::Max
                                   : pool.kind == PoolKind::kAverage ? fb::PoolKind::Average
                                                                     : fb::PoolKind::ArgMax,
                                   pool.kernel_h, pool.kernel_w, pool.stride_h, pool.stride_w,
                                   ToSchema(pool.padding_rule), &pads, pool.ceil_mode,
                                   pool.count_include_pad, pool.dilation_h, pool.dilation_w,
                                   pool.kind == PoolKind::kArgMax && pool.indices_column_major);
  out.Emit(pool.name, v2 ? fb::LayerOp::Pool2DV2 : fb::LayerOp::Pool2D, op.Union());
  return Status::Ok();
}

LayerSpec PoolSpecOf(const LayerDesc& layer) {
  const PoolParams& p = layer.pool;
  PoolSpec pool;
  pool.name = layer.name;
  pool.kind = p.kind;
  pool.kernel_h = p.kernel_h;
  pool.kernel_w = p.kernel_w;
  pool.stride_h = p.stride_h;
  pool.stride_w = p.stride_w;
  pool.dilation_h = p.dilation_h;
  pool.dilation_w = p.dilation_w;
  pool.padding_rule = p.padding_rule;
  pool.pads = p.pads;
  pool.ceil_mode = p.ceil_mode;
  pool.count_include_pad = p.count_include_pad;
  pool.indices_column_major = p.indices_column_major;
  return pool;
}

}  // namespace sfrt::exporter::writers
