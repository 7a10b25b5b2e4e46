// The runtime's one table of layer kinds (the op resolver): a kind's unit is found here and
// nowhere else. Adding a kind: its unit (ops/<kind>.cc), its line below, LayerKind's enumerator.
#include <array>
#include <cstdio>

#include "ops/layer_op.h"

namespace sfrt::ops {
namespace {

// Indexed by LayerKind.
constexpr std::array<const LayerOp*, kLayerKindCount> kOps = {
    &kConv2DOp,          &kUpsampleOp, &kCropOp,   &kConcatOp,        &kAddOp,
    &kConvTranspose2DOp, &kPool2DOp,   &kResizeOp, &kChannelAffineOp,
};

}  // namespace

const LayerOp& OpOf(LayerKind kind) { return *kOps[static_cast<size_t>(kind)]; }

const LayerOp* OpStoredAs(schema::LayerOp stored) {
  if (stored == schema::LayerOp::NONE) return nullptr;
  for (const LayerOp* op : kOps) {
    if (op->stored[0] == stored || op->stored[1] == stored) return op;
  }
  return nullptr;
}

std::string Quote(const LayerDesc& layer, size_t index) {
  return "layer " + std::to_string(index) + " '" + layer.name + "'";
}

std::string SizeText(const TensorShape& s) {
  return std::to_string(s.height) + "x" + std::to_string(s.width) + "x" +
         std::to_string(s.channels);
}

std::string FloatText(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

std::string ActivationSuffix(Activation activation, float leaky_slope,
                             const ChannelAffineParams* affine) {
  switch (activation) {
    case Activation::kNone:
      return "";
    case Activation::kLeakyRelu:
      return " + leaky(" + FloatText(leaky_slope) + ")";
    case Activation::kElu:
      return " + elu(" + FloatText(affine->elu_alpha) + ")";
    case Activation::kClip:
      return " + clip(" + FloatText(affine->clip_min) + ".." + FloatText(affine->clip_max) + ")";
    default:
      return std::string(" + ") + ActivationName(activation);
  }
}

std::string DilationSuffix(int dh, int dw) {
  if (dh == 1 && dw == 1) return "";
  return " dilation " + std::to_string(dh) + (dw == dh ? "" : "x" + std::to_string(dw));
}

std::string PadsText(const Padding& p) {
  return std::to_string(p.top) + "," + std::to_string(p.left) + "," + std::to_string(p.bottom) +
         "," + std::to_string(p.right);
}

std::string NoPadding(const LayerDesc&, const LayerGeometry&) { return "-"; }

}  // namespace sfrt::ops

namespace sfrt {

const char* LayerKindName(LayerKind kind) { return ops::OpOf(kind).name; }

std::string DescribeLayer(const LayerDesc& layer, LayerText detail) {
  return ops::OpOf(layer.kind).describe(layer, detail);
}

std::string DescribePadding(const LayerDesc& layer, const LayerGeometry& geometry) {
  return ops::OpOf(layer.kind).padding(layer, geometry);
}

uint64_t LayerParameterCount(const LayerDesc& layer) {
  return ops::OpOf(layer.kind).parameters(layer);
}

bool Float32OnlyKind(LayerKind kind) { return ops::OpOf(kind).float32_only; }

int ReadsNearest2xUpsampling(std::span<const LayerDesc> layers, int input, int* crop) {
  if (crop != nullptr) *crop = -1;
  int k = input;
  if (k >= 0 && layers[static_cast<size_t>(k)].kind == LayerKind::kCrop) {
    if (crop != nullptr) *crop = k;
    k = layers[static_cast<size_t>(k)].inputs[0];
  }
  const bool nearest2x = k >= 0 && layers[static_cast<size_t>(k)].kind == LayerKind::kUpsample &&
                         layers[static_cast<size_t>(k)].upsample.factor_h == 2 &&
                         layers[static_cast<size_t>(k)].upsample.factor_w == 2;
  if (nearest2x) return k;
  if (crop != nullptr) *crop = -1;
  return -1;
}

}  // namespace sfrt
