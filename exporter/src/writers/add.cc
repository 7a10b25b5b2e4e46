// Add's writer (schema 1.5).
#include "writers/layer_writer.h"

namespace sfrt::exporter::writers {

Status Write(const AddSpec& add, LayerWriting& out) {
  if (Status s = out.Requires(5, "Add needs"); !s.ok()) return s;
  const auto op = fb::CreateAdd(out.w.builder(), ToSchema(add.activation), add.leaky_slope);
  out.Emit(add.name, fb::LayerOp::Add, op.Union());
  return Status::Ok();
}

LayerSpec AddSpecOf(const LayerDesc& layer) {
  return AddSpec{layer.name, {}, layer.add.activation, layer.add.leaky_slope};
}

}  // namespace sfrt::exporter::writers
