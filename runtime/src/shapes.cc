#include "sfrt/shapes.h"

#include <algorithm>
#include <string>

#include "ops/layer_op.h"

namespace sfrt {

int ConvOutputSize(int in, int kernel, int stride, PaddingRule rule, int explicit_before,
                   int explicit_after, int* pad_before, int* pad_after) {
  if (rule != PaddingRule::kExplicit) {
    const int out = (in + stride - 1) / stride;
    const int total = std::max((out - 1) * stride + kernel - in, 0);
    const int smaller = total / 2;
    *pad_before = rule == PaddingRule::kSameUpper ? smaller : total - smaller;
    *pad_after = total - *pad_before;
    return out;
  }
  *pad_before = explicit_before;
  *pad_after = explicit_after;
  const int padded = in + explicit_before + explicit_after;
  if (padded < kernel) return 0;
  return (padded - kernel) / stride + 1;
}

int64_t ResizeOutputSize(int in, int64_t num, int64_t den) { return int64_t{in} * num / den; }

int PoolOutputSize(int in, int kernel, int stride, PaddingRule rule, int explicit_before,
                   int explicit_after, bool ceil_mode, int* pad_before, int* pad_after) {
  if (rule != PaddingRule::kExplicit || !ceil_mode) {
    return ConvOutputSize(in, kernel, stride, rule, explicit_before, explicit_after, pad_before,
                          pad_after);
  }
  *pad_before = explicit_before;
  *pad_after = explicit_after;
  // ceil(span / stride) + 1, span possibly negative (a window wider than the padded input still
  // gives one output in ceil mode, as in PyTorch and ONNX).
  const int64_t span = int64_t{in} + explicit_before + explicit_after - kernel;
  const int64_t up = span + stride - 1;
  int64_t out = (up >= 0 ? up / stride : -((-up + stride - 1) / stride)) + 1;
  if (out >= 1 && (out - 1) * stride >= int64_t{in} + explicit_before) --out;
  return static_cast<int>(std::max<int64_t>(out, 0));
}

namespace {

// The input size every query accepts, whatever the model.
Status CheckInputSize(int height, int width) {
  if (height <= 0 || width <= 0) {
    return Status::Error("input size " + std::to_string(height) + "x" + std::to_string(width) +
                         " is not positive");
  }
  if (height > kMaxTensorSide || width > kMaxTensorSide) {
    return Status::Error("input size " + std::to_string(height) + "x" + std::to_string(width) +
                         " exceeds the largest supported side, " + std::to_string(kMaxTensorSide));
  }
  return Status::Ok();
}

// Fills `g` for layer `i` through its kind's shape rule (ops/layer_op.h).
Status GeometryOfLayer(const LayerDesc& layer, const ops::GeometryInputs& in, LayerGeometry& g) {
  g = LayerGeometry{};
  g.input = in.first;
  return ops::OpOf(layer.kind).geometry(layer, in, g);
}

}  // namespace

Status InferGeometry(const Model& model, int height, int width, std::span<LayerGeometry> out) {
  const auto layers = model.layers();
  if (out.size() != layers.size()) {
    return Status::Error("internal: geometry buffer has " + std::to_string(out.size()) +
                         " entries for " + std::to_string(layers.size()) + " layers");
  }
  if (Status s = CheckInputSize(height, width); !s.ok()) return s;
  ops::GeometryInputs in;
  in.height = height;
  in.width = width;
  in.model_input = {height, width, model.metadata().input.channels};
  for (size_t i = 0; i < layers.size(); ++i) {
    in.index = i;
    in.earlier = std::span<const LayerGeometry>(out.data(), i);
    in.first = in.Of(layers[i].inputs[0]);
    if (Status s = GeometryOfLayer(layers[i], in, out[i]); !s.ok()) return s;
  }
  return Status::Ok();
}

Result<TensorShape> InferOutputShape(const Model& model, int height, int width) {
  if (!model.is_chain()) {
    Result<std::vector<LayerGeometry>> geometry = InferGeometry(model, height, width);
    if (!geometry.ok()) return geometry.status();
    return geometry->back().output;
  }
  if (Status s = CheckInputSize(height, width); !s.ok()) return s;
  const auto layers = model.layers();
  // A chain's layers read only the previous one's output: no earlier geometry is kept.
  ops::GeometryInputs in;
  in.height = height;
  in.width = width;
  in.model_input = {height, width, model.metadata().input.channels};
  in.first = in.model_input;
  LayerGeometry g;
  for (size_t i = 0; i < layers.size(); ++i) {
    in.index = i;
    if (Status s = GeometryOfLayer(layers[i], in, g); !s.ok()) return s;
    in.first = g.output;
  }
  return in.first;
}

Result<std::vector<LayerGeometry>> InferGeometry(const Model& model, int height, int width) {
  std::vector<LayerGeometry> geometry(model.layers().size());
  Status s = InferGeometry(model, height, width, geometry);
  if (!s.ok()) return s;
  return geometry;
}

}  // namespace sfrt
