#include "sfrt/shapes.h"

#include <algorithm>
#include <string>

namespace sfrt {
namespace {

std::string Quote(const LayerDesc& layer, size_t index) {
  return "layer " + std::to_string(index) + " '" + layer.name + "'";
}

}  // namespace

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

std::string SizeText(const TensorShape& s) {
  return std::to_string(s.height) + "x" + std::to_string(s.width) + "x" +
         std::to_string(s.channels);
}

// Fills `g` for layer `i`, which reads `cur` (and, for a Concat or an Add, also the tensors
// `shape_of` gives for its other inputs), in a model whose input is height x width.
template <typename ShapeOf>
Status GeometryOfLayer(const LayerDesc& layer, size_t i, int height, int width,
                       const TensorShape& cur, const ShapeOf& shape_of, LayerGeometry& g) {
  g = LayerGeometry{};
  g.input = cur;
  switch (layer.kind) {
    case LayerKind::kConcat: {
      g.output = cur;
      for (size_t k = 1; k < layer.inputs.size(); ++k) {
        const TensorShape other = shape_of(layer.inputs[k]);
        if (other.height != cur.height || other.width != cur.width) {
          return Status::Error(Quote(layer, i) + ": concatenates a " + SizeText(cur) +
                               " tensor with a " + SizeText(other) +
                               " one; all its inputs must have the same height and width");
        }
        g.output.channels += other.channels;
      }
      break;
    }
    case LayerKind::kAdd: {
      const TensorShape other = shape_of(layer.inputs[1]);
      if (!(other == cur)) {
        return Status::Error(Quote(layer, i) + ": adds a " + SizeText(cur) + " tensor to a " +
                             SizeText(other) + " one; both must have the same shape");
      }
      g.output = cur;
      break;
    }
    case LayerKind::kConv2D: {
      const ConvParams& c = layer.conv;
      const int oh =
          ConvOutputSize(cur.height, DilatedExtent(c.kernel_h, c.dilation_h), c.stride_h,
                         c.padding_rule, c.pads.top, c.pads.bottom, &g.pads.top, &g.pads.bottom);
      const int ow =
          ConvOutputSize(cur.width, DilatedExtent(c.kernel_w, c.dilation_w), c.stride_w,
                         c.padding_rule, c.pads.left, c.pads.right, &g.pads.left, &g.pads.right);
      if (oh <= 0 || ow <= 0) {
        return Status::Error(Quote(layer, i) + ": input " + std::to_string(cur.height) + "x" +
                             std::to_string(cur.width) + " is smaller than its " +
                             std::to_string(c.kernel_h) + "x" + std::to_string(c.kernel_w) +
                             " kernel with its padding");
      }
      g.output = {oh, ow, c.out_channels};
      const uint64_t group_inputs = static_cast<uint64_t>(c.in_channels / c.groups);
      g.params = static_cast<uint64_t>(c.kernel_h) * c.kernel_w * group_inputs * c.out_channels +
                 static_cast<uint64_t>(c.out_channels);
      g.macs = static_cast<uint64_t>(g.output.elements()) * c.kernel_h * c.kernel_w * group_inputs;
      break;
    }
    case LayerKind::kConvTranspose2D: {
      const ConvTransposeParams& c = layer.deconv;
      // In 64 bits: a side up to kMaxTensorSide times a stride up to kMaxStride.
      const int64_t oh = (int64_t{cur.height} - 1) * c.stride_h - c.pads.top - c.pads.bottom +
                         DilatedExtent(c.kernel_h, c.dilation_h) + c.output_padding_h;
      const int64_t ow = (int64_t{cur.width} - 1) * c.stride_w - c.pads.left - c.pads.right +
                         DilatedExtent(c.kernel_w, c.dilation_w) + c.output_padding_w;
      if (oh <= 0 || ow <= 0 || oh > kMaxTensorSide || ow > kMaxTensorSide) {
        return Status::Error(Quote(layer, i) + ": a " + std::to_string(cur.height) + "x" +
                             std::to_string(cur.width) + " input gives a " + std::to_string(oh) +
                             "x" + std::to_string(ow) + " output; each side must be in 1.." +
                             std::to_string(kMaxTensorSide));
      }
      g.output = {static_cast<int>(oh), static_cast<int>(ow), c.out_channels};
      g.pads = c.pads;
      g.params = static_cast<uint64_t>(c.kernel_h) * c.kernel_w * c.in_channels * c.out_channels +
                 static_cast<uint64_t>(c.out_channels);
      g.macs = static_cast<uint64_t>(cur.elements()) * c.kernel_h * c.kernel_w * c.out_channels;
      break;
    }
    case LayerKind::kChannelAffine:
      g.output = cur;
      break;
    case LayerKind::kResize: {
      const ResizeParams& r = layer.resize;
      const int64_t oh = ResizeOutputSize(cur.height, r.scale_num_h, r.scale_den_h);
      const int64_t ow = ResizeOutputSize(cur.width, r.scale_num_w, r.scale_den_w);
      if (oh < 1 || ow < 1 || oh > kMaxTensorSide || ow > kMaxTensorSide) {
        return Status::Error(Quote(layer, i) + ": resizing " + std::to_string(cur.height) + "x" +
                             std::to_string(cur.width) + " gives " + std::to_string(oh) + "x" +
                             std::to_string(ow) + ", outside 1.." + std::to_string(kMaxTensorSide) +
                             " per side");
      }
      g.output = {static_cast<int>(oh), static_cast<int>(ow), cur.channels};
      break;
    }
    case LayerKind::kPool2D: {
      const PoolParams& p = layer.pool;
      const int oh = PoolOutputSize(cur.height, DilatedExtent(p.kernel_h, p.dilation_h), p.stride_h,
                                    p.padding_rule, p.pads.top, p.pads.bottom, p.ceil_mode,
                                    &g.pads.top, &g.pads.bottom);
      const int ow = PoolOutputSize(cur.width, DilatedExtent(p.kernel_w, p.dilation_w), p.stride_w,
                                    p.padding_rule, p.pads.left, p.pads.right, p.ceil_mode,
                                    &g.pads.left, &g.pads.right);
      if (oh <= 0 || ow <= 0) {
        return Status::Error(Quote(layer, i) + ": input " + std::to_string(cur.height) + "x" +
                             std::to_string(cur.width) + " is smaller than its " +
                             std::to_string(p.kernel_h) + "x" + std::to_string(p.kernel_w) +
                             " window with its padding");
      }
      if (p.kind == PoolKind::kArgMax && cur.elements() > (size_t{1} << 24)) {
        return Status::Error(Quote(layer, i) + ": an argmax pool over " +
                             std::to_string(cur.height) + "x" + std::to_string(cur.width) + "x" +
                             std::to_string(cur.channels) +
                             " values: float32 holds their indices exactly up to 2^24 only");
      }
      g.output = {oh, ow, cur.channels};
      break;
    }
    case LayerKind::kUpsample:
      if (cur.height > kMaxTensorSide / layer.upsample.factor_h ||
          cur.width > kMaxTensorSide / layer.upsample.factor_w) {
        return Status::Error(
            Quote(layer, i) + ": upsampling " + std::to_string(cur.height) + "x" +
            std::to_string(cur.width) + " by " + std::to_string(layer.upsample.factor_h) + "x" +
            std::to_string(layer.upsample.factor_w) + " exceeds the largest supported side, " +
            std::to_string(kMaxTensorSide));
      }
      g.output = {cur.height * layer.upsample.factor_h, cur.width * layer.upsample.factor_w,
                  cur.channels};
      break;
    case LayerKind::kCrop: {
      const CropParams& c = layer.crop;
      if (c.rule == CropRule::kExplicit) {
        g.crop = c.amounts;
      } else {
        const bool to_input = c.rule == CropRule::kToInputSize;
        const TensorShape target =
            to_input ? TensorShape{height, width, 0} : shape_of(layer.inputs[1]);
        const int excess_rows = cur.height - target.height;
        const int excess_cols = cur.width - target.width;
        if (excess_rows < 0 || excess_cols < 0) {
          return Status::Error(Quote(layer, i) + ": crops to " +
                               (to_input ? "the input size " : "its second input's size ") +
                               std::to_string(target.height) + "x" + std::to_string(target.width) +
                               " but receives only " + std::to_string(cur.height) + "x" +
                               std::to_string(cur.width));
        }
        (c.excess_rows_from_top ? g.crop.top : g.crop.bottom) = excess_rows;
        (c.excess_cols_from_left ? g.crop.left : g.crop.right) = excess_cols;
      }
      // In 64 bits: explicit amounts are any non-negative int in a (crafted) file.
      const int64_t rows = int64_t{cur.height} - g.crop.top - g.crop.bottom;
      const int64_t cols = int64_t{cur.width} - g.crop.left - g.crop.right;
      if (rows <= 0 || cols <= 0) {
        return Status::Error(Quote(layer, i) + ": removes everything of a " +
                             std::to_string(cur.height) + "x" + std::to_string(cur.width) +
                             " input");
      }
      g.output = {static_cast<int>(rows), static_cast<int>(cols), cur.channels};
      break;
    }
  }
  return Status::Ok();
}

}  // namespace

