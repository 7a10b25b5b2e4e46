// Turns a float32 ModelSpec into a bf16 one for runtime tests: the chosen convolutions (all by
// default) get precision bf16 and keep their float32 weights, which a session rounds to bf16
// (kernels/bf16_job.h). The exporter's `--precision bf16` is tested in tests/tools.
#pragma once

#include <variant>
#include <vector>

#include "sfrt/exporter/model_spec.h"

namespace sfrt::testing {

inline exporter::ModelSpec Bf16Spec(exporter::ModelSpec spec,
                                    const std::vector<bool>& bf16_convs = {}) {
  size_t k = 0;
  for (exporter::LayerSpec& layer : spec.layers) {
    auto* c = std::get_if<exporter::ConvSpec>(&layer);
    if (c == nullptr) continue;
    if (k >= bf16_convs.size() || bf16_convs[k]) c->precision = Precision::kBFloat16;
    ++k;
  }
  return spec;
}

}  // namespace sfrt::testing
