// ConvTranspose2D: a transposed convolution (schema 1.6, float32; ConvTransposeParams), the
// decoder's learned upsampling.
#include <string>

#include "kernels/ref/conv_transpose_ref.h"
#include "ops/layer_op.h"

namespace sfrt::ops {
namespace {

// Sizes, strides, dilations, pads and output padding.
Status TakeWindow(const LayerReader& r, const schema::ConvTranspose2D& c, bool v2,
                  ConvTransposeParams& p) {
  if (Status s = r.CheckWindow("kernel", p.kernel_h, p.kernel_w, p.stride_h, p.stride_w); !s.ok()) {
    return s;
  }
  if (Status s = r.CheckDilation(p.dilation_h, p.dilation_w, v2, "ConvTranspose2D"); !s.ok()) {
    return s;
  }
  if (const schema::Padding* pads = c.pads()) {
    p.pads = {pads->top(), pads->left(), pads->bottom(), pads->right()};
  }
  if (Status s = r.CheckPadsBelowKernel(p.pads, DilatedExtent(p.kernel_h, p.dilation_h),
                                        DilatedExtent(p.kernel_w, p.dilation_w));
      !s.ok()) {
    return s;
  }
  if (p.output_padding_h < 0 || p.output_padding_h >= p.stride_h || p.output_padding_w < 0 ||
      p.output_padding_w >= p.stride_w) {
    return r.Fail("output padding is " + std::to_string(p.output_padding_h) + "x" +
                  std::to_string(p.output_padding_w) +
                  "; each must be at least 0 and less than its stride (" +
                  std::to_string(p.stride_h) + "x" + std::to_string(p.stride_w) + ")");
  }
  return Status::Ok();
}

Status Parse(LayerReader& r, LayerDesc& layer, int* out_channels) {
  const bool v2 = r.stored().op_type() == schema::LayerOp::ConvTranspose2DV2;
  const schema::ConvTranspose2D* c =
      v2 ? r.stored().op_as_ConvTranspose2DV2() : r.stored().op_as_ConvTranspose2D();
  layer.kind = LayerKind::kConvTranspose2D;
  ConvTransposeParams& p = layer.deconv;
  p.in_channels = c->in_channels();
  p.out_channels = c->out_channels();
  p.kernel_h = c->kernel_h();
  p.kernel_w = c->kernel_w();
  p.stride_h = c->stride_h();
  p.stride_w = c->stride_w();
  p.output_padding_h = c->output_padding_h();
  p.output_padding_w = c->output_padding_w();
  p.dilation_h = c->dilation_h();
  p.dilation_w = c->dilation_w();
  if (Status s = r.CheckArity(layer, "a ConvTranspose2D", 1, 1); !s.ok()) return s;
  if (Status s = r.CheckChannels(p.in_channels, r.ChannelsRead(layer.inputs[0]), p.out_channels);
      !s.ok()) {
    return s;
  }
  if (Status s = TakeWindow(r, *c, v2, p); !s.ok()) return s;
  if (Status s = r.TakeActivation(c->activation(), c->leaky_slope(), &p.activation, &p.leaky_slope);
      !s.ok()) {
    return s;
  }
  if (Status s = r.TakeTensor(c->weights(), "weights",
                              {p.kernel_h, p.kernel_w, p.in_channels, p.out_channels}, &p.weights);
      !s.ok()) {
    return s;
  }
  if (Status s = r.TakeTensor(c->bias(), "bias", {p.out_channels}, &p.bias); !s.ok()) return s;
  *out_channels = p.out_channels;
  return Status::Ok();
}

uint64_t Parameters(const LayerDesc& layer) {
  const ConvTransposeParams& c = layer.deconv;
  return static_cast<uint64_t>(c.kernel_h) * c.kernel_w * static_cast<uint64_t>(c.in_channels) *
             static_cast<uint64_t>(c.out_channels) +
         static_cast<uint64_t>(c.out_channels);
}

Status Geometry(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g) {
  const ConvTransposeParams& c = layer.deconv;
  const TensorShape& cur = in.first;
  // In 64 bits: a side up to kMaxTensorSide times a stride up to kMaxStride.
  const int64_t oh = (int64_t{cur.height} - 1) * c.stride_h - c.pads.top - c.pads.bottom +
                     DilatedExtent(c.kernel_h, c.dilation_h) + c.output_padding_h;
  const int64_t ow = (int64_t{cur.width} - 1) * c.stride_w - c.pads.left - c.pads.right +
                     DilatedExtent(c.kernel_w, c.dilation_w) + c.output_padding_w;
  if (oh <= 0 || ow <= 0 || oh > kMaxTensorSide || ow > kMaxTensorSide) {
    return Status::Error(Quote(layer, in.index) + ": a " + std::to_string(cur.height) + "x" +
                         std::to_string(cur.width) + " input gives a " + std::to_string(oh) + "x" +
                         std::to_string(ow) + " output; each side must be in 1.." +
                         std::to_string(kMaxTensorSide));
  }
  g.output = {static_cast<int>(oh), static_cast<int>(ow), c.out_channels};
  g.pads = c.pads;
  g.params = Parameters(layer);
  g.macs = static_cast<uint64_t>(cur.elements()) * c.kernel_h * c.kernel_w *
           static_cast<uint64_t>(c.out_channels);
  return Status::Ok();
}

void Rows(const LayerRows& rows, int begin, int end) {
  ref::ConvTranspose2dRows(rows.inputs[0], rows.layer->deconv, rows.out, begin, end);
}

std::string Describe(const LayerDesc& layer, LayerText detail) {
  const ConvTransposeParams& c = layer.deconv;
  std::string op = "deconv " + std::to_string(c.kernel_h) + "x" + std::to_string(c.kernel_w) +
                   "/s" + std::to_string(c.stride_h);
  if (c.stride_w != c.stride_h) op += "x" + std::to_string(c.stride_w);
  if (detail == LayerText::kBrief) return op;
  if (c.output_padding_h > 0 || c.output_padding_w > 0) {
    op +=
        " outpad " + std::to_string(c.output_padding_h) + "," + std::to_string(c.output_padding_w);
  }
  return op + DilationSuffix(c.dilation_h, c.dilation_w) +
         ActivationSuffix(c.activation, c.leaky_slope);
}

// What a transposed convolution's pads do: remove rows and columns from its full output.
std::string PaddingText(const LayerDesc&, const LayerGeometry& g) {
  return "crop " + PadsText(g.pads);
}

}  // namespace

const LayerOp kConvTranspose2DOp = {
    .kind = LayerKind::kConvTranspose2D,
    .name = "ConvTranspose2D",
    .float32_only = true,
    .stored = {schema::LayerOp::ConvTranspose2D, schema::LayerOp::ConvTranspose2DV2},
    .parse = Parse,
    .geometry = Geometry,
    .parameters = Parameters,
    .rows = Rows,
    .rows_kernel = "ref::ConvTranspose2dRows",
    .describe = Describe,
    .padding = PaddingText,
};

}  // namespace sfrt::ops
