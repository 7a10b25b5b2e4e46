// Crop's writer: explicit amounts, or to the input's or (schema 1.5) the second input's size.
#include "writers/layer_writer.h"

namespace sfrt::exporter::writers {

Status Write(const CropSpec& cr, LayerWriting& out) {
  if (cr.rule == CropRule::kToSecondInput && (out.schema_minor < 5 || out.inputs_named != 2)) {
    return out.Fail("a crop to its second input's size needs schema 1.5 and two inputs; has " +
                    std::to_string(out.inputs_named) + ", writing 1." +
                    std::to_string(out.schema_minor));
  }
  auto& b = out.w.builder();
  const fb::Padding amounts(cr.amounts.top, cr.amounts.left, cr.amounts.bottom, cr.amounts.right);
  const auto crop =
      fb::CreateCrop(b,
                     cr.rule == CropRule::kToInputSize     ? fb::CropRule::ToInputSize
                     : cr.rule == CropRule::kToSecondInput ? fb::CropRule::ToSecondInput
                                                           : fb::CropRule::Explicit,
                     &amounts, cr.excess_rows_from_top ? fb::RowSide::Top : fb::RowSide::Bottom,
                     cr.excess_cols_from_left ? fb::ColSide::Left : fb::ColSide::Right);
  out.Emit(cr.name, fb::LayerOp::Crop, crop.Union());
  return Status::Ok();
}

LayerSpec CropSpecOf(const LayerDesc& layer) {
  CropSpec c;
  c.name = layer.name;
  c.rule = layer.crop.rule;
  c.amounts = layer.crop.amounts;
  c.excess_rows_from_top = layer.crop.excess_rows_from_top;
  c.excess_cols_from_left = layer.crop.excess_cols_from_left;
  return c;
}

}  // namespace sfrt::exporter::writers
