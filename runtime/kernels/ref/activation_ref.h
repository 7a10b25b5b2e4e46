// The activations, per value, written for clarity: the one definition every reference kernel
// applies (the SIMD epilogues are tested against it through those kernels).
#pragma once

#include <algorithm>
#include <cmath>

#include "sfrt/model.h"

namespace sfrt::ref {

// kNone, kRelu and kLeakyRelu (slope `leaky_slope`); the ChannelAffine-only kinds need their
// parameters: ActivateAffine.
inline float Activate(float v, Activation activation, float leaky_slope) {
  switch (activation) {
    case Activation::kRelu:
      return v > 0.0f ? v : 0.0f;
    case Activation::kLeakyRelu:
      return v > 0.0f ? v : v * leaky_slope;
    default:
      return v;
  }
}

// Every kind, as a ChannelAffine layer applies it (sfrt/model.h, ChannelAffineParams).
inline float ActivateAffine(float v, const ChannelAffineParams& p) {
  switch (p.activation) {
    case Activation::kElu:
      return v > 0.0f ? v : p.elu_alpha * std::expm1(v);
    case Activation::kSigmoid:
      return 1.0f / (1.0f + std::exp(-v));
    case Activation::kTanh:
      return std::tanh(v);
    case Activation::kClip:
      return std::min(std::max(v, p.clip_min), p.clip_max);
    default:
      return Activate(v, p.activation, p.leaky_slope);
  }
}

}  // namespace sfrt::ref
