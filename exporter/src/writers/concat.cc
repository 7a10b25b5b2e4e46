// Concat's writer (schema 1.5): its channels are the sum of its inputs'.
#include "writers/layer_writer.h"

namespace sfrt::exporter::writers {

Status Write(const ConcatSpec& cat, LayerWriting& out) {
  if (Status s = out.Requires(5, "Concat needs"); !s.ok()) return s;
  out.channels = 0;
  for (int part : out.read) out.channels += part;
  out.Emit(cat.name, fb::LayerOp::Concat, fb::CreateConcat(out.w.builder()).Union());
  return Status::Ok();
}

LayerSpec ConcatSpecOf(const LayerDesc& layer) { return ConcatSpec{layer.name, {}}; }

}  // namespace sfrt::exporter::writers
