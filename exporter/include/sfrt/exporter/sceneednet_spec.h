// Builds SceneEDNet (Thakur and Mukherjee, ICARCV 2018) as an exporter ModelSpec with seeded
// random weights: the network's real layer shapes for the runtime's tests (which then need
// neither Python nor files) and the kernel benchmarks (tools/bench/kernels).
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <string>

#include "sfrt/exporter/model_spec.h"

namespace sfrt::exporter {

// width_divisor 1 = the published widths (64 ... 1024); 16 = every hidden width / 16.
inline exporter::ModelSpec SceneEdNetSpec(int width_divisor, uint32_t seed = 1) {
  std::mt19937 rng(seed);
  ModelSpec spec;
  spec.name = "sceneednet-w" + std::to_string(width_divisor) + "-test";
  int channels = 12;
  auto conv = [&](const std::string& name, int out, int stride, bool leaky) {
    ConvSpec c;
    c.name = name;
    c.in_channels = channels;
    c.out_channels = out;
    c.stride_h = c.stride_w = stride;
    c.padding_rule = PaddingRule::kSameUpper;
    c.activation = leaky ? Activation::kLeakyRelu : Activation::kNone;
    c.leaky_slope = 0.3f;
    // He-style scale keeps activations in range through the chain.
    std::normal_distribution<float> dist(0.0f, std::sqrt(2.0f / (9.0f * channels)));
    c.weights_hwio.resize(static_cast<size_t>(9) * channels * out);
    for (float& v : c.weights_hwio) v = dist(rng);
    std::uniform_real_distribution<float> bias(-0.1f, 0.1f);
    c.bias.resize(out);
    for (float& v : c.bias) v = bias(rng);
    spec.layers.push_back(c);
    channels = out;
  };
  auto up = [&](int i) { spec.layers.push_back(UpsampleSpec{"up" + std::to_string(i), 2, 2, {}}); };
  auto w = [&](int published) { return published / width_divisor; };
  conv("conv0", w(64), 2, true);
  conv("conv1", w(128), 2, true);
  conv("conv2", w(256), 2, true);
  conv("conv3", w(512), 2, true);
  conv("conv4", w(1024), 1, true);
  conv("conv5", w(1024), 1, true);
  up(1);
  conv("conv6", w(512), 1, true);
  up(2);
  conv("conv7", w(256), 1, true);
  up(3);
  conv("conv8", w(128), 1, true);
  up(4);
  spec.layers.push_back(CropSpec{"crop", CropRule::kToInputSize, {}, true, true, {}});
  conv("conv9", w(64), 1, true);
  conv("output", 3, 1, false);
  return spec;
}

}  // namespace sfrt::exporter
