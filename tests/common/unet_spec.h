// SceneEDNet with U-Net skip connections (the network issue 16 calls SceneEDNet-U) as an exporter
// ModelSpec with seeded random weights: the encoder's conv0..conv3 outputs are concatenated with
// the decoder's upsampled tensors of the same resolution (each upsampled tensor cropped to its
// skip's size first, which odd sizes need), so that runtime tests of graphs need neither Python
// nor files. With `residual`, the bottleneck's conv5 becomes conv4 + conv5 (an Add).
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "sfrt/exporter/model_spec.h"

namespace sfrt::testing {

inline exporter::ModelSpec SceneEdNetUSpec(int width_divisor, uint32_t seed = 1,
                                           bool residual = false) {
  using namespace sfrt::exporter;
  std::mt19937 rng(seed);
  ModelSpec spec;
  spec.name = "sceneednet-u-w" + std::to_string(width_divisor) + "-test";
  std::vector<std::pair<std::string, int>> made;  // (name, channels) of every layer so far
  auto channels_of = [&](const std::string& name) {
    if (name == spec.input.name) return spec.input.channels;
    for (const auto& [n, c] : made) {
      if (n == name) return c;
    }
    return 0;
  };
  auto conv = [&](const std::string& name, const std::string& input, int out, int stride,
                  bool leaky) {
    ConvSpec c;
    c.name = name;
    c.inputs = {input};
    c.in_channels = channels_of(input);
    c.out_channels = out;
    c.stride_h = c.stride_w = stride;
    c.padding_rule = PaddingRule::kSameUpper;
    c.activation = leaky ? Activation::kLeakyRelu : Activation::kNone;
    c.leaky_slope = 0.3f;
    std::normal_distribution<float> dist(0.0f, std::sqrt(2.0f / (9.0f * c.in_channels)));
    c.weights_hwio.resize(static_cast<size_t>(9) * c.in_channels * out);
    for (float& v : c.weights_hwio) v = dist(rng);
    std::uniform_real_distribution<float> bias(-0.1f, 0.1f);
    c.bias.resize(out);
    for (float& v : c.bias) v = bias(rng);
    spec.layers.push_back(c);
    made.emplace_back(name, out);
  };
  // Upsamples `low` 2x, crops it to `skip`'s size (excess from the bottom and right, as a
  // PyTorch x[..., :h, :w] does) and stacks `skip` behind it.
  auto up_skip = [&](const std::string& level, const std::string& low, const std::string& skip) {
    spec.layers.push_back(UpsampleSpec{"up" + level, 2, 2, {low}});
    made.emplace_back("up" + level, channels_of(low));
    spec.layers.push_back(
        CropSpec{"crop" + level, CropRule::kToSecondInput, {}, false, false, {"up" + level, skip}});
    made.emplace_back("crop" + level, channels_of(low));
    spec.layers.push_back(ConcatSpec{"cat" + level, {"crop" + level, skip}});
    made.emplace_back("cat" + level, channels_of(low) + channels_of(skip));
  };
  auto w = [&](int published) { return published / width_divisor; };
  conv("conv0", spec.input.name, w(64), 2, true);
  conv("conv1", "conv0", w(128), 2, true);
  conv("conv2", "conv1", w(256), 2, true);
  conv("conv3", "conv2", w(512), 2, true);
  conv("conv4", "conv3", w(1024), 1, true);
  conv("conv5", "conv4", w(1024), 1, !residual);
  std::string bottleneck = "conv5";
  if (residual) {
    spec.layers.push_back(AddSpec{"res5", {"conv4", "conv5"}, Activation::kLeakyRelu, 0.3f});
    made.emplace_back("res5", w(1024));
    bottleneck = "res5";
  }
  spec.layers.push_back(ConcatSpec{"cat4", {bottleneck, "conv3"}});
  made.emplace_back("cat4", w(1024) + w(512));
  up_skip("1", "cat4", "conv2");
  conv("conv6", "cat1", w(512), 1, true);
  up_skip("2", "conv6", "conv1");
  conv("conv7", "cat2", w(256), 1, true);
  up_skip("3", "conv7", "conv0");
  conv("conv8", "cat3", w(128), 1, true);
  spec.layers.push_back(UpsampleSpec{"up4", 2, 2, {"conv8"}});
  made.emplace_back("up4", w(128));
  spec.layers.push_back(CropSpec{"crop", CropRule::kToInputSize, {}, true, true, {"up4"}});
  made.emplace_back("crop", w(128));
  conv("conv9", "crop", w(64), 1, true);
  conv("output", "conv9", 3, 1, false);
  return spec;
}

}  // namespace sfrt::testing
