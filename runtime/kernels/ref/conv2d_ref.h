// Reference 2D convolution: written for clarity, the oracle every optimised kernel is tested
// against. Not fast on purpose; do not optimise it.
#pragma once

#include "kernels/tensor_view.h"
#include "sfrt/model.h"

namespace sfrt::ref {

// out[oy][ox][co] = act(bias[co] + sum over (ky, kx, ci) of
//     in[oy*stride_h - pads.top + ky*dilation_h][ox*stride_w - pads.left + kx*dilation_w]
//       [g*gi + ci] * weights[ky][kx][ci][co]),
// where g = co / (out_channels / groups) is co's group, ci runs over gi = in_channels / groups,
// and input positions outside the image read as zero. Terms are added in (ky, kx, ci) order.
// `out` must have the convolution's output size; `pads` are the amounts in effect at this size
// (pads.bottom/right only decide the output size, which the caller already did).
void Conv2d(const ConstTensorView& in, const ConvParams& params, const Padding& pads,
            const TensorView& out);

}  // namespace sfrt::ref
