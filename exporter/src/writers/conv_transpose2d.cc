// ConvTranspose2D's writer (schema 1.6; dilated: ConvTranspose2DV2, 1.8).
#include "writers/layer_writer.h"

namespace sfrt::exporter::writers {

Status Write(const ConvTransposeSpec& d, LayerWriting& out) {
  const bool v2 = d.dilation_h != 1 || d.dilation_w != 1;
  if (v2) {
    if (Status s = out.Requires(8, "dilation or groups other than 1 need"); !s.ok()) return s;
  }
  if (Status s = out.Requires(6, "ConvTranspose2D needs"); !s.ok()) return s;
  if (d.in_channels != out.read[0]) {
    return out.Fail("in_channels is " + std::to_string(d.in_channels) + " but its input has " +
                    std::to_string(out.read[0]));
  }
  const size_t want = static_cast<size_t>(d.kernel_h) * d.kernel_w * d.in_channels * d.out_channels;
  if (d.weights_hwio.size() != want || d.bias.size() != static_cast<size_t>(d.out_channels)) {
    return out.Fail("holds " + std::to_string(d.weights_hwio.size()) + " weights and " +
                    std::to_string(d.bias.size()) + " biases; needs " + std::to_string(want) +
                    " and " + std::to_string(d.out_channels));
  }
  TensorWriter& w = out.w;
  const auto weights =
      w.AddTensor(d.weights_hwio, {d.kernel_h, d.kernel_w, d.in_channels, d.out_channels});
  const auto bias = w.AddTensor(d.bias, {d.out_channels});
  const fb::Padding pads(d.pads.top, d.pads.left, d.pads.bottom, d.pads.right);
  const auto deconv = fb::CreateConvTranspose2D(
      w.builder(), d.in_channels, d.out_channels, d.kernel_h, d.kernel_w, d.stride_h, d.stride_w,
      &pads, d.output_padding_h, d.output_padding_w, ToSchema(d.activation), d.leaky_slope, weights,
      bias, d.dilation_h, d.dilation_w);
  out.Emit(d.name, v2 ? fb::LayerOp::ConvTranspose2DV2 : fb::LayerOp::ConvTranspose2D,
           deconv.Union());
  out.channels = d.out_channels;
  return Status::Ok();
}

LayerSpec ConvTransposeSpecOf(const LayerDesc& layer) {
  const ConvTransposeParams& p = layer.deconv;
  ConvTransposeSpec d;
  d.name = layer.name;
  d.in_channels = p.in_channels;
  d.out_channels = p.out_channels;
  d.kernel_h = p.kernel_h;
  d.kernel_w = p.kernel_w;
  d.stride_h = p.stride_h;
  d.stride_w = p.stride_w;
  d.dilation_h = p.dilation_h;
  d.dilation_w = p.dilation_w;
  d.pads = p.pads;
  d.output_padding_h = p.output_padding_h;
  d.output_padding_w = p.output_padding_w;
  d.activation = p.activation;
  d.leaky_slope = p.leaky_slope;
  const size_t count = static_cast<size_t>(p.kernel_h) * p.kernel_w * p.in_channels *
                       static_cast<size_t>(p.out_channels);
  d.weights_hwio.assign(p.weights, p.weights + count);
  d.bias.assign(p.bias, p.bias + p.out_channels);
  return d;
}

}  // namespace sfrt::exporter::writers
