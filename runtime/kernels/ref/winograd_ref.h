// Reference Winograd F(m x m, 3 x 3) convolution (m = 2 or 4), written for clarity: the same
// algorithm the SIMD tiers run (kernels/winograd_job.h), one scalar step at a time, so that the
// method can be read and checked apart from the vectorisation. Tests compare it, like every
// optimised path, with the direct reference (ref::Conv2d); Session never calls it. It allocates
// its transformed weights and tile buffers on every call.
#pragma once

#include "kernels/tensor_view.h"
#include "sfrt/model.h"

namespace sfrt::ref {

// Same contract as ref::Conv2d for a 3x3 stride-1 convolution (params.kernel_* == 3,
// params.stride_* == 1); m is the output tile side, 2 or 4.
void Conv2dWinograd(const ConstTensorView& in, const ConvParams& params, const Padding& pads, int m,
                    const TensorView& out);

}  // namespace sfrt::ref
