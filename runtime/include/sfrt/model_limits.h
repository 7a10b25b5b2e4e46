// The limits the model loader enforces (Model::Load*), in one table. The importers (ONNX, Keras)
// check the same numbers before they write a file, so an imported model is never one the loader
// rejects; tests/exporter/model_limits_test.cc builds a model at each limit and one past it.
#pragma once

#include <cstdint>

namespace sfrt::model_limits {

// Layers in one model.
inline constexpr int kMaxLayers = 4096;
// Channels of the input and of every Conv2D output.
inline constexpr int kMaxChannels = 1 << 16;
// Each side of a Conv2D kernel: 1..kMaxKernel.
inline constexpr int kMaxKernel = 31;
// Each Conv2D stride: 1..kMaxStride.
inline constexpr int kMaxStride = 16;
// Each dilation of a Conv2D, ConvTranspose2D or Pool2D (schema 1.8): 1..kMaxDilation.
inline constexpr int kMaxDilation = 64;
// Each Upsample factor: 1..kMaxUpsample.
inline constexpr int kMaxUpsample = 64;
// Resize scales (schema 1.7): numerator 1..kMaxResizeNum, denominator 1..kMaxResizeDen, their
// ratio at most kMaxUpsample.
inline constexpr int64_t kMaxResizeNum = int64_t{1} << 40;
inline constexpr int64_t kMaxResizeDen = int64_t{1} << 32;
// tf_crop_and_resize's region of interest (schema 1.9): each fraction within -64..64.
inline constexpr float kMaxResizeRoi = 64.0f;
// Explicit Conv2D pads on a side: 0..MaxPad(kernel side along that axis).
constexpr int MaxPad(int kernel) { return kernel - 1; }

}  // namespace sfrt::model_limits
