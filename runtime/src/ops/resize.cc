// Resize: ONNX Resize's nearest, linear and cubic modes and its coordinate transformations
// (schema 1.7 and 1.9, float32; ResizeParams).
#include <cmath>
#include <string>
#include <tuple>
#include <utility>

#include "kernels/ref/resize_ref.h"
#include "ops/layer_op.h"
#include "sfrt/model_limits.h"

namespace sfrt::ops {
namespace {

Status TakeMode(const LayerReader& r, const schema::Resize& s, ResizeParams& p) {
  switch (s.mode()) {
    case schema::ResizeMode::Nearest:
      p.mode = ResizeMode::kNearest;
      return Status::Ok();
    case schema::ResizeMode::Linear:
      p.mode = ResizeMode::kLinear;
      return Status::Ok();
    case schema::ResizeMode::Cubic:
      p.mode = ResizeMode::kCubic;
      return Status::Ok();
  }
  return r.Fail("resize mode is unknown value " + std::to_string(static_cast<int>(s.mode())));
}

Status TakeCoordinates(const LayerReader& r, const schema::Resize& s, ResizeParams& p) {
  switch (s.coordinates()) {
    case schema::ResizeCoordinates::HalfPixel:
      p.coordinates = ResizeCoordinates::kHalfPixel;
      return Status::Ok();
    case schema::ResizeCoordinates::PytorchHalfPixel:
      p.coordinates = ResizeCoordinates::kPytorchHalfPixel;
      return Status::Ok();
    case schema::ResizeCoordinates::AlignCorners:
      p.coordinates = ResizeCoordinates::kAlignCorners;
      return Status::Ok();
    case schema::ResizeCoordinates::Asymmetric:
      p.coordinates = ResizeCoordinates::kAsymmetric;
      return Status::Ok();
    case schema::ResizeCoordinates::TfHalfPixelForNn:
      p.coordinates = ResizeCoordinates::kTfHalfPixelForNn;
      return Status::Ok();
    case schema::ResizeCoordinates::TfCropAndResize:
      p.coordinates = ResizeCoordinates::kTfCropAndResize;
      return Status::Ok();
  }
  return r.Fail("resize coordinates is unknown value " +
                std::to_string(static_cast<int>(s.coordinates())));
}

Status TakeRounding(const LayerReader& r, const schema::Resize& s, ResizeParams& p) {
  switch (s.nearest()) {
    case schema::NearestRounding::RoundPreferFloor:
      p.nearest = NearestRounding::kRoundPreferFloor;
      return Status::Ok();
    case schema::NearestRounding::RoundPreferCeil:
      p.nearest = NearestRounding::kRoundPreferCeil;
      return Status::Ok();
    case schema::NearestRounding::Floor:
      p.nearest = NearestRounding::kFloor;
      return Status::Ok();
    case schema::NearestRounding::Ceil:
      p.nearest = NearestRounding::kCeil;
      return Status::Ok();
  }
  return r.Fail("resize nearest rounding is unknown value " +
                std::to_string(static_cast<int>(s.nearest())));
}

// The scales, each a fraction within the loader's limits.
Status TakeScales(const LayerReader& r, const schema::Resize& s, ResizeParams& p) {
  using model_limits::kMaxResizeDen;
  using model_limits::kMaxResizeNum;
  using model_limits::kMaxUpsample;
  p.scale_num_h = s.scale_num_h();
  p.scale_den_h = s.scale_den_h();
  p.scale_num_w = s.scale_num_w();
  p.scale_den_w = s.scale_den_w();
  for (const auto& [num, den, axis] : {std::tuple{p.scale_num_h, p.scale_den_h, "h"},
                                       std::tuple{p.scale_num_w, p.scale_den_w, "w"}}) {
    if (num < 1 || num > kMaxResizeNum || den < 1 || den > kMaxResizeDen ||
        num > den * kMaxUpsample) {
      return r.Fail(
          std::string("scale_") + axis + " is " + std::to_string(num) + "/" + std::to_string(den) +
          "; numerator must be in 1.." + std::to_string(kMaxResizeNum) + ", denominator in 1.." +
          std::to_string(kMaxResizeDen) + ", the ratio at most " + std::to_string(kMaxUpsample));
    }
  }
  return Status::Ok();
}

// The cubic coefficient, the region of interest and the extrapolation value: finite, in range.
Status TakeValues(const LayerReader& r, const schema::Resize& s, ResizeParams& p) {
  p.cubic_coeff_a = s.cubic_coeff_a();
  if (!std::isfinite(p.cubic_coeff_a)) {
    return r.Fail("cubic_coeff_a is " + std::to_string(p.cubic_coeff_a) + "; must be finite");
  }
  p.exclude_outside = s.exclude_outside();
  p.roi_start_h = s.roi_start_h();
  p.roi_start_w = s.roi_start_w();
  p.roi_end_h = s.roi_end_h();
  p.roi_end_w = s.roi_end_w();
  p.extrapolation_value = s.extrapolation_value();
  constexpr float kRoi = model_limits::kMaxResizeRoi;
  for (const auto& [value, field] :
       {std::pair{p.roi_start_h, "roi_start_h"}, std::pair{p.roi_start_w, "roi_start_w"},
        std::pair{p.roi_end_h, "roi_end_h"}, std::pair{p.roi_end_w, "roi_end_w"}}) {
    if (!(std::fabs(value) <= kRoi)) {
      return r.Fail(std::string(field) + " is " + std::to_string(value) +
                    "; must be finite and within -" + std::to_string(static_cast<int>(kRoi)) +
                    ".." + std::to_string(static_cast<int>(kRoi)));
    }
  }
  if (!std::isfinite(p.extrapolation_value)) {
    return r.Fail("extrapolation_value is " + std::to_string(p.extrapolation_value) +
                  "; must be finite");
  }
  return Status::Ok();
}

Status Parse(LayerReader& r, LayerDesc& layer, int* out_channels) {
  const schema::Resize& s = *r.stored().op_as_Resize();
  layer.kind = LayerKind::kResize;
  ResizeParams& p = layer.resize;
  if (Status st = r.CheckArity(layer, "a Resize", 1, 1); !st.ok()) return st;
  for (auto take : {TakeMode, TakeCoordinates, TakeRounding, TakeScales, TakeValues}) {
    if (Status st = take(r, s, p); !st.ok()) return st;
  }
  *out_channels = r.ChannelsRead(layer.inputs[0]);
  return Status::Ok();
}

uint64_t Parameters(const LayerDesc&) { return 0; }

Status Geometry(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g) {
  const ResizeParams& r = layer.resize;
  const TensorShape& cur = in.first;
  const int64_t oh = ResizeOutputSize(cur.height, r.scale_num_h, r.scale_den_h);
  const int64_t ow = ResizeOutputSize(cur.width, r.scale_num_w, r.scale_den_w);
  if (oh < 1 || ow < 1 || oh > kMaxTensorSide || ow > kMaxTensorSide) {
    return Status::Error(Quote(layer, in.index) + ": resizing " + std::to_string(cur.height) + "x" +
                         std::to_string(cur.width) + " gives " + std::to_string(oh) + "x" +
                         std::to_string(ow) + ", outside 1.." + std::to_string(kMaxTensorSide) +
                         " per side");
  }
  g.output = {static_cast<int>(oh), static_cast<int>(ow), cur.channels};
  return Status::Ok();
}

void Rows(const LayerRows& rows, int begin, int end) {
  ref::ResizeRows(rows.inputs[0], rows.layer->resize, rows.out, begin, end);
}

std::string Describe(const LayerDesc& layer, LayerText detail) {
  const ResizeParams& r = layer.resize;
  if (detail == LayerText::kBrief) return std::string("resize ") + ResizeModeName(r.mode);
  auto scale = [](int64_t num, int64_t den) {
    return den == 1 ? std::to_string(num) : std::to_string(num) + "/" + std::to_string(den);
  };
  std::string op = std::string("resize ") + ResizeModeName(r.mode) + " x" +
                   scale(r.scale_num_h, r.scale_den_h) + "," + scale(r.scale_num_w, r.scale_den_w) +
                   " " + ResizeCoordinatesName(r.coordinates);
  if (r.mode == ResizeMode::kNearest) op += std::string(" ") + NearestRoundingName(r.nearest);
  if (r.mode == ResizeMode::kCubic) {
    op += " a=" + FloatText(r.cubic_coeff_a) + (r.exclude_outside ? " exclude-outside" : "");
  }
  if (r.coordinates == ResizeCoordinates::kTfCropAndResize) {
    op += " roi " + FloatText(r.roi_start_h) + "," + FloatText(r.roi_start_w) + ".." +
          FloatText(r.roi_end_h) + "," + FloatText(r.roi_end_w) + " outside " +
          FloatText(r.extrapolation_value);
  }
  return op;
}

}  // namespace

const LayerOp kResizeOp = {
    .kind = LayerKind::kResize,
    .name = "Resize",
    .float32_only = true,
    .stored = {schema::LayerOp::Resize, schema::LayerOp::NONE},
    .parse = Parse,
    .geometry = Geometry,
    .parameters = Parameters,
    .rows = Rows,
    .rows_kernel = "ref::ResizeRows",
    .describe = Describe,
    .padding = NoPadding,
};

}  // namespace sfrt::ops
