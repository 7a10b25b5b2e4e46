// A chain through every float32-only layer kind of schema 1.6-1.8 (pooling, dilated and grouped
// convolutions, a ChannelAffine with a 1.8 activation, a linear Resize, a dilated transposed
// convolution) with seeded weights, for tests that need them all in one model (zero allocation).
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "sfrt/exporter/model_spec.h"

namespace sfrt::testing {

// conv 3x3 12->8 + relu -> maxpool 2x2/2 (ceil) -> depthwise 3x3 dilation 2 -> sigmoid ->
// resize linear x2 -> conv 3x3 groups 2 8->4 -> deconv 3x3 dilation 2 4->3.
inline exporter::ModelSpec FloatOpsChainSpec() {
  using namespace sfrt::exporter;
  ModelSpec spec;
  spec.name = "float-ops-chain";
  std::mt19937 rng(13);
  auto fill = [&](std::vector<float>& v, size_t n, float scale) {
    std::uniform_real_distribution<float> dist(-scale, scale);
    v.resize(n);
    for (float& x : v) x = dist(rng);
  };
  auto conv = [&](const char* name, int in, int out, int groups, int dilation) {
    ConvSpec c;
    c.name = name;
    c.in_channels = in;
    c.out_channels = out;
    c.kernel_h = c.kernel_w = 3;
    c.groups = groups;
    c.dilation_h = c.dilation_w = dilation;
    c.pads = {dilation, dilation, dilation, dilation};
    fill(c.weights_hwio, static_cast<size_t>(9) * (in / groups) * out,
         std::sqrt(3.0f / (9.0f * in / groups)) * (in == 12 ? 1.0f / 128 : 1.0f));
    fill(c.bias, static_cast<size_t>(out), 0.1f);
    return c;
  };
  ConvSpec first = conv("conv0", 12, 8, 1, 1);
  first.activation = Activation::kRelu;
  spec.layers.push_back(first);
  PoolSpec pool;
  pool.name = "pool";
  pool.ceil_mode = true;
  spec.layers.push_back(pool);
  spec.layers.push_back(conv("depthwise", 8, 8, 8, 2));
  ChannelAffineSpec squash{"squash", {}, std::vector<float>(8, 1.0f), std::vector<float>(8, 0.0f)};
  squash.activation = Activation::kSigmoid;
  spec.layers.push_back(squash);
  ResizeSpec resize;
  resize.name = "resize";
  resize.params.mode = ResizeMode::kLinear;
  resize.params.scale_num_h = resize.params.scale_num_w = 2;
  spec.layers.push_back(resize);
  spec.layers.push_back(conv("grouped", 8, 4, 2, 1));
  ConvTransposeSpec up;
  up.name = "deconv";
  up.in_channels = 4;
  up.out_channels = 3;
  up.kernel_h = up.kernel_w = 3;
  up.stride_h = up.stride_w = 1;
  up.dilation_h = up.dilation_w = 2;
  up.pads = {2, 2, 2, 2};
  fill(up.weights_hwio, 9 * 4 * 3, 0.3f);
  fill(up.bias, 3, 0.1f);
  spec.layers.push_back(up);
  return spec;
}

}  // namespace sfrt::testing
