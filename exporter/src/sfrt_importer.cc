#include "sfrt/exporter/sfrt_importer.h"

#include <memory>
#include <utility>
#include <variant>

#include "sfrt/model.h"

namespace sfrt::exporter {
namespace {

// The loader has checked the names, so an unknown one cannot reach here.
ImageSlot SlotFromName(const std::string& name) {
  return vocabulary::ImageSlotFromName(name).value_or(ImageSlot::kLeft0);
}

LayerSpec LayerFromDesc(const LayerDesc& layer) {
  switch (layer.kind) {
    case LayerKind::kConv2D: {
      const ConvParams& p = layer.conv;
      ConvSpec c;
      c.name = layer.name;
      c.in_channels = p.in_channels;
      c.out_channels = p.out_channels;
      c.kernel_h = p.kernel_h;
      c.kernel_w = p.kernel_w;
      c.stride_h = p.stride_h;
      c.stride_w = p.stride_w;
      c.dilation_h = p.dilation_h;
      c.dilation_w = p.dilation_w;
      c.groups = p.groups;
      c.padding_rule = p.padding_rule;
      c.pads = p.pads;
      c.activation = p.activation;
      c.leaky_slope = p.leaky_slope;
      const size_t count = static_cast<size_t>(p.kernel_h) * p.kernel_w *
                           (p.in_channels / p.groups) * static_cast<size_t>(p.out_channels);
      c.bias.assign(p.bias, p.bias + p.out_channels);
      c.precision = p.precision;
      if (p.precision == Precision::kInt8) {
        c.weights_q.assign(p.weights_q, p.weights_q + count);
        c.weight_scales.assign(p.weight_scales, p.weight_scales + p.out_channels);
        c.input_quant = p.input_quant;
        c.output_quant = p.output_quant;
        if (p.phase_weights_q != nullptr) {
          c.phase_weights_q.assign(p.phase_weights_q, p.phase_weights_q + 16 * count / 9);
          c.phase_scales.assign(p.phase_scales, p.phase_scales + 4 * p.out_channels);
        }
      } else {
        c.weights_hwio.assign(p.weights, p.weights + count);
      }
      return c;
    }
    case LayerKind::kUpsample:
      return UpsampleSpec{layer.name, layer.upsample.factor_h, layer.upsample.factor_w, {}};
    case LayerKind::kConcat:
      return ConcatSpec{layer.name, {}};
    case LayerKind::kAdd:
      return AddSpec{layer.name, {}, layer.add.activation, layer.add.leaky_slope};
    case LayerKind::kConvTranspose2D: {
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
    case LayerKind::kPool2D: {
      const PoolParams& p = layer.pool;
      PoolSpec pool;
      pool.name = layer.name;
      pool.kind = p.kind;
      pool.kernel_h = p.kernel_h;
      pool.kernel_w = p.kernel_w;
      pool.stride_h = p.stride_h;
      pool.stride_w = p.stride_w;
      pool.dilation_h = p.dilation_h;
      pool.dilation_w = p.dilation_w;
      pool.padding_rule = p.padding_rule;
      pool.pads = p.pads;
      pool.ceil_mode = p.ceil_mode;
      pool.count_include_pad = p.count_include_pad;
      pool.indices_column_major = p.indices_column_major;
      return pool;
    }
    case LayerKind::kResize:
      return ResizeSpec{layer.name, {}, layer.resize};
    case LayerKind::kChannelAffine: {
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
    case LayerKind::kCrop:
      break;
  }
  CropSpec c;
  c.name = layer.name;
  c.rule = layer.crop.rule;
  c.amounts = layer.crop.amounts;
  c.excess_rows_from_top = layer.crop.excess_rows_from_top;
  c.excess_cols_from_left = layer.crop.excess_cols_from_left;
  return c;
}

}  // namespace

Result<ModelSpec> ImportSfrt(const std::string& path) {
  Result<std::shared_ptr<const Model>> loaded = Model::LoadFile(path);
  if (!loaded.ok()) return loaded.status();
  const Model& model = **loaded;
  const ModelMetadata& meta = model.metadata();

  ModelSpec spec;
  spec.name = meta.name;
  spec.producer.source_format = meta.source_format;
  spec.producer.source_file = meta.source_file;
  spec.producer.source_sha256 = meta.source_sha256;
  spec.input.name = meta.input.name;
  spec.input.channels = meta.input.channels;
  spec.input.image_order.clear();
  for (const std::string& slot : meta.input.image_order) {
    spec.input.image_order.push_back(SlotFromName(slot));
  }
  spec.input.color_order =
      vocabulary::ColorOrderFromName(meta.input.color_order).value_or(ColorOrder::kBGR);
  spec.input.scale = meta.input.scale;
  for (int c = 0; c < 3; ++c) {
    spec.input.mean[static_cast<size_t>(c)] = meta.input.mean[c];
    spec.input.std[static_cast<size_t>(c)] = meta.input.std[c];
  }
  spec.input.traced_height = meta.input.traced_height;
  spec.input.traced_width = meta.input.traced_width;
  spec.input.depth_mean = meta.input.depth_mean;
  spec.input.depth_std = meta.input.depth_std;
  spec.input.depth_invalid = meta.input.depth_invalid;
  spec.output.name = meta.output.name;
  spec.output.channels = meta.output.channels;
  spec.output.channel_names = meta.output.channel_names;
  spec.output.units = meta.output.units_declared ? meta.output.units : "";
  spec.camera = {meta.camera.focal_px, meta.camera.baseline, meta.camera.cx, meta.camera.cy};
  spec.weight_type = meta.weight_type;
  spec.training = meta.training;
  spec.calibration = meta.calibration;
  const auto layers = model.layers();
  for (const LayerDesc& layer : layers) {
    spec.layers.push_back(LayerFromDesc(layer));
    if (model.is_chain()) continue;  // the previous layer: no names needed
    std::vector<std::string> inputs;
    for (int t : layer.inputs) {
      inputs.push_back(t == kModelInput ? meta.input.name : layers[static_cast<size_t>(t)].name);
    }
    std::visit([&](auto& l) { l.inputs = std::move(inputs); }, spec.layers.back());
  }
  return spec;
}

}  // namespace sfrt::exporter
