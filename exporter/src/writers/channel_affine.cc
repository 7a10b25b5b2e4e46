// ChannelAffine's writer (schema 1.7; Elu, Sigmoid, Tanh and Clip: 1.8).
#include "writers/layer_writer.h"

namespace sfrt::exporter::writers {

Status Write(const ChannelAffineSpec& affine, LayerWriting& out) {
  if (affine.activation != Activation::kNone && affine.activation != Activation::kRelu &&
      affine.activation != Activation::kLeakyRelu) {
    const std::string what = std::string("activation ") + ActivationName(affine.activation);
    if (Status s = out.Requires(8, what + " needs"); !s.ok()) return s;
  }
  if (Status s = out.Requires(7, "ChannelAffine needs"); !s.ok()) return s;
  const int channels = out.read[0];
  if (affine.scale.size() != static_cast<size_t>(channels) ||
      affine.shift.size() != static_cast<size_t>(channels)) {
    return out.Fail("holds " + std::to_string(affine.scale.size()) + " scales and " +
                    std::to_string(affine.shift.size()) + " shifts; its input has " +
                    std::to_string(channels) + " channels");
  }
  const auto scale = out.w.AddTensor(affine.scale, {channels});
  const auto shift = out.w.AddTensor(affine.shift, {channels});
  const auto op = fb::CreateChannelAffine(out.w.builder(), scale, shift,
                                          ToSchema(affine.activation), affine.leaky_slope,
                                          affine.elu_alpha, affine.clip_min, affine.clip_max);
  out.Emit(affine.name, fb::LayerOp::ChannelAffine, op.Union());
  return Status::Ok();
}

LayerSpec ChannelAffineSpecOf(const LayerDesc& layer) {
  const ChannelAffineParams& a = layer.affine;
  return ChannelAffineSpec{layer.name,
                           {},
                           std::vector<float>(a.scale, a.scale + a.channels),
                           std::vector<float>(a.shift, a.shift + a.channels),
                           a.activation,
                           a.leaky_slope,
                           a.elu_alpha,
                           a.clip_min,
                           a.clip_max};
}

}  // namespace sfrt::exporter::writers
