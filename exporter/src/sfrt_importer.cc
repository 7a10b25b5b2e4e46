#include "sfrt/exporter/sfrt_importer.h"

#include <memory>
#include <utility>
#include <variant>

#include "sfrt/model.h"
#include "writers/layer_writer.h"

namespace sfrt::exporter {
namespace {

// The loader has checked the names, so an unknown one cannot reach here.
ImageSlot SlotFromName(const std::string& name) {
  return vocabulary::ImageSlotFromName(name).value_or(ImageSlot::kLeft0);
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
    spec.layers.push_back(writers::SpecOfLayer(layer));
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
