// Resize's writer (schema 1.7; tf_crop_and_resize: 1.9).
#include "writers/layer_writer.h"

namespace sfrt::exporter::writers {

Status Write(const ResizeSpec& resize, LayerWriting& out) {
  if (Status s = out.Requires(7, "Resize needs"); !s.ok()) return s;
  const ResizeParams& r = resize.params;
  if (r.coordinates == ResizeCoordinates::kTfCropAndResize) {
    if (Status s = out.Requires(9, "Resize coordinates tf_crop_and_resize need"); !s.ok()) return s;
  }
  static_assert(static_cast<int>(ResizeMode::kCubic) == static_cast<int>(fb::ResizeMode::Cubic));
  static_assert(static_cast<int>(ResizeCoordinates::kTfCropAndResize) ==
                static_cast<int>(fb::ResizeCoordinates::TfCropAndResize));
  static_assert(static_cast<int>(NearestRounding::kCeil) ==
                static_cast<int>(fb::NearestRounding::Ceil));
  const auto op = fb::CreateResize(out.w.builder(), static_cast<fb::ResizeMode>(r.mode),
                                   static_cast<fb::ResizeCoordinates>(r.coordinates),
                                   static_cast<fb::NearestRounding>(r.nearest), r.scale_num_h,
                                   r.scale_den_h, r.scale_num_w, r.scale_den_w, r.cubic_coeff_a,
                                   r.exclude_outside, r.roi_start_h, r.roi_start_w, r.roi_end_h,
                                   r.roi_end_w, r.extrapolation_value);
  out.Emit(resize.name, fb::LayerOp::Resize, op.Union());
  return Status::Ok();
}

LayerSpec ResizeSpecOf(const LayerDesc& layer) { return ResizeSpec{layer.name, {}, layer.resize}; }

}  // namespace sfrt::exporter::writers
