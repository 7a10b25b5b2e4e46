// LayerObserver: how a forward pass shows its layers' outputs to a caller (the exporter's
// calibration, debugging tools). Both RunReferenceForward (sfrt/reference.h) and
// Session::RunObserved (sfrt/session.h) take one.
#pragma once

#include <functional>
#include <span>

#include "sfrt/shapes.h"

namespace sfrt {

// Called after a layer has run with its output as real numbers, dense NHWC in `shape`: float32
// values, a uint8 tensor's values dequantised (scale * (q - zero_point), in float32), or a bf16
// tensor's values. `values` is valid during the call only.
using LayerObserver =
    std::function<void(int layer, const TensorShape& shape, std::span<const float> values)>;

}  // namespace sfrt