Status InferGeometry(const Model& model, int height, int width, std::span<LayerGeometry> out) {
  const auto layers = model.layers();
  if (out.size() != layers.size()) {
    return Status::Error("internal: geometry buffer has " + std::to_string(out.size()) +
                         " entries for " + std::to_string(layers.size()) + " layers");
  }
  if (Status s = CheckInputSize(height, width); !s.ok()) return s;
  const TensorShape input{height, width, model.metadata().input.channels};
  auto shape_of = [&](int tensor) {
    return tensor == kModelInput ? input : out[static_cast<size_t>(tensor)].output;
  };
  for (size_t i = 0; i < layers.size(); ++i) {
    const TensorShape cur = shape_of(layers[i].inputs[0]);
    if (Status s = GeometryOfLayer(layers[i], i, height, width, cur, shape_of, out[i]); !s.ok()) {
      return s;
    }
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
  TensorShape cur{height, width, model.metadata().input.channels};
  // A chain's layers read only the previous one's output.
  auto no_other_inputs = [](int) { return TensorShape{}; };
  LayerGeometry g;
  for (size_t i = 0; i < layers.size(); ++i) {
    if (Status s = GeometryOfLayer(layers[i], i, height, width, cur, no_other_inputs, g); !s.ok()) {
      return s;
    }
    cur = g.output;
  }
  return cur;
}

Result<std::vector<LayerGeometry>> InferGeometry(const Model& model, int height, int width) {
  std::vector<LayerGeometry> geometry(model.layers().size());
  Status s = InferGeometry(model, height, width, geometry);
  if (!s.ok()) return s;
  return geometry;
}

}  // namespace sfrt
