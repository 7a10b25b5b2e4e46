// Reference max and average pooling (schema 1.6, float32), written for clarity, on output rows
// [row_begin, row_end) so that a session can split a layer over threads.
#pragma once

#include "kernels/tensor_view.h"
#include "sfrt/model.h"

namespace sfrt::ref {

// `pads`: the amounts in effect at this size (LayerGeometry::pads); `out` has the layer's output
// size for `in` (sfrt/shapes.h) and in's channels.
void PoolRows(const ConstTensorView& in, const PoolParams& params, const Padding& pads,
              const TensorView& out, int row_begin, int row_end);

}  // namespace sfrt::ref
