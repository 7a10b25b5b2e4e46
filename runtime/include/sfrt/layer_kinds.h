// What each layer kind is, asked of the kind itself: its name, its one-line description, the
// padding it adds or removes, how many parameters it stores. Every answer comes from the layer
// kind's own unit (runtime/src/ops/<kind>.cc), found through the runtime's one table of kinds
// (runtime/src/ops/registry.cc); nothing outside that unit switches on the kind to answer them.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "sfrt/model.h"
#include "sfrt/shapes.h"

namespace sfrt {

// How many layer kinds there are (LayerKind's enumerators run 0..kLayerKindCount - 1).
inline constexpr int kLayerKindCount = static_cast<int>(LayerKind::kChannelAffine) + 1;

// The kind as the schema names its op: "Conv2D", "Upsample", "Crop", "Concat", "Add",
// "ConvTranspose2D", "Pool2D", "Resize", "ChannelAffine".
const char* LayerKindName(LayerKind kind);

// How much a description says.
enum class LayerText {
  kBrief,  // for tables of steps: "conv 3x3/s1", "upsample x2", "concat 2"
  kFull,   // `sfrt inspect`: every parameter that is not its default, activation included
};
std::string DescribeLayer(const LayerDesc& layer, LayerText detail);

// What the layer adds (convolution, pooling: "t,l,b,r rule") or removes (crop, transposed
// convolution: "crop t,l,b,r") per side at the size `geometry` is for; "-" for neither.
std::string DescribePadding(const LayerDesc& layer, const LayerGeometry& geometry);

// The weights and biases (or per-channel scales and shifts) the layer stores.
uint64_t LayerParameterCount(const LayerDesc& layer);

// The phase rule's premise: whether tensor `input` (a layer index into `layers`, or kModelInput)
// is a nearest-2x upsampling, or a crop of one. Returns the upsampling's index and sets *crop to
// the crop's (-1 when none); -1 when it is neither. A 3x3 stride-1 convolution that reads such a
// tensor computes the pixels whose window lies inside it from four 2x2 phase kernels over the
// low-resolution map (int8 files carry them as phase_weights; kernels/conv_job.h).
int ReadsNearest2xUpsampling(std::span<const LayerDesc> layers, int input, int* crop = nullptr);

}  // namespace sfrt
