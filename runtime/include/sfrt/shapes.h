// Shape inference and cost accounting for a model at a given input size. Pure functions of the
// model and the size; used by Session at load and by `sfrt inspect`.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "sfrt/model.h"
#include "sfrt/status.h"

namespace sfrt {

struct TensorShape {  // one image, NHWC
  int height = 0;
  int width = 0;
  int channels = 0;
  size_t elements() const {
    return static_cast<size_t>(height) * static_cast<size_t>(width) * static_cast<size_t>(channels);
  }
  friend bool operator==(const TensorShape&, const TensorShape&) = default;
};

// The largest height or width of the input and of every intermediate tensor (2^20). Larger
// sizes are rejected by InferGeometry (so by Session::Create) instead of overflowing int.
inline constexpr int kMaxTensorSide = 1 << 20;

// What one layer does at one input size.
struct LayerGeometry {
  TensorShape input;  // the first input's
  TensorShape output;
  Padding pads;         // Conv2D, ConvTranspose2D, Pool2D: the amounts in effect at this size
  Padding crop;         // Crop: rows/cols removed per side at this size
  uint64_t macs = 0;    // multiply-accumulates (Conv2D and ConvTranspose2D)
  uint64_t params = 0;  // weights + biases
};

// Pooling output size along one axis (PoolParams): as ConvOutputSize, rounded up when
// `ceil_mode` (then a last window starting past the input and its leading pad is dropped).
int PoolOutputSize(int in, int kernel, int stride, PaddingRule rule, int explicit_before,
                   int explicit_after, bool ceil_mode, int* pad_before, int* pad_after);

// Resize output size along one axis (ResizeParams): floor(in * num / den).
int64_t ResizeOutputSize(int in, int64_t num, int64_t den);

// Convolution output size along one axis; `pad_before`/`pad_after` receive the amounts.
// `kernel` is the window's extent (DilatedExtent for a dilated one). Returns <= 0 when the
// window does not fit.
int ConvOutputSize(int in, int kernel, int stride, PaddingRule rule, int explicit_before,
                   int explicit_after, int* pad_before, int* pad_after);

// Fills `out` (one entry per layer) for an input of height x width. Does not allocate when
// `out.size() == model.layers().size()`. Errors name the layer and the offending size.
Status InferGeometry(const Model& model, int height, int width, std::span<LayerGeometry> out);

// The last layer's output shape for an input of height x width. For a chain model (is_chain())
// it keeps no per-layer storage and allocates nothing on success (the message of an error is the
// only allocation); for a graph it allocates the layers' geometry (Session::OutputShape does not).
Result<TensorShape> InferOutputShape(const Model& model, int height, int width);

// Convenience for tools: allocates the vector.
Result<std::vector<LayerGeometry>> InferGeometry(const Model& model, int height, int width);

}  // namespace sfrt
