// Crop: removes rows and columns at the edges, by explicit amounts or down to the model input's
// size or its second input's (what a decoder does before a skip connection). In a session it is a
// view of its input, copied only when it is the model's output (Session::Plan).
#include <string>

#include "kernels/ref/resample_ref.h"
#include "ops/layer_op.h"

namespace sfrt::ops {
namespace {

Status TakeRule(const LayerReader& r, schema::CropRule stored, CropRule* rule) {
  switch (stored) {
    case schema::CropRule::Explicit:
      *rule = CropRule::kExplicit;
      return Status::Ok();
    case schema::CropRule::ToInputSize:
      *rule = CropRule::kToInputSize;
      return Status::Ok();
    case schema::CropRule::ToSecondInput:
      *rule = CropRule::kToSecondInput;
      return Status::Ok();
  }
  return r.Fail("crop rule is unknown value " + std::to_string(static_cast<int>(stored)));
}

Status Parse(LayerReader& r, LayerDesc& layer, int* out_channels) {
  const schema::Crop* c = r.stored().op_as_Crop();
  layer.kind = LayerKind::kCrop;
  CropParams& p = layer.crop;
  *out_channels = r.ChannelsRead(layer.inputs[0]);
  if (Status s = TakeRule(r, c->rule(), &p.rule); !s.ok()) return s;
  if (const schema::Padding* a = c->amounts()) {
    p.amounts = {a->top(), a->left(), a->bottom(), a->right()};
  }
  if (p.amounts.top < 0 || p.amounts.left < 0 || p.amounts.bottom < 0 || p.amounts.right < 0) {
    return r.Fail("crop amounts must not be negative");
  }
  const Status arity = p.rule == CropRule::kToSecondInput
                           ? r.CheckArity(layer, "a Crop to its second input's size", 2, 2)
                           : r.CheckArity(layer, "a Crop", 1, 1);
  if (!arity.ok()) return arity;
  p.excess_rows_from_top = c->excess_rows_from() == schema::RowSide::Top;
  p.excess_cols_from_left = c->excess_cols_from() == schema::ColSide::Left;
  return Status::Ok();
}

uint64_t Parameters(const LayerDesc&) { return 0; }

// The amounts a crop to a size removes: the excess rows from the top or the bottom, the excess
// columns from the left or the right.
Status CropToSize(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g) {
  const CropParams& c = layer.crop;
  const TensorShape& cur = in.first;
  const bool to_input = c.rule == CropRule::kToInputSize;
  const TensorShape target =
      to_input ? TensorShape{in.height, in.width, 0} : in.Of(layer.inputs[1]);
  const int excess_rows = cur.height - target.height;
  const int excess_cols = cur.width - target.width;
  if (excess_rows < 0 || excess_cols < 0) {
    return Status::Error(Quote(layer, in.index) + ": crops to " +
                         (to_input ? "the input size " : "its second input's size ") +
                         std::to_string(target.height) + "x" + std::to_string(target.width) +
                         " but receives only " + std::to_string(cur.height) + "x" +
                         std::to_string(cur.width));
  }
  (c.excess_rows_from_top ? g.crop.top : g.crop.bottom) = excess_rows;
  (c.excess_cols_from_left ? g.crop.left : g.crop.right) = excess_cols;
  return Status::Ok();
}

Status Geometry(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g) {
  const TensorShape& cur = in.first;
  if (layer.crop.rule == CropRule::kExplicit) {
    g.crop = layer.crop.amounts;
  } else if (Status s = CropToSize(layer, in, g); !s.ok()) {
    return s;
  }
  // In 64 bits: explicit amounts are any non-negative int in a (crafted) file.
  const int64_t rows = int64_t{cur.height} - g.crop.top - g.crop.bottom;
  const int64_t cols = int64_t{cur.width} - g.crop.left - g.crop.right;
  if (rows <= 0 || cols <= 0) {
    return Status::Error(Quote(layer, in.index) + ": removes everything of a " +
                         std::to_string(cur.height) + "x" + std::to_string(cur.width) + " input");
  }
  g.output = {static_cast<int>(rows), static_cast<int>(cols), cur.channels};
  return Status::Ok();
}

void Rows(const LayerRows& rows, int begin, int end) {
  const Padding& crop = rows.geometry->crop;
  ConstTensorView in = rows.inputs[0];
  in.data = in.pixel(crop.top + begin, crop.left);
  in.height = end - begin;
  in.width = rows.out.width;
  TensorView out = rows.out;
  out.data = out.pixel(begin, 0);
  out.height = end - begin;
  ref::Copy(in, out);
}

std::string Describe(const LayerDesc& layer, LayerText detail) {
  const CropParams& c = layer.crop;
  if (detail == LayerText::kBrief) return "crop";
  if (c.rule == CropRule::kExplicit) return "crop explicit";
  return std::string(c.rule == CropRule::kToSecondInput ? "crop to 2nd input" : "crop to input") +
         " (rows from " + (c.excess_rows_from_top ? "top" : "bottom") + ", cols from " +
         (c.excess_cols_from_left ? "left" : "right") + ")";
}

std::string PaddingText(const LayerDesc&, const LayerGeometry& g) {
  return "crop " + PadsText(g.crop);
}

}  // namespace

const LayerOp kCropOp = {
    .kind = LayerKind::kCrop,
    .name = "Crop",
    .float32_only = false,
    .stored = {schema::LayerOp::Crop, schema::LayerOp::NONE},
    .parse = Parse,
    .geometry = Geometry,
    .parameters = Parameters,
    .rows = Rows,
    .rows_kernel = "ref::Copy",
    .describe = Describe,
    .padding = PaddingText,
};

}  // namespace sfrt::ops
