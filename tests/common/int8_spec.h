// Turns a float32 ModelSpec into a mixed-precision one for runtime tests, with fixed activation
// quantisation (no calibration, so the same model on every machine): the model input as
// 0..255 pixels (scale 1, zero point 0), every other activation tensor with `act_scale` and
// `act_zero_point`; weights symmetric per output channel (scale = max |w| / 127, round half to
// even). The exporter's calibrated quantiser is tested in tests/exporter.
#pragma once

#include <cmath>
#include <cstdint>
#include <variant>
#include <vector>

#include "sfrt/exporter/model_spec.h"

namespace sfrt::testing {

// int8_convs[k]: whether the k-th convolution becomes int8 (missing entries: true).
inline exporter::ModelSpec Int8Spec(exporter::ModelSpec spec,
                                    const std::vector<bool>& int8_convs = {},
                                    float act_scale = 4.0f / 255.0f, int act_zero_point = 77) {
  const QuantParams input{1.0f, 0};
  const QuantParams hidden{act_scale, act_zero_point};
  size_t k = 0;
  bool first = true;
  for (exporter::LayerSpec& layer : spec.layers) {
    auto* c = std::get_if<exporter::ConvSpec>(&layer);
    if (c == nullptr) continue;
    const bool int8 = k >= int8_convs.size() || int8_convs[k];
    ++k;
    if (int8) {
      c->precision = Precision::kInt8;
      c->input_quant = first ? input : hidden;
      c->output_quant = hidden;
      const size_t cout = static_cast<size_t>(c->out_channels);
      c->weight_scales.assign(cout, 1.0f);
      for (size_t o = 0; o < cout; ++o) {
        float m = 0.0f;
        for (size_t i = o; i < c->weights_hwio.size(); i += cout) {
          m = std::fmax(m, std::fabs(c->weights_hwio[i]));
        }
        if (m > 0.0f) c->weight_scales[o] = m / 127.0f;
      }
      c->weights_q.resize(c->weights_hwio.size());
      for (size_t i = 0; i < c->weights_hwio.size(); ++i) {
        const float q = std::nearbyint(c->weights_hwio[i] / c->weight_scales[i % cout]);
        c->weights_q[i] = static_cast<int8_t>(std::fmax(-127.0f, std::fmin(127.0f, q)));
      }
      c->weights_hwio.clear();
    }
    first = false;
  }
  return spec;
}

}  // namespace sfrt::testing
