// Upsample's writer.
#include "writers/layer_writer.h"

namespace sfrt::exporter::writers {

Status Write(const UpsampleSpec& u, LayerWriting& out) {
  const auto up = fb::CreateUpsample(out.w.builder(), u.factor_h, u.factor_w);
  out.Emit(u.name, fb::LayerOp::Upsample, up.Union());
  return Status::Ok();
}

LayerSpec UpsampleSpecOf(const LayerDesc& layer) {
  return UpsampleSpec{layer.name, layer.upsample.factor_h, layer.upsample.factor_w, {}};
}

}  // namespace sfrt::exporter::writers
