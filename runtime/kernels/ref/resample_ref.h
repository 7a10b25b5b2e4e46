// Reference data-movement kernels: nearest upsampling and copying a (cropped) view.
#pragma once

#include "kernels/tensor_view.h"

namespace sfrt::ref {

// out[y][x][c] = in[y / factor_h][x / factor_w][c]; out is (in.height*factor_h, in.width*factor_w).
void UpsampleNearest(const ConstTensorView& in, int factor_h, int factor_w, const TensorView& out);

// out = in, element by element; both views have the same shape.
void Copy(const ConstTensorView& in, const TensorView& out);

}  // namespace sfrt::ref
