// Turns a float32 ModelSpec into a mixed-precision one for runtime tests, with fixed activation
// quantisation (no calibration, so the same model on every machine): the model input as
// 0..255 pixels (scale 1, zero point 0), every other activation tensor with `act_scale` and
// `act_zero_point`; weights symmetric per output channel (scale = max |w| / 127, round half to
// even), with phase kernels for the convolutions that read a nearest-2x upsampling (as the
// exporter writes them). The exporter's calibrated quantiser is tested in tests/exporter.
#pragma once

#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <variant>
#include <vector>

#include "sfrt/exporter/model_spec.h"

namespace sfrt::testing {

// Per-output-channel symmetric int8 of `w` (HWIO with cout outputs): scale max |w| / 127.
inline void QuantizePerChannel(const std::vector<float>& w, size_t cout, std::vector<int8_t>* q,
                               std::vector<float>* scales) {
  scales->assign(cout, 1.0f);
  for (size_t o = 0; o < cout; ++o) {
    float m = 0.0f;
    for (size_t i = o; i < w.size(); i += cout) m = std::fmax(m, std::fabs(w[i]));
    if (m > 0.0f) (*scales)[o] = m / 127.0f;
  }
  q->resize(w.size());
  for (size_t i = 0; i < w.size(); ++i) {
    const float v = std::nearbyint(w[i] / (*scales)[i % cout]);
    (*q)[i] = static_cast<int8_t>(std::fmax(-127.0f, std::fmin(127.0f, v)));
  }
}

// The four phase kernels of a 3x3 convolution that reads a nearest-2x upsampling: along each
// axis phase 0 reads low-resolution pixels (i, i, i + 1) with its taps (0, 1, 2), phase 1 reads
// (i, i + 1, i + 1); taps reading one pixel are summed, then each phase quantised per channel.
inline void PhaseKernels(exporter::ConvSpec& c) {
  const size_t per_tap = static_cast<size_t>(c.in_channels) * c.out_channels;
  // pixel[phase][k]: the low-resolution tap (0 or 1) that 3x3 tap k reads.
  const int pixel[2][3] = {{0, 0, 1}, {0, 1, 1}};
  c.phase_weights_q.clear();
  c.phase_scales.clear();
  for (int py = 0; py < 2; ++py) {
    for (int px = 0; px < 2; ++px) {
      std::vector<float> w(4 * per_tap, 0.0f);
      for (int ky = 0; ky < 3; ++ky) {
        for (int kx = 0; kx < 3; ++kx) {
          const size_t t = static_cast<size_t>(pixel[py][ky] * 2 + pixel[px][kx]);
          for (size_t i = 0; i < per_tap; ++i) {
            w[t * per_tap + i] += c.weights_hwio[static_cast<size_t>(ky * 3 + kx) * per_tap + i];
          }
        }
      }
      std::vector<int8_t> q;
      std::vector<float> scales;
      QuantizePerChannel(w, static_cast<size_t>(c.out_channels), &q, &scales);
      c.phase_weights_q.insert(c.phase_weights_q.end(), q.begin(), q.end());
      c.phase_scales.insert(c.phase_scales.end(), scales.begin(), scales.end());
    }
  }
}

// int8_convs[k]: whether the k-th convolution becomes int8 (missing entries: true).
inline exporter::ModelSpec Int8Spec(exporter::ModelSpec spec,
                                    const std::vector<bool>& int8_convs = {},
                                    float act_scale = 4.0f / 255.0f, int act_zero_point = 77) {
  const QuantParams input{1.0f, 0};
  const QuantParams hidden{act_scale, act_zero_point};
  size_t k = 0;
  bool first = true;
  // Per layer name: whether its output is a nearest-2x upsampling, through a crop or not.
  std::map<std::string, bool> upsampled;
  std::string previous = spec.input.name;  // what a layer without named inputs reads
  for (exporter::LayerSpec& layer : spec.layers) {
    const std::string name = std::visit([](const auto& l) { return l.name; }, layer);
    const std::vector<std::string> inputs =
        std::visit([](const auto& l) { return l.inputs; }, layer);
    const std::string read = inputs.empty() ? previous : inputs[0];
    previous = name;
    upsampled[name] = false;
    if (const auto* u = std::get_if<exporter::UpsampleSpec>(&layer)) {
      upsampled[name] = u->factor_h == 2 && u->factor_w == 2;
    }
    if (std::holds_alternative<exporter::CropSpec>(layer)) upsampled[name] = upsampled[read];
    auto* c = std::get_if<exporter::ConvSpec>(&layer);
    if (c == nullptr) continue;
    const bool reads_upsampling = upsampled[read] && c->kernel_h == 3 && c->kernel_w == 3 &&
                                  c->stride_h == 1 && c->stride_w == 1;
    const bool int8 = k >= int8_convs.size() || int8_convs[k];
    ++k;
    if (int8) {
      c->precision = Precision::kInt8;
      c->input_quant = first ? input : hidden;
      c->output_quant = hidden;
      QuantizePerChannel(c->weights_hwio, static_cast<size_t>(c->out_channels), &c->weights_q,
                         &c->weight_scales);
      if (reads_upsampling) PhaseKernels(*c);
      c->weights_hwio.clear();
    }
    first = false;
  }
  return spec;
}

}  // namespace sfrt::testing
