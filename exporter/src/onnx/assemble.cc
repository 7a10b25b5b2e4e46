// The GraphOps the output needs, lowered to the ModelSpec (Importer::LoweringOf names the member
// for each kind), then the output checks and the padding and crop rules.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <set>
#include <string>
#include <vector>

#include "crop_rule.h"
#include "onnx/importer.h"

namespace sfrt::exporter::onnx_import {

// The needed ops: those the output depends on through runtime tensors (an op whose output only
// Shape or Size nodes read is not one).
std::vector<bool> Importer::NeededOps(const std::string& out_name) const {
  std::vector<bool> needed(ops_.size(), false);
  for (std::vector<std::string> stack{out_name}; !stack.empty();) {
    const std::string name = std::move(stack.back());
    stack.pop_back();
    if (name == input_name_) continue;
    const size_t i = producer_op_.at(name);
    if (needed[i]) continue;
    needed[i] = true;
    for (const std::string& in : ops_[i].inputs) stack.push_back(in);
  }
  return needed;
}

// torch.onnx.export names nodes by module path and op ("/conv0/Conv"): keep the module path,
// which is what the author called the layer ("conv0"); `prefix` and `counter` name a node without
// a name; a name taken gets a suffix.
std::string Importer::UniqueName(Assembly& a, const std::string& wanted, const std::string& prefix,
                                 int counter) {
  std::string readable = wanted;
  if (readable.size() > 1 && readable[0] == '/') {
    readable.erase(0, 1);
    const size_t last_slash = readable.rfind('/');
    if (last_slash != std::string::npos && last_slash > 0) readable.erase(last_slash);
  }
  std::string base = readable.empty() ? prefix + std::to_string(counter) : readable;
  std::string name = base;
  for (int k = 2; a.used_names.count(name) > 0; ++k) name = base + "_" + std::to_string(k);
  a.used_names.insert(name);
  return name;
}

void Importer::AddLayer(Assembly& a, LayerSpec layer, const std::string& output) {
  const std::string name = std::visit([](const auto& l) { return l.name; }, layer);
  a.source[output] = Source{name, static_cast<int>(a.spec.layers.size()), false, {}, {}, {}};
  a.spec.layers.push_back(std::move(layer));
}

std::vector<std::string> Importer::InputNames(const Assembly& a, const GraphOp& op) const {
  std::vector<std::string> names;
  for (const std::string& in : op.inputs) names.push_back(a.source.at(in).layer);
  return names;
}

// A Pad's output is folded into the Conv (or AveragePool, as torch.onnx.export writes an
// AvgPool2d that counts its pads) that reads it; nothing else may read it.
Status Importer::CheckPadReader(const Assembly& a, const GraphOp& op) const {
  // A Pad's output is folded into the Conv (or AveragePool, as torch.onnx.export writes an
  // AvgPool2d that counts its pads) that reads it; nothing else may read it.
  for (const std::string& in : op.inputs) {
    const Source& src = a.source.at(in);
    const bool average = op.kind == GraphOp::Kind::kPool && op.pool.kind == PoolKind::kAverage;
    if (src.padded && op.kind != GraphOp::Kind::kConv && op.kind != GraphOp::Kind::kPad &&
        !average) {
      return FileError(NodeLabel(src.pad_nodes.back()) +
                       ": a Pad must be followed by a Conv or an AveragePool (it is folded "
                       "into its padding), but it is followed by " +
                       NodeLabel(op.node_index));
    }
  }
  return Status::Ok();
}

// Identity: the tensor it reads.
Status Importer::LowerIdentity(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  a.source[op.output] = a.source.at(in0);
  return Status::Ok();
}

// Pad: amounts waiting for the Conv (or counting AveragePool) that reads its output.
Status Importer::LowerPad(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  Source padded = a.source.at(in0);
  if (!padded.padded) padded.pre_pad_shape = op.in_shape;
  padded.padded = true;
  padded.pads.top += op.pads.top;
  padded.pads.left += op.pads.left;
  padded.pads.bottom += op.pads.bottom;
  padded.pads.right += op.pads.right;
  padded.pad_nodes.push_back(op.node_index);
  a.source[op.output] = std::move(padded);
  return Status::Ok();
}

// Conv, with the Pads before it folded into its padding.
Status Importer::LowerConv(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  const Source& src = a.source.at(in0);
  ConvSpec conv = op.conv;
  const Shape4 traced_in = src.padded ? src.pre_pad_shape : op.in_shape;
  conv.pads.top += src.pads.top;
  conv.pads.left += src.pads.left;
  conv.pads.bottom += src.pads.bottom;
  conv.pads.right += src.pads.right;
  // A folded Pad's amounts are fixed: the sum holds at the traced size only.
  if (src.padded) conv.padding_rule = PaddingRule::kExplicit;
  SFRT_ONNX_RETURN_IF_ERROR(CheckConvPads(op.node_index, conv, src.pad_nodes));
  conv.name = UniqueName(a, conv.name, "conv", a.count.convs++);
  conv.inputs = {src.layer};
  a.convs.push_back({a.spec.layers.size(), op.node_index, traced_in[2], traced_in[3]});
  AddLayer(a, std::move(conv), op.output);
  return Status::Ok();
}

// MaxPool and AveragePool; an AveragePool counts the zeros of a Pad before it.
Status Importer::LowerPool(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  PoolSpec pool = op.pool;
  const Source& src = a.source.at(in0);
  if (src.padded) {
    // Zeros padded before an average: the pool's own pads, counted in the divisor. Its
    // size at the traced input must stay what the file computes after the Pad.
    if (pool.padding_rule != PaddingRule::kExplicit ||
        (pool.pads != Pads{} && !pool.count_include_pad)) {
      return FileError(NodeLabel(src.pad_nodes.back()) + ": a Pad before " +
                       NodeLabel(op.node_index) +
                       " folds into its pads only when it pads explicitly and counts them");
    }
    pool.pads.top += src.pads.top;
    pool.pads.left += src.pads.left;
    pool.pads.bottom += src.pads.bottom;
    pool.pads.right += src.pads.right;
    pool.count_include_pad = true;
    int before = 0, after = 0;
    const Shape4& pre = src.pre_pad_shape;
    const int extent_h = DilatedExtent(pool.kernel_h, pool.dilation_h);
    const int extent_w = DilatedExtent(pool.kernel_w, pool.dilation_w);
    const int oh =
        PoolOutputSize(static_cast<int>(pre[2]), extent_h, pool.stride_h, pool.padding_rule,
                       pool.pads.top, pool.pads.bottom, pool.ceil_mode, &before, &after);
    const int ow =
        PoolOutputSize(static_cast<int>(pre[3]), extent_w, pool.stride_w, pool.padding_rule,
                       pool.pads.left, pool.pads.right, pool.ceil_mode, &before, &after);
    const bool in_range = pool.pads.top < extent_h && pool.pads.bottom < extent_h &&
                          pool.pads.left < extent_w && pool.pads.right < extent_w;
    if (!in_range || oh != op.out_shape[2] || ow != op.out_shape[3]) {
      return FileError(NodeLabel(src.pad_nodes.back()) + ": the Pad before " +
                       NodeLabel(op.node_index) +
                       " cannot become the pool's own padding (pads below the window, the "
                       "same output size)");
    }
  }
  pool.name = UniqueName(a, pool.name, "pool", a.count.pools++);
  pool.inputs = {a.source.at(in0).layer};
  AddLayer(a, std::move(pool), op.output);
  return Status::Ok();
}

// ConvTranspose.
Status Importer::LowerConvTranspose(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  ConvTransposeSpec deconv = op.deconv;
  deconv.name = UniqueName(a, deconv.name, "deconv", a.count.deconvs++);
  deconv.inputs = {a.source.at(in0).layer};
  AddLayer(a, std::move(deconv), op.output);
  return Status::Ok();
}

// A scale and shift (BatchNormalization, Add/Sub/Mul/Div by a constant) folds into the Conv or
// ConvTranspose before it, or joins a ChannelAffine before it; an activation fuses into a Conv,
// ConvTranspose or Add (ReLU and LeakyReLU) or a ChannelAffine (any). The layer before must have
// no activation yet and be read by this node only (its output is then this node's). Otherwise the
// node becomes a ChannelAffine of its own (schema 1.7).
Status Importer::LowerScaleOrActivation(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  const bool scales = op.kind != GraphOp::Kind::kActivation;
  const Source& src = a.source.at(in0);
  const bool last_and_sole = src.layer_index >= 0 &&
                             src.layer_index == static_cast<int>(a.spec.layers.size()) - 1 &&
                             SoleReader(a, in0);
  LayerSpec* layer = last_and_sole ? &a.spec.layers[src.layer_index] : nullptr;
  auto* conv = layer != nullptr ? std::get_if<ConvSpec>(layer) : nullptr;
  auto* deconv = layer != nullptr ? std::get_if<ConvTransposeSpec>(layer) : nullptr;
  auto* add = layer != nullptr ? std::get_if<AddSpec>(layer) : nullptr;
  auto* affine = layer != nullptr ? std::get_if<ChannelAffineSpec>(layer) : nullptr;
  if (conv != nullptr && conv->activation != Activation::kNone) conv = nullptr;
  if (deconv != nullptr && deconv->activation != Activation::kNone) deconv = nullptr;
  if (add != nullptr && add->activation != Activation::kNone) add = nullptr;
  if (affine != nullptr && affine->activation != Activation::kNone) affine = nullptr;
  const bool fusable_activation =
      op.activation == Activation::kRelu || op.activation == Activation::kLeakyRelu;
  const float slope = op.activation == Activation::kLeakyRelu ? op.slope : 0.0f;
  auto activate = [&](ChannelAffineSpec& target) {
    target.activation = op.activation;
    target.leaky_slope = slope;
    target.elu_alpha = op.elu_alpha;
    target.clip_min = op.clip_min;
    target.clip_max = op.clip_max;
  };
  if (scales && conv != nullptr) {
    FoldIntoConv(op.batch_norm, conv);
  } else if (scales && deconv != nullptr) {
    FoldIntoConv(op.batch_norm, deconv);
  } else if (scales && affine != nullptr) {  // a * (x * s + t) + b
    for (size_t ch = 0; ch < affine->scale.size(); ++ch) {
      affine->scale[ch] *= op.batch_norm.scale[ch];
      affine->shift[ch] = affine->shift[ch] * op.batch_norm.scale[ch] + op.batch_norm.shift[ch];
    }
  } else if (!scales && fusable_activation && conv != nullptr) {
    conv->activation = op.activation;
    conv->leaky_slope = slope;
  } else if (!scales && fusable_activation && deconv != nullptr) {
    deconv->activation = op.activation;
    deconv->leaky_slope = slope;
  } else if (!scales && fusable_activation && add != nullptr) {
    add->activation = op.activation;
    add->leaky_slope = slope;
  } else if (!scales && affine != nullptr) {
    activate(*affine);
  } else {
    ChannelAffineSpec own;
    own.name = UniqueName(a, graph().node(op.node_index).name(), "affine", a.count.affines++);
    own.inputs = {src.layer};
    const size_t channels = static_cast<size_t>(op.in_shape[1]);
    own.scale = scales ? op.batch_norm.scale : std::vector<float>(channels, 1.0f);
    own.shift = scales ? op.batch_norm.shift : std::vector<float>(channels, 0.0f);
    if (!scales) activate(own);
    AddLayer(a, std::move(own), op.output);
    return Status::Ok();
  }
  a.source[op.output] = a.source.at(in0);
  return Status::Ok();
}

// Resize that is not nearest upsampling by integers.
Status Importer::LowerResize(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  ResizeSpec resize;
  resize.name = UniqueName(a, graph().node(op.node_index).name(), "resize", a.count.ups++);
  resize.params = op.resize;
  resize.inputs = {a.source.at(in0).layer};
  AddLayer(a, std::move(resize), op.output);
  return Status::Ok();
}

// Nearest upsampling by integer factors.
Status Importer::LowerUpsample(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  UpsampleSpec up;
  up.name = UniqueName(a, graph().node(op.node_index).name(), "up", a.count.ups++);
  up.factor_h = op.factor_h;
  up.factor_w = op.factor_w;
  up.inputs = {a.source.at(in0).layer};
  AddLayer(a, std::move(up), op.output);
  return Status::Ok();
}

// Slice: a crop; consecutive Slices merge into one.
Status Importer::LowerSlice(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  const Source& src = a.source.at(in0);
  const bool merge = !a.crops.empty() && a.crops.back().output == in0 && SoleReader(a, in0);
  if (merge) {  // consecutive slices become one crop
    auto& crop = std::get<CropSpec>(a.spec.layers[a.crops.back().layer]);
    crop.amounts.top += op.pads.top;
    crop.amounts.left += op.pads.left;
    crop.amounts.bottom += op.pads.bottom;
    crop.amounts.right += op.pads.right;
    a.crops.back().output = op.output;
    a.crops.back().out_h = op.out_shape[2];
    a.crops.back().out_w = op.out_shape[3];
    a.source[op.output] = src;
  } else {
    CropSpec crop;
    crop.name = UniqueName(a, graph().node(op.node_index).name(), "crop", a.count.crops++);
    crop.amounts = op.pads;
    crop.inputs = {src.layer};
    a.crops.push_back({a.spec.layers.size(), op.output, op.out_shape[2], op.out_shape[3]});
    AddLayer(a, std::move(crop), op.output);
  }
  return Status::Ok();
}

// Concat of channels.
Status Importer::LowerConcat(Assembly& a, const GraphOp& op) {
  ConcatSpec cat;
  cat.name = UniqueName(a, graph().node(op.node_index).name(), "concat", a.count.cats++);
  cat.inputs = InputNames(a, op);
  AddLayer(a, std::move(cat), op.output);
  return Status::Ok();
}

// Add of two runtime tensors.
Status Importer::LowerAdd(Assembly& a, const GraphOp& op) {
  AddSpec add;
  add.name = UniqueName(a, graph().node(op.node_index).name(), "add", a.count.adds++);
  add.inputs = InputNames(a, op);
  AddLayer(a, std::move(add), op.output);
  return Status::Ok();
}

// Each GraphOp kind is lowered to the spec by one member, indexed by GraphOp::Kind.
Importer::Lowering Importer::LoweringOf(GraphOp::Kind kind) {
  using K = GraphOp::Kind;
  static constexpr std::array<std::pair<K, Lowering>, 13> kLowerings = {{
      {K::kIdentity, &Importer::LowerIdentity},
      {K::kPad, &Importer::LowerPad},
      {K::kConv, &Importer::LowerConv},
      {K::kPool, &Importer::LowerPool},
      {K::kConvTranspose, &Importer::LowerConvTranspose},
      {K::kBatchNorm, &Importer::LowerScaleOrActivation},
      {K::kAffine, &Importer::LowerScaleOrActivation},
      {K::kActivation, &Importer::LowerScaleOrActivation},
      {K::kResize, &Importer::LowerResize},
      {K::kUpsample, &Importer::LowerUpsample},
      {K::kSlice, &Importer::LowerSlice},
      {K::kConcat, &Importer::LowerConcat},
      {K::kAdd, &Importer::LowerAdd},
  }};
  for (const auto& [k, lowering] : kLowerings) {
    if (k == kind) return lowering;
  }
  return nullptr;
}

// The output is the last layer, and the layer count within the loader's limit.
Status Importer::CheckAssembledOutput(const Assembly& a, const std::string& out_name) const {
  if (const Source& out = a.source.at(out_name); out.padded) {
    return FileError(NodeLabel(out.pad_nodes.back()) +
                     ": a Pad must be followed by a Conv (it is folded into the Conv's "
                     "padding), but it ends the graph");
  }
  if (a.spec.layers.empty()) return FileError("graph has no layers between input and output");
  if (a.spec.layers.size() > static_cast<size_t>(model_limits::kMaxLayers)) {
    return FileError("graph gives " + std::to_string(a.spec.layers.size()) + " layers; at most " +
                     std::to_string(model_limits::kMaxLayers) + " are supported");
  }
  // The graph output may be a fused layer's tensor that an earlier layer computes (an Identity
  // or activation of it); the spec's output is its last layer.
  if (a.source.at(out_name).layer_index != static_cast<int>(a.spec.layers.size()) - 1) {
    return FileError("graph output " + Quote(out_name) + " is computed by layer " +
                     Quote(a.source.at(out_name).layer) +
                     ", which is not the last: the network's output must be its last layer");
  }
  return Status::Ok();
}

// Padding rule: SAME_UPPER for every Conv when each one's traced pads are its SAME_UPPER amounts
// (--padding auto), else explicit.
Status Importer::ChoosePaddingRules(Assembly& a) const {
  bool all_same_upper = true;
  for (const ConvTrace& t : a.convs) {
    auto& conv = std::get<ConvSpec>(a.spec.layers[t.layer]);
    const Pads same =
        SameUpperPads(t.in_h, t.in_w, DilatedExtent(conv.kernel_h, conv.dilation_h),
                      DilatedExtent(conv.kernel_w, conv.dilation_w), conv.stride_h, conv.stride_w);
    if (conv.pads == same) continue;
    // A SAME_LOWER conv keeps its rule (kAuto) whatever the others do.
    if (conv.padding_rule == PaddingRule::kSameLower &&
        options_.padding == PaddingDetection::kAuto) {
      continue;
    }
    all_same_upper = false;
    if (options_.padding == PaddingDetection::kSameUpper) {
      return FileError("conv " + Quote(conv.name) + ": traced pads " + PadsText(conv.pads) +
                       " at input " + std::to_string(t.in_h) + "x" + std::to_string(t.in_w) +
                       " differ from the SAME_UPPER pads " + PadsText(same) +
                       "; cannot force padding rule SameUpper");
    }
  }
  const bool same_upper = options_.padding == PaddingDetection::kSameUpper ||
                          (options_.padding == PaddingDetection::kAuto && all_same_upper);
  for (const ConvTrace& t : a.convs) {
    auto& conv = std::get<ConvSpec>(a.spec.layers[t.layer]);
    if (conv.padding_rule == PaddingRule::kSameLower &&
        options_.padding == PaddingDetection::kAuto) {
      continue;
    }
    conv.padding_rule = same_upper ? PaddingRule::kSameUpper : PaddingRule::kExplicit;
  }
  return Status::Ok();
}

void Importer::ChooseCropRules(Assembly& a) const {
  // Crop rules (crop_rule.h): the skip a crop's only reader, a Concat, also reads at the crop's
  // size decides a crop to that layer's size.
  for (const CropTrace& t : a.crops) {
    auto& crop = std::get<CropSpec>(a.spec.layers[t.layer]);
    TracedCrop traced{static_cast<int>(t.out_h), static_cast<int>(t.out_w), ""};
    const auto& crop_readers = a.readers[t.output];
    if (crop_readers.size() == 1 && ops_[crop_readers[0]].kind == GraphOp::Kind::kConcat) {
      for (const std::string& in : ops_[crop_readers[0]].inputs) {
        const Source& other = a.source.at(in);
        const Shape4& shape = runtime_.at(in);
        if (in == t.output || other.padded || other.layer_index >= static_cast<int>(t.layer) ||
            shape[2] != t.out_h || shape[3] != t.out_w) {
          continue;
        }
        traced.skip = other.layer;
        break;
      }
    }
    ChooseCropRule(crop, traced, static_cast<int>(input_shape_[2]),
                   static_cast<int>(input_shape_[3]));
  }
}

Result<ModelSpec> Importer::Assemble() {
  const std::string& out_name = graph().output(output_index_).name();
  if (runtime_.count(out_name) == 0) {
    return FileError("graph output " + Quote(out_name) +
                     (IsConst(out_name) ? " is a constant: it does not depend on the input"
                                        : " is not produced by any node"));
  }
  const std::vector<bool> needed = NeededOps(out_name);
  SFRT_ONNX_RETURN_IF_ERROR(CheckIntegerGraph(needed));
  Assembly a;
  // The needed ops that read each runtime tensor (a Concat reading it twice counts once).
  for (size_t i = 0; i < ops_.size(); ++i) {
    if (!needed[i]) continue;
    for (const std::string& in : ops_[i].inputs) {
      auto& list = a.readers[in];
      if (list.empty() || list.back() != i) list.push_back(i);
    }
  }
  // The input's name is one a layer may read: no layer may take it.
  a.used_names.insert(input_name_);
  a.source[input_name_] = Source{input_name_, -1, false, {}, {}, {}};
  // The layers, in file order, which ONNX makes topological.
  for (size_t i = 0; i < ops_.size(); ++i) {
    if (!needed[i]) continue;
    SFRT_ONNX_RETURN_IF_ERROR(CheckPadReader(a, ops_[i]));
    SFRT_ONNX_RETURN_IF_ERROR((this->*LoweringOf(ops_[i].kind))(a, ops_[i]));
  }
  SFRT_ONNX_RETURN_IF_ERROR(CheckAssembledOutput(a, out_name));
  SFRT_ONNX_RETURN_IF_ERROR(ChoosePaddingRules(a));
  ChooseCropRules(a);

  const Shape4& out_shape = runtime_.at(out_name);
  a.spec.input.channels = static_cast<int>(input_shape_[1]);
  // The default image order (four RGB images) only fits 12 channels; for any other count the file
  // does not say which images the channels hold, so the spec names none (as the loader accepts).
  if (a.spec.input.channels != 3 * static_cast<int>(a.spec.input.image_order.size())) {
    a.spec.input.image_order.clear();
  }
  a.spec.input.traced_height = static_cast<int>(input_shape_[2]);
  a.spec.input.traced_width = static_cast<int>(input_shape_[3]);
  SetOutputChannels(a.spec, static_cast<int>(out_shape[1]));
  KeepInputNamesOfAGraph(a.spec, input_name_);
  return std::move(a.spec);
}

}  // namespace sfrt::exporter::onnx_import
