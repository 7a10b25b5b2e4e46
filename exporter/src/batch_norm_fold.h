// Inference batch normalisation folded into the convolution before it, shared by the ONNX and
// Keras importers: y = (conv(x) - mean) * gamma / sqrt(var + epsilon) + beta becomes a
// convolution whose weights are scaled per output channel and whose bias is shifted. Not
// installed.
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

#include "sfrt/exporter/model_spec.h"

namespace sfrt::exporter {

// The normalisation as y = x * scale[c] + shift[c], computed in double.
struct ChannelAffine {
  std::vector<float> scale;
  std::vector<float> shift;
};

// From the four per-channel vectors (all the same size). Returns the first channel whose
// var + epsilon is not a positive finite number, or -1 when every channel is valid (then *out
// is filled).
inline long BatchNormAffine(const std::vector<float>& gamma, const std::vector<float>& beta,
                            const std::vector<float>& mean, const std::vector<float>& var,
                            double epsilon, ChannelAffine* out) {
  out->scale.resize(gamma.size());
  out->shift.resize(gamma.size());
  for (size_t c = 0; c < gamma.size(); ++c) {
    const double v = static_cast<double>(var[c]) + epsilon;
    if (!(v > 0) || !std::isfinite(v)) return static_cast<long>(c);
    const double s = gamma[c] / std::sqrt(v);
    out->scale[c] = static_cast<float>(s);
    out->shift[c] = static_cast<float>(beta[c] - mean[c] * s);
  }
  return -1;
}

// Applies `affine` (one entry per output channel) to a float32 convolution's (ConvSpec) or
// transposed convolution's (ConvTransposeSpec) HWIO weights (the output channel innermost) and
// bias (created as zeros when absent).
template <typename Spec>
void FoldIntoConv(const ChannelAffine& affine, Spec* conv) {
  const auto oc = static_cast<size_t>(conv->out_channels);
  if (conv->bias.empty()) conv->bias.assign(oc, 0.0f);
  for (size_t i = 0; i < conv->weights_hwio.size(); ++i) {
    conv->weights_hwio[i] *= affine.scale[i % oc];
  }
  for (size_t o = 0; o < oc; ++o) conv->bias[o] = conv->bias[o] * affine.scale[o] + affine.shift[o];
}

}  // namespace sfrt::exporter
