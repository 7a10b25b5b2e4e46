// A small FlowNetS-style decoder with seeded weights for runtime tests of transposed
// convolutions (schema 1.6), built without Python or files.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "sfrt/exporter/model_spec.h"

namespace sfrt::testing {

// input -> conv1 7x7/2 -> conv2 5x5/2 -> deconv2 4x4/2 (cut to conv1's size) ++ conv1 ->
// deconv1 3x3/2 with output padding 1 (cut to the input's size) -> conv 3x3: FlowNetS's pattern
// at two levels, with the crops odd sizes need.
inline exporter::ModelSpec TwoLevelDecoderSpec() {
  using namespace sfrt::exporter;
  ModelSpec spec;
  spec.name = "deconv-two-level";
  std::mt19937 rng(7);
  auto fill = [&](std::vector<float>& v, size_t n, float scale) {
    std::uniform_real_distribution<float> dist(-scale, scale);
    v.resize(n);
    for (float& x : v) x = dist(rng);
  };
  auto conv = [&](const char* name, const char* input, int in, int out, int k, int s) {
    ConvSpec c;
    c.name = name;
    c.inputs = {input};
    c.in_channels = in;
    c.out_channels = out;
    c.kernel_h = c.kernel_w = k;
    c.stride_h = c.stride_w = s;
    c.pads = {(k - 1) / 2, (k - 1) / 2, (k - 1) / 2, (k - 1) / 2};
    c.activation = Activation::kLeakyRelu;
    c.leaky_slope = 0.1f;
    fill(c.weights_hwio, static_cast<size_t>(k) * k * in * out,
         std::sqrt(3.0f / (k * k * in)) * (in == 12 ? 1.0f / 128 : 1.0f));
    fill(c.bias, static_cast<size_t>(out), 0.1f);
    return c;
  };
  auto deconv = [&](const char* name, const char* input, int in, int out, int k, int out_pad) {
    ConvTransposeSpec d;
    d.name = name;
    d.inputs = {input};
    d.in_channels = in;
    d.out_channels = out;
    d.kernel_h = d.kernel_w = k;
    d.pads = {1, 1, 1, 1};
    d.output_padding_h = d.output_padding_w = out_pad;
    d.activation = Activation::kLeakyRelu;
    d.leaky_slope = 0.1f;
    fill(d.weights_hwio, static_cast<size_t>(k) * k * in * out, std::sqrt(12.0f / (k * k * in)));
    fill(d.bias, static_cast<size_t>(out), 0.1f);
    return d;
  };
  spec.layers.push_back(conv("conv1", "stereo_pairs", 12, 8, 7, 2));
  spec.layers.push_back(conv("conv2", "conv1", 8, 16, 5, 2));
  spec.layers.push_back(deconv("deconv2", "conv2", 16, 8, 4, 0));
  spec.layers.push_back(
      CropSpec{"cut2", CropRule::kToSecondInput, {}, false, false, {"deconv2", "conv1"}});
  spec.layers.push_back(ConcatSpec{"cat1", {"conv1", "cut2"}});
  spec.layers.push_back(deconv("deconv1", "cat1", 16, 8, 3, 1));
  spec.layers.push_back(CropSpec{"cut1", CropRule::kToInputSize, {}, false, false, {"deconv1"}});
  ConvSpec out = conv("flow", "cut1", 8, 3, 3, 1);
  out.activation = Activation::kNone;
  spec.layers.push_back(out);
  return spec;
}

}  // namespace sfrt::testing
