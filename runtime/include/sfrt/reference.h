// The model's forward pass on the scalar reference kernels, layer by layer, written for clarity:
// the oracle a Session is tested against (bit for bit where both compute in int8), and what the
// exporter's calibration observes when asked for results the same on every CPU. It allocates
// every tensor and is slow: not for the hot path.
#pragma once

#include <span>

#include "sfrt/layer_observer.h"
#include "sfrt/model.h"
#include "sfrt/shapes.h"
#include "sfrt/status.h"

namespace sfrt {

// Runs `model` on `input` (height x width x input channels, NHWC float32) and writes the last
// layer's output (float32) to `output`. Each layer computes in its own precision: an int8
// convolution reads uint8 (the float32 input or a float32 layer's output quantised with its
// input_quant) and writes uint8 for a following int8 convolution, float32 otherwise; a bf16
// convolution likewise reads and writes bf16 (kernels/bf16_job.h), and a nearest-2x upsampling
// (+ crop) before a 3x3 stride-1 bf16 convolution goes through its phase kernels as in a Session.
// A float32 tensor is converted where a Session converts it: before the upsamplings and crops
// that lead to the convolution reading it. `observer` is shown every layer's output (a graph's
// as float32, since the reference keeps float32 between a graph's layers).
Status RunReferenceForward(const Model& model, std::span<const float> input, int height, int width,
                           std::span<float> output, const LayerObserver& observer = {});

}  // namespace sfrt
