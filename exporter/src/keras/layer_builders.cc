// Building the ModelSpec from the Keras layers: one member per layer class (Importer::BuilderOf
// finds it by class name), the fusions into the layer before (BatchNormalization, activations),
// ZeroPadding2D folded into the convolution after it, and the crop rules (crop_rule.h).
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <tuple>
#include <vector>

#include "crop_rule.h"
#include "keras/importer.h"

namespace sfrt::exporter::keras_import {

Result<ResizeCoordinates> Importer::BilinearGrid(const ChainLayer& l) {
  switch (options_.bilinear_grid) {
    case KerasBilinearGrid::kHalfPixel:
      return ResizeCoordinates::kHalfPixel;
    case KerasBilinearGrid::kAsymmetric:
      return ResizeCoordinates::kAsymmetric;
    case KerasBilinearGrid::kFromKerasVersion:
      break;
  }
  if (SavedOnTensorFlow2(keras_version_)) {
    notes_.push_back("bilinear UpSampling2D " + Quote(l.name) +
                     " samples on TensorFlow 2's half-pixel grid (the file was saved by Keras " +
                     Printable(keras_version_) + ")");
    return ResizeCoordinates::kHalfPixel;
  }
  return LayerFail(l,
                   "bilinear interpolation samples on a grid that depends on the TensorFlow "
                   "the model ran on, which a file saved by Keras " +
                       Printable(keras_version_.empty() ? "(no version)" : keras_version_) +
                       " does not record: TensorFlow 2 uses half-pixel centres, TensorFlow 1 "
                       "the asymmetric grid (align_corners=False); say which with "
                       "KerasImportOptions::bilinear_grid (sfrt export --keras-bilinear "
                       "half-pixel or asymmetric)");
}

Result<std::string> Importer::SameOrValid(const ChainLayer& l) const {
  const json* p = Find(*l.config, "padding");
  if (p == nullptr) return std::string("valid");
  if (!p->is_string()) return LayerFail(l, "padding " + JsonText(*p) + " is not a string");
  std::string padding = p->get<std::string>();
  if (padding != "same" && padding != "valid") {
    return LayerFail(l, "padding " + Quote(padding) + " is not supported (same, valid)");
  }
  return padding;
}

// Keras' Conv2DTranspose is TensorFlow's conv2d_transpose: input pixel i scatters kernel tap k
// to output row i * stride + k * dilation - top, kernel (kh, kw, filters, in). Its output length
// L (Keras' deconv_output_length, with the dilated extent e = (k - 1) * d + 1) is in * stride
// (+ max(e - stride, 0) for 'valid') without output_padding, else (in - 1) * stride + e -
// 2 * pad + output_padding with pad = e / 2 for 'same' and 0 for 'valid'. TensorFlow places
// it like the forward convolution of an L-long input: 'valid' crops nothing at the top, 'same'
// crops top = total / 2 of total = max((in - 1) * stride + e - L, 0). The full output
// ((in - 1) * stride + e rows) then loses `top` rows at the top and what exceeds L at the
// bottom, or gains zero rows (bias only) there up to L. Neither amount depends on `in`.
Result<ConvTransposeSpec> Importer::ReadConvTranspose(const ChainLayer& l, int in_channels) {
  ConvTransposeSpec d;
  d.name = l.name;
  d.in_channels = in_channels;
  if (Status s = ReadConvTransposeShape(l, &d); !s.ok()) return s;
  if (Status s = ReadConvTransposeWeights(l, &d); !s.ok()) return s;
  return d;
}

namespace {

// Per axis of a Conv2DTranspose: the rows cropped at the top and bottom and added at the bottom,
// from the output length at an input of one pixel (the amounts are the same at every length).
struct Placement {
  int top = 0, bottom = 0, added = 0;
};

Placement PlaceTransposed(int k, int s, int dil, bool same, bool has_output_padding, int out_pad) {
  const int e = DilatedExtent(k, dil);
  const int length = !has_output_padding ? s + (same ? 0 : std::max(e - s, 0))
                                         : e - 2 * (same ? e / 2 : 0) + out_pad;
  Placement p;
  p.top = same ? std::max(e - length, 0) / 2 : 0;
  const int rest = e - p.top;  // full rows after the top crop
  p.bottom = std::max(rest - length, 0);
  p.added = std::max(length - rest, 0);
  return p;
}

}  // namespace

// Filters, kernel, strides, dilation and the placement of a Conv2DTranspose's output.
Status Importer::ReadConvTransposeShape(const ChainLayer& l, ConvTransposeSpec* out) {
  const json& cfg = *l.config;
  ConvTransposeSpec& d = *out;
  if (!GetInt(Find(cfg, "filters"), 1, model_limits::kMaxChannels, &d.out_channels)) {
    return LayerFail(l, "'filters' is missing or not an integer in 1.." +
                            std::to_string(model_limits::kMaxChannels));
  }
  std::array<int, 2> kernel{};
  if (!GetPair(Find(cfg, "kernel_size"), 1, model_limits::kMaxKernel, &kernel)) {
    return LayerFail(l, "'kernel_size' is missing or not integers in 1.." +
                            std::to_string(model_limits::kMaxKernel));
  }
  std::array<int, 2> strides{1, 1};
  if (const json* st = Find(cfg, "strides");
      st != nullptr && !GetPair(st, 1, model_limits::kMaxStride, &strides)) {
    return LayerFail(l, "strides " + JsonText(*st) + " are not integers in 1.." +
                            std::to_string(model_limits::kMaxStride));
  }
  std::array<int, 2> dilation{1, 1};
  if (const json* dr = Find(cfg, "dilation_rate");
      dr != nullptr && !GetPair(dr, 1, model_limits::kMaxDilation, &dilation)) {
    return LayerFail(l, "dilation_rate " + JsonText(*dr) + " is not integers in 1.." +
                            std::to_string(model_limits::kMaxDilation));
  }
  Result<std::string> padding = SameOrValid(l);
  if (!padding.ok()) return padding.status();
  const json* op = Find(cfg, "output_padding");
  std::array<int, 2> output_padding{};
  const bool has_output_padding = op != nullptr && !op->is_null();
  if (has_output_padding && !GetPair(op, 0, model_limits::kMaxStride, &output_padding)) {
    return LayerFail(l, "output_padding " + JsonText(*op) + " is not integers >= 0");
  }
  d.kernel_h = kernel[0];
  d.kernel_w = kernel[1];
  d.stride_h = strides[0];
  d.stride_w = strides[1];
  d.dilation_h = dilation[0];
  d.dilation_w = dilation[1];
  const bool same = *padding == "same";
  const Placement ph = PlaceTransposed(d.kernel_h, d.stride_h, d.dilation_h, same,
                                       has_output_padding, output_padding[0]);
  const Placement pw = PlaceTransposed(d.kernel_w, d.stride_w, d.dilation_w, same,
                                       has_output_padding, output_padding[1]);
  if (ph.added >= d.stride_h || pw.added >= d.stride_w) {
    return LayerFail(l, "its output gains " + std::to_string(std::max(ph.added, pw.added)) +
                            " zero rows or columns beyond the kernel's reach; the model format "
                            "takes fewer than the stride");
  }
  d.pads = Pads{ph.top, pw.top, ph.bottom, pw.bottom};
  d.output_padding_h = ph.added;
  d.output_padding_w = pw.added;
  return Status::Ok();
}

// A Conv2DTranspose's activation, kernel (as HWIO) and bias.
Status Importer::ReadConvTransposeWeights(const ChainLayer& l, ConvTransposeSpec* out) {
  const json& cfg = *l.config;
  ConvTransposeSpec& d = *out;
  bool use_bias = true;
  if (const json* b = Find(cfg, "use_bias")) {
    if (!b->is_boolean()) return LayerFail(l, "use_bias " + JsonText(*b) + " is not a bool");
    use_bias = b->get<bool>();
  }
  std::string activation = "linear";
  if (const json* a = Find(cfg, "activation")) {
    activation = a->is_string() ? a->get<std::string>() : JsonText(*a);
  }
  if (activation != "linear" && activation != "relu") {
    return LayerFail(l, "activation " + Quote(activation) + " is not supported (linear, relu)");
  }
  d.activation = activation == "relu" ? Activation::kRelu : Activation::kNone;
  Result<std::vector<std::string>> paths = WeightPaths(l, use_bias ? 2 : 1);
  if (!paths.ok()) return paths.status();
  const auto kh = static_cast<size_t>(d.kernel_h), kw = static_cast<size_t>(d.kernel_w);
  const auto ci = static_cast<size_t>(d.in_channels), co = static_cast<size_t>(d.out_channels);
  auto kernel_values =
      ReadDataset(l, (*paths)[0], {kh, kw, co, ci},
                  "(kernel_size " + std::to_string(kh) + "x" + std::to_string(kw) + ", filters " +
                      std::to_string(co) + ", " + std::to_string(ci) + " input channels)");
  if (!kernel_values.ok()) return kernel_values.status();
  // (kh, kw, out, in) -> HWIO (kh, kw, in, out).
  d.weights_hwio.resize(kernel_values->size());
  for (size_t t = 0; t < kh * kw; ++t) {
    for (size_t o = 0; o < co; ++o) {
      for (size_t i = 0; i < ci; ++i) {
        d.weights_hwio[(t * ci + i) * co + o] = (*kernel_values)[(t * co + o) * ci + i];
      }
    }
  }
  if (use_bias) {
    auto bias = ReadDataset(l, (*paths)[1], {co}, "(filters " + std::to_string(co) + ")");
    if (!bias.ok()) return bias.status();
    d.bias = std::move(bias).value();
  } else {
    d.bias.assign(co, 0.0f);
  }
  return Status::Ok();
}

// Every layer a layer reads is computed before it, and a ZeroPadding2D is read only by the
// convolution it folds into (or another ZeroPadding2D).
Status Importer::CheckInbound(const BuildState& s, const ChainLayer& l) const {
  for (const std::string& name : l.inbound) {
    const auto found = s.tensors.find(name);
    if (found == s.tensors.end()) {
      return LayerFail(l, "reads layer " + Quote(name) + ", which is not computed before it");
    }
    const Tensor& t = found->second;
    if (t.pad_layer != nullptr && l.cls != "Conv2D" && l.cls != "DepthwiseConv2D" &&
        l.cls != "ZeroPadding2D") {
      return LayerFail(*t.pad_layer,
                       "must be followed by a Conv2D with padding 'valid' (it is "
                       "folded into the convolution), but is followed by layer " +
                           Quote(l.name) + " (" + Printable(l.cls) + ")");
    }
  }
  return Status::Ok();
}

Status Importer::OneInput(const LayerBuild& b, const char* what) const {
  if (b.l.inbound.size() == 1) return Status::Ok();
  return LayerFail(
      b.l, "reads " + std::to_string(b.l.inbound.size()) + " tensors; " + what + " reads one");
}

void Importer::AddLayer(LayerBuild& b, LayerSpec layer) {
  b.s.tensors[b.l.name] =
      Tensor{b.h, b.w, b.c, b.l.name, static_cast<int>(b.s.spec->layers.size()), {}, nullptr};
  b.s.spec->layers.push_back(std::move(layer));
}

LayerSpec* Importer::FusionTarget(LayerBuild& b, bool add_too) {
  const Tensor& in = b.in;
  if (in.index < 0 || in.pad_layer != nullptr || b.s.readers[b.l.inbound[0]].size() != 1) {
    return nullptr;
  }
  LayerSpec* target = &b.s.spec->layers[static_cast<size_t>(in.index)];
  if (const auto* conv = std::get_if<ConvSpec>(target)) {
    return conv->activation == Activation::kNone ? target : nullptr;
  }
  if (const auto* deconv = std::get_if<ConvTransposeSpec>(target)) {
    return deconv->activation == Activation::kNone ? target : nullptr;
  }
  if (const auto* add = std::get_if<AddSpec>(target); add != nullptr && add_too) {
    return add->activation == Activation::kNone ? target : nullptr;
  }
  return nullptr;
}

Status Importer::FusionRefused(LayerBuild& b, const std::string& what) {
  std::string also;
  for (const ChainLayer* r : b.s.readers[b.l.inbound[0]]) {
    if (r != &b.l) also += (also.empty() ? "" : ", ") + Quote(r->name);
  }
  return LayerFail(b.l, what + (also.empty() ? "" : "; its input is also read by layer " + also));
}

Importer::LayerBuilder Importer::BuilderOf(std::string_view cls) {
  static constexpr std::pair<std::string_view, LayerBuilder> kBuilders[] = {
      {"Conv2D", &Importer::BuildConvolution},
      {"DepthwiseConv2D", &Importer::BuildConvolution},
      {"BatchNormalization", &Importer::BuildBatchNormalization},
      {"LeakyReLU", &Importer::BuildLeakyRelu},
      {"Activation", &Importer::BuildActivation},
      {"Conv2DTranspose", &Importer::BuildConvTranspose},
      {"MaxPooling2D", &Importer::BuildPooling},
      {"AveragePooling2D", &Importer::BuildPooling},
      {"UpSampling2D", &Importer::BuildUpSampling},
      {"Cropping2D", &Importer::BuildCropping},
      {"ZeroPadding2D", &Importer::BuildZeroPadding},
      {"Concatenate", &Importer::BuildMerge},
      {"Add", &Importer::BuildMerge},
  };
  for (const auto& [name, builder] : kBuilders) {
    if (name == cls) return builder;
  }
  return nullptr;
}

// Conv2D and DepthwiseConv2D.
// A Conv2D's or DepthwiseConv2D's configuration: filters (or depth_multiplier), kernel size,
// strides, dilation, groups, bias and activation, into `conv`.
Status Importer::ReadConvConfig(const LayerBuild& b, bool depthwise, ConvSpec* conv,
                                bool* use_bias) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const int c = b.c;
  auto field = [&](const char* key) { return Find(cfg, key); };
  int filters_value = 0;
  std::array<int, 2> kernel_value{};
  int groups = 1;
  if (depthwise) {
    int multiplier = 1;
    if (const json* m = field("depth_multiplier");
        m != nullptr && !GetInt(m, 1, model_limits::kMaxChannels / c, &multiplier)) {
      return LayerFail(l, "depth_multiplier " + JsonText(*m) + " is not an integer in 1.." +
                              std::to_string(model_limits::kMaxChannels / c));
    }
    filters_value = c * multiplier;
    groups = c;
  } else if (!GetInt(field("filters"), 1, model_limits::kMaxChannels, &filters_value)) {
    return LayerFail(l, "'filters' is missing or not an integer in 1.." +
                            std::to_string(model_limits::kMaxChannels));
  }
  if (!GetPair(field("kernel_size"), 1, model_limits::kMaxKernel, &kernel_value)) {
    return LayerFail(l, "'kernel_size' is missing or not integers in 1.." +
                            std::to_string(model_limits::kMaxKernel));
  }
  const int* filters = &filters_value;
  const std::array<int, 2>* kernel = &kernel_value;
  std::array<int, 2> strides{1, 1};
  if (const json* s = field("strides")) {
    if (!GetPair(s, 1, model_limits::kMaxStride, &strides)) {
      return LayerFail(l, "strides " + JsonText(*s) + " are not integers in 1.." +
                              std::to_string(model_limits::kMaxStride));
    }
  }
  std::array<int, 2> dilation{1, 1};
  if (const json* d = field("dilation_rate")) {
    if (!GetPair(d, 1, model_limits::kMaxDilation, &dilation)) {
      return LayerFail(l, "dilation_rate " + JsonText(*d) + " is not integers in 1.." +
                              std::to_string(model_limits::kMaxDilation));
    }
  }
  if (const json* g = field("groups"); g != nullptr && !depthwise) {
    if (!GetInt(g, 1, c, &groups) || c % groups != 0 || filters_value % groups != 0) {
      return LayerFail(l, "groups " + JsonText(*g) + " does not divide its " + std::to_string(c) +
                              " input channels and " + std::to_string(filters_value) + " filters");
    }
  }
  *use_bias = true;
  if (const json* flag = field("use_bias")) {
    if (!flag->is_boolean()) return LayerFail(l, "use_bias " + JsonText(*flag) + " is not a bool");
    *use_bias = flag->get<bool>();
  }
  std::string activation = "linear";
  if (const json* a = field("activation")) {
    if (!a->is_string()) {
      return LayerFail(l, "activation " + JsonText(*a) + " is not supported (linear, relu)");
    }
    activation = a->get<std::string>();
  }
  if (activation != "linear" && activation != "relu") {
    return LayerFail(l, "activation " + Quote(activation) + " is not supported (linear, relu)");
  }

  conv->name = l.name;
  conv->in_channels = c;
  conv->out_channels = *filters;
  conv->kernel_h = (*kernel)[0];
  conv->kernel_w = (*kernel)[1];
  conv->stride_h = strides[0];
  conv->stride_w = strides[1];
  conv->dilation_h = dilation[0];
  conv->dilation_w = dilation[1];
  conv->groups = groups;
  conv->activation = activation == "relu" ? Activation::kRelu : Activation::kNone;
  return Status::Ok();
}

// The convolution's padding: 'same' as the same-upper rule, 'valid' taking the ZeroPadding2D
// before it; then the output size, where the input size is known.
Status Importer::PadConvolution(LayerBuild& b, ConvSpec* conv) {
  const ChainLayer& l = b.l;
  int& h = b.h;
  int& w = b.w;
  Pads& pending = b.pending;
  const ChainLayer*& pending_pad = b.pending_pad;
  Result<std::string> padding_value = SameOrValid(l);
  if (!padding_value.ok()) return padding_value.status();
  const std::string& padding = *padding_value;
  // The window's rows and columns (the kernel's dilated extent).
  const int extent_h = DilatedExtent(conv->kernel_h, conv->dilation_h);
  const int extent_w = DilatedExtent(conv->kernel_w, conv->dilation_w);
  if (padding == "same") {
    if (pending_pad != nullptr) {
      return LayerFail(l, "follows ZeroPadding2D " + Quote(pending_pad->name) +
                              " but pads 'same'; only padding 'valid' can absorb it");
    }
    conv->padding_rule = PaddingRule::kSameUpper;
    if (b.s.known) {
      const auto [top, bottom] = SameAxis(h, conv->stride_h, extent_h);
      const auto [left, right] = SameAxis(w, conv->stride_w, extent_w);
      conv->pads = Pads{top, left, bottom, right};
    }
  } else {
    conv->padding_rule = PaddingRule::kExplicit;
    conv->pads = pending;
    // The model format takes explicit pads of at most kernel - 1 per side (as the loader).
    for (const auto& [amount, side, size] : {std::tuple{conv->pads.top, "top", extent_h},
                                             std::tuple{conv->pads.bottom, "bottom", extent_h},
                                             std::tuple{conv->pads.left, "left", extent_w},
                                             std::tuple{conv->pads.right, "right", extent_w}}) {
      if (amount > model_limits::MaxPad(size)) {
        return LayerFail(
            l, "follows ZeroPadding2D " + Quote(pending_pad != nullptr ? pending_pad->name : "") +
                   " whose padding gives it " + std::to_string(amount) + " on the " + side +
                   "; a " + std::to_string(conv->kernel_h) + "x" + std::to_string(conv->kernel_w) +
                   " kernel takes at most " + std::to_string(model_limits::MaxPad(size)));
      }
    }
  }
  pending = Pads{};
  pending_pad = nullptr;
  if (b.s.known) {
    const int ph = h + conv->pads.top + conv->pads.bottom;
    const int pw = w + conv->pads.left + conv->pads.right;
    if (ph < extent_h || pw < extent_w) {
      return LayerFail(l, "its " + std::to_string(ph) + "x" + std::to_string(pw) +
                              " input at the built size is smaller than the kernel");
    }
    h = (ph - extent_h) / conv->stride_h + 1;
    w = (pw - extent_w) / conv->stride_w + 1;
  }
  return Status::Ok();
}

// The convolution's kernel (and bias) from the file, checked against its configuration.
Status Importer::ReadConvWeights(const LayerBuild& b, bool depthwise, bool use_bias,
                                 ConvSpec* conv) {
  const ChainLayer& l = b.l;
  const int c = b.c;
  const int groups = conv->groups;
  Result<std::vector<std::string>> paths = WeightPaths(l, use_bias ? 2 : 1);
  if (!paths.ok()) return paths.status();
  const std::string meaning =
      "(kernel_size " + std::to_string(conv->kernel_h) + "x" + std::to_string(conv->kernel_w) +
      ", " + std::to_string(c) + " input channels, " +
      (depthwise ? "depth_multiplier " + std::to_string(conv->out_channels / c)
                 : "filters " + std::to_string(conv->out_channels) +
                       (groups > 1 ? ", groups " + std::to_string(groups) : "")) +
      ")";
  // Conv2D: (kh, kw, in / groups, filters); DepthwiseConv2D: (kh, kw, in, multiplier).
  const uint64_t third = depthwise ? static_cast<uint64_t>(c) : static_cast<uint64_t>(c / groups);
  const uint64_t fourth = depthwise ? static_cast<uint64_t>(conv->out_channels / c)
                                    : static_cast<uint64_t>(conv->out_channels);
  auto kernel_values = ReadDataset(
      l, (*paths)[0],
      {static_cast<uint64_t>(conv->kernel_h), static_cast<uint64_t>(conv->kernel_w), third, fourth},
      meaning);
  if (!kernel_values.ok()) return kernel_values.status();
  conv->weights_hwio = std::move(kernel_values).value();
  if (use_bias) {
    auto bias = ReadDataset(l, (*paths)[1], {static_cast<uint64_t>(conv->out_channels)},
                            "(filters " + std::to_string(conv->out_channels) + ")");
    if (!bias.ok()) return bias.status();
    conv->bias = std::move(bias).value();
  } else {
    conv->bias.assign(static_cast<size_t>(conv->out_channels), 0.0f);
  }
  return Status::Ok();
}

Status Importer::BuildConvolution(LayerBuild& b) {
  const ChainLayer& l = b.l;
  // DepthwiseConv2D: depth_multiplier outputs per input channel, kernel (kh, kw, in,
  // multiplier), which is HWIO with one input per group (output c * multiplier + m).
  const bool depthwise = l.cls == "DepthwiseConv2D";
  if (Status s = OneInput(b, depthwise ? "a DepthwiseConv2D" : "a Conv2D"); !s.ok()) return s;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  ConvSpec conv;
  bool use_bias = true;
  if (Status s = ReadConvConfig(b, depthwise, &conv, &use_bias); !s.ok()) return s;
  if (Status s = PadConvolution(b, &conv); !s.ok()) return s;
  if (Status s = ReadConvWeights(b, depthwise, use_bias, &conv); !s.ok()) return s;
  b.c = conv.out_channels;
  conv.inputs = {b.in.layer};
  ++b.s.convs;
  AddLayer(b, std::move(conv));
  return Status::Ok();
}

// Inference normalisation with the moving statistics, folded into the convolution before it.
Status Importer::BuildBatchNormalization(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& c = b.c;
  // Inference normalisation with the moving statistics, folded into the Conv2D before it:
  // weights * gamma / sqrt(var + epsilon) per output channel, bias shifted.
  if (Status s = OneInput(b, "a BatchNormalization"); !s.ok()) return s;
  LayerSpec* target = FusionTarget(b, false);
  if (target == nullptr) {
    return FusionRefused(
        b,
        "must directly follow a Conv2D, DepthwiseConv2D or Conv2DTranspose with activation "
        "'linear' (it is folded into the convolution's weights and bias)");
  }
  const json* axis = Find(cfg, "axis");
  const json* axis_value =
      axis != nullptr && axis->is_array() && axis->size() == 1 ? &(*axis)[0] : axis;
  if (axis_value != nullptr &&
      !(axis_value->is_number_integer() &&
        (axis_value->get<int64_t>() == -1 || axis_value->get<int64_t>() == 3))) {
    return LayerFail(
        l, "axis " + JsonText(*axis) + " is not supported (only the channels axis, -1 or 3)");
  }
  auto flag = [&](const char* key) {
    const json* v = Find(cfg, key);
    return v == nullptr || !v->is_boolean() || v->get<bool>();
  };
  const bool scale = flag("scale"), center = flag("center");
  const json* eps = Find(cfg, "epsilon");
  const double epsilon = eps != nullptr && eps->is_number() ? eps->get<double>() : 1e-3;
  if (!(epsilon >= 0) || !std::isfinite(epsilon)) {
    return LayerFail(l, "epsilon " + JsonText(*eps) + " is not a finite number >= 0");
  }
  const size_t count = (scale ? 1 : 0) + (center ? 1 : 0) + 2;
  Result<std::vector<std::string>> paths = WeightPaths(l, count);
  if (!paths.ok()) return paths.status();
  std::vector<float> values[4];  // gamma, beta, moving_mean, moving_variance
  static const char* const kNames[4] = {"gamma", "beta", "moving_mean", "moving_variance"};
  size_t next = 0;
  for (int k = 0; k < 4; ++k) {
    if ((k == 0 && !scale) || (k == 1 && !center)) {
      values[k].assign(static_cast<size_t>(c), k == 0 ? 1.0f : 0.0f);
      return Status::Ok();
    }
    auto v = ReadDataset(l, (*paths)[next++], {static_cast<uint64_t>(c)},
                         std::string("(") + kNames[k] + ", " + std::to_string(c) + " channels)");
    if (!v.ok()) return v.status();
    values[k] = std::move(v).value();
  }
  ChannelAffine affine;
  const long bad = BatchNormAffine(values[0], values[1], values[2], values[3], epsilon, &affine);
  if (bad >= 0) {
    return LayerFail(
        l, "channel " + std::to_string(bad) + ": moving_variance + epsilon = " +
               std::to_string(static_cast<double>(values[3][static_cast<size_t>(bad)]) + epsilon) +
               " is not positive");
  }
  if (auto* conv = std::get_if<ConvSpec>(target)) {
    FoldIntoConv(affine, conv);
  } else {
    FoldIntoConv(affine, &std::get<ConvTransposeSpec>(*target));
  }
  b.s.tensors[l.name] = in;  // an activation may still follow and fuse
  return Status::Ok();
}

// LeakyReLU, fused into the convolution or Add before it.
Status Importer::BuildLeakyRelu(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  if (Status s = OneInput(b, "a LeakyReLU"); !s.ok()) return s;
  const json* alpha = Find(cfg, "alpha");
  if (alpha == nullptr) {
    return LayerFail(l,
                     "config has no 'alpha' (the negative slope; Keras 2 always stores "
                     "it, default 0.3)");
  }
  if (!alpha->is_number() || !std::isfinite(alpha->get<double>())) {
    return LayerFail(l, "alpha " + JsonText(*alpha) + " is not a finite number");
  }
  LayerSpec* target = FusionTarget(b, true);
  if (target == nullptr) {
    return FusionRefused(
        b,
        "must directly follow a convolution with activation 'linear' or an Add (it is "
        "fused into it)");
  }
  SetActivation(target, Activation::kLeakyRelu, static_cast<float>(alpha->get<double>()));
  b.s.tensors[l.name] = in;
  return Status::Ok();
}

// Activation: linear (nothing) or relu, fused into the convolution or Add before it.
Status Importer::BuildActivation(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  if (Status s = OneInput(b, "an Activation"); !s.ok()) return s;
  const json* a = Find(cfg, "activation");
  const std::string act = a != nullptr && a->is_string() ? a->get<std::string>() : "";
  if (act == "linear") {  // identity
    b.s.tensors[l.name] = in;
    return Status::Ok();
  }
  if (act != "relu") {
    return LayerFail(l, "activation " + (a ? JsonText(*a) : std::string("(missing)")) +
                            " is not supported (linear, relu)");
  }
  LayerSpec* target = FusionTarget(b, true);
  if (target == nullptr) {
    return FusionRefused(
        b,
        "must directly follow a convolution with activation 'linear' or an Add (it is "
        "fused into it)");
  }
  SetActivation(target, Activation::kRelu, 0.0f);
  b.s.tensors[l.name] = in;
  return Status::Ok();
}

// Conv2DTranspose.
Status Importer::BuildConvTranspose(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const Tensor& in = b.in;
  int& h = b.h;
  int& w = b.w;
  int& c = b.c;
  if (Status st = OneInput(b, "a Conv2DTranspose"); !st.ok()) return st;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  Result<ConvTransposeSpec> deconv = ReadConvTranspose(l, c);
  if (!deconv.ok()) return deconv.status();
  if (b.s.known) {
    h = (h - 1) * deconv->stride_h + DilatedExtent(deconv->kernel_h, deconv->dilation_h) -
        deconv->pads.top - deconv->pads.bottom + deconv->output_padding_h;
    w = (w - 1) * deconv->stride_w + DilatedExtent(deconv->kernel_w, deconv->dilation_w) -
        deconv->pads.left - deconv->pads.right + deconv->output_padding_w;
    if (h < 1 || w < 1) {
      return LayerFail(l, "crops its output at the built size to nothing");
    }
  }
  c = deconv->out_channels;
  deconv->inputs = {in.layer};
  ++b.s.convs;
  AddLayer(b, std::move(deconv).value());
  return Status::Ok();
}

// MaxPooling2D and AveragePooling2D.
Status Importer::BuildPooling(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& h = b.h;
  int& w = b.w;
  if (Status st = OneInput(b, l.cls == "MaxPooling2D" ? "a MaxPooling2D" : "an AveragePooling2D");
      !st.ok()) {
    return st;
  }
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  std::array<int, 2> size{2, 2};
  if (const json* ps = Find(cfg, "pool_size");
      ps != nullptr && !GetPair(ps, 1, model_limits::kMaxKernel, &size)) {
    return LayerFail(l, "pool_size " + JsonText(*ps) + " is not integers in 1.." +
                            std::to_string(model_limits::kMaxKernel));
  }
  std::array<int, 2> strides = size;  // Keras: strides None means pool_size
  if (const json* st = Find(cfg, "strides");
      st != nullptr && !st->is_null() && !GetPair(st, 1, model_limits::kMaxStride, &strides)) {
    return LayerFail(l, "strides " + JsonText(*st) + " are not integers in 1.." +
                            std::to_string(model_limits::kMaxStride));
  }
  Result<std::string> padding = SameOrValid(l);
  if (!padding.ok()) return padding.status();
  PoolSpec pool;
  pool.name = l.name;
  pool.kind = l.cls == "MaxPooling2D" ? PoolKind::kMax : PoolKind::kAverage;
  pool.kernel_h = size[0];
  pool.kernel_w = size[1];
  pool.stride_h = strides[0];
  pool.stride_w = strides[1];
  // TensorFlow's 'same' pads the larger half at the bottom/right; its averages count only
  // the input positions under the window.
  pool.count_include_pad = false;
  if (*padding == "same") {
    pool.padding_rule = PaddingRule::kSameUpper;
    if (b.s.known) {
      const auto [top, bottom] = SameAxis(h, pool.stride_h, pool.kernel_h);
      const auto [left, right] = SameAxis(w, pool.stride_w, pool.kernel_w);
      pool.pads = Pads{top, left, bottom, right};
    }
  }
  if (b.s.known) {
    const int ph = h + pool.pads.top + pool.pads.bottom;
    const int pw = w + pool.pads.left + pool.pads.right;
    if (ph < pool.kernel_h || pw < pool.kernel_w) {
      return LayerFail(l, "its " + std::to_string(h) + "x" + std::to_string(w) +
                              " input at the built size is smaller than the pool");
    }
    h = (ph - pool.kernel_h) / pool.stride_h + 1;
    w = (pw - pool.kernel_w) / pool.stride_w + 1;
  }
  pool.inputs = {in.layer};
  AddLayer(b, std::move(pool));
  return Status::Ok();
}

// UpSampling2D: nearest (Upsample) or bilinear (Resize).
Status Importer::BuildUpSampling(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& h = b.h;
  int& w = b.w;
  if (Status s = OneInput(b, "an UpSampling2D"); !s.ok()) return s;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  std::array<int, 2> factors_value{};
  const std::array<int, 2>* factors = &factors_value;
  if (!GetPair(Find(cfg, "size"), 1, model_limits::kMaxUpsample, &factors_value)) {
    return LayerFail(
        l, "'size' is missing or not integers in 1.." + std::to_string(model_limits::kMaxUpsample));
  }
  bool bilinear = false;
  if (const json* interp = Find(cfg, "interpolation")) {
    bilinear = interp->is_string() && interp->get<std::string>() == "bilinear";
    if (!bilinear && (!interp->is_string() || interp->get<std::string>() != "nearest")) {
      return LayerFail(
          l, "interpolation " + JsonText(*interp) + " is not supported (nearest or bilinear)");
    }
  }
  h *= (*factors)[0];
  w *= (*factors)[1];
  if (bilinear) {
    Result<ResizeCoordinates> grid = BilinearGrid(l);
    if (!grid.ok()) return grid.status();
    ResizeSpec resize;
    resize.name = l.name;
    resize.params.mode = ResizeMode::kLinear;
    resize.params.coordinates = *grid;
    resize.params.scale_num_h = (*factors)[0];
    resize.params.scale_num_w = (*factors)[1];
    resize.inputs = {in.layer};
    AddLayer(b, std::move(resize));
  } else {
    UpsampleSpec up;
    up.name = l.name;
    up.factor_h = (*factors)[0];
    up.factor_w = (*factors)[1];
    up.inputs = {in.layer};
    AddLayer(b, std::move(up));
  }
  return Status::Ok();
}

// Cropping2D: its amounts now; its rule after every layer is built (ChooseCropRules).
Status Importer::BuildCropping(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& h = b.h;
  int& w = b.w;
  if (Status s = OneInput(b, "a Cropping2D"); !s.ok()) return s;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  Pads amounts_value;
  const Pads* amounts = &amounts_value;
  if (!GetSidePads(Find(cfg, "cropping"), &amounts_value)) {
    return LayerFail(l, "'cropping' is missing or not ((top, bottom), (left, right))");
  }
  if (b.s.known) {
    const int oh = h - amounts->top - amounts->bottom;
    const int ow = w - amounts->left - amounts->right;
    if (oh < 1 || ow < 1) {
      return LayerFail(l, "crops its " + std::to_string(h) + "x" + std::to_string(w) +
                              " input at the built size to nothing");
    }
    h = oh;
    w = ow;
  }
  CropSpec crop;
  crop.name = l.name;
  crop.rule = CropRule::kExplicit;
  crop.amounts = *amounts;
  crop.inputs = {in.layer};
  b.s.crops.push_back({b.s.spec->layers.size(), l.name, h, w});
  AddLayer(b, std::move(crop));
  return Status::Ok();
}

// ZeroPadding2D: amounts waiting for the convolution that reads it.
Status Importer::BuildZeroPadding(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  if (Status s = OneInput(b, "a ZeroPadding2D"); !s.ok()) return s;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  Pads amounts_value;
  const Pads* amounts = &amounts_value;
  if (!GetSidePads(Find(cfg, "padding"), &amounts_value)) {
    return LayerFail(l, "'padding' is missing or not ((top, bottom), (left, right))");
  }
  Tensor padded = in;
  padded.pads.top += amounts->top;
  padded.pads.left += amounts->left;
  padded.pads.bottom += amounts->bottom;
  padded.pads.right += amounts->right;
  padded.pad_layer = &l;
  b.s.tensors[l.name] = padded;
  return Status::Ok();
}

// Concatenate (channels) and Add.
Status Importer::BuildMerge(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& c = b.c;
  const bool concat = l.cls == "Concatenate";
  if (concat) {
    const json* axis = Find(cfg, "axis");
    if (axis != nullptr &&
        !(axis->is_number_integer() && (axis->get<int64_t>() == -1 || axis->get<int64_t>() == 3))) {
      return LayerFail(
          l, "axis " + JsonText(*axis) + " is not supported (only the channels axis, -1 or 3)");
    }
  }
  if (l.inbound.size() < 2 || (!concat && l.inbound.size() != 2)) {
    return LayerFail(l, "reads " + std::to_string(l.inbound.size()) + " tensors; " +
                            (concat ? "a Concatenate reads two or more" : "an Add reads two"));
  }
  std::vector<std::string> names;
  int channels = 0;
  for (const std::string& name : l.inbound) {
    const Tensor& t = b.s.tensors.at(name);
    const bool size_differs = b.s.known && (t.h != in.h || t.w != in.w);
    if (size_differs || (!concat && t.c != in.c)) {
      return LayerFail(
          l, "reads " + Quote(l.inbound[0]) + " (" + std::to_string(in.h) + "x" +
                 std::to_string(in.w) + "x" + std::to_string(in.c) + ") and " + Quote(name) + " (" +
                 std::to_string(t.h) + "x" + std::to_string(t.w) + "x" + std::to_string(t.c) +
                 "); " +
                 (concat ? "their heights and widths must match" : "their shapes must match"));
    }
    channels += t.c;
    names.push_back(t.layer);
  }
  if (concat) {
    if (channels > model_limits::kMaxChannels) {
      return LayerFail(l, "concatenates " + std::to_string(channels) + " channels; at most " +
                              std::to_string(model_limits::kMaxChannels));
    }
    c = channels;
    AddLayer(b, ConcatSpec{l.name, std::move(names)});
  } else {
    AddLayer(b, AddSpec{l.name, std::move(names), Activation::kNone, 0.0f});
  }
  return Status::Ok();
}

// Why layer class `l.cls` has no builder: a nested model, or a class the importer does not know.
Status Importer::UnknownLayer(const ChainLayer& l) const {
  if (IsNestedModelClass(l.cls)) {
    return LayerFail(l, std::string("nested models are supported only as a multi_gpu_model "
                                    "wrapper (InputLayer/Lambda/Concatenate around one nested "
                                    "model); supported layers: ") +
                            kSupportedLayers);
  }
  return LayerFail(
      l, std::string("layer class is not supported (supported: ") + kSupportedLayers + ")");
}

// The crop rule of every Cropping2D (crop_rule.h), traced at the built size: the skip its only
// reader, a Concatenate, also reads at its size; a note for each that keeps its amounts.
void Importer::ChooseCropRules(BuildState& s) {
  for (const CropTrace& t : s.crops) {
    auto& crop = std::get<CropSpec>(s.spec->layers[t.layer]);
    if (!s.known) {
      NoteKeptCrop(crop,
                   "the model's input height/width are None, so the size it was built for "
                   "is unknown");
      continue;
    }
    TracedCrop traced{t.out_h, t.out_w, ""};
    const auto& crop_readers = s.readers[t.output];
    if (crop_readers.size() == 1 && crop_readers[0]->cls == "Concatenate") {
      for (const std::string& name : crop_readers[0]->inbound) {
        const Tensor& other = s.tensors.at(name);
        if (name != t.output && other.pad_layer == nullptr &&
            other.index < static_cast<int>(t.layer) && other.h == t.out_h && other.w == t.out_w) {
          traced.skip = other.layer;
          break;
        }
      }
    }
    const std::string why = ChooseCropRule(crop, traced, s.model.height, s.model.width);
    if (!why.empty()) NoteKeptCrop(crop, why);
  }
}

void Importer::NoteKeptCrop(const CropSpec& crop, const std::string& why) {
  const Pads& a = crop.amounts;
  notes_.push_back("Cropping2D " + Quote(crop.name) + " keeps its amounts (top " +
                   std::to_string(a.top) + ", bottom " + std::to_string(a.bottom) + ", left " +
                   std::to_string(a.left) + ", right " + std::to_string(a.right) +
                   ") at every input size: " + why);
}

Status Importer::Build(const ChainModel& model, ModelSpec* spec) {
  BuildState s{model, spec, model.height > 0 && model.width > 0, {}, {}, {}, 0};
  s.tensors[model.input_name] =
      Tensor{model.height, model.width, model.channels, model.input_name, -1, {}, nullptr};
  for (const ChainLayer& l : model.layers) {
    for (size_t k = 0; k < l.inbound.size(); ++k) {
      if (std::find(l.inbound.begin(), l.inbound.begin() + k, l.inbound[k]) ==
          l.inbound.begin() + k) {
        s.readers[l.inbound[k]].push_back(&l);
      }
    }
  }
  for (const ChainLayer& l : model.layers) {
    if (Status st = CheckInbound(s, l); !st.ok()) return st;
    const LayerBuilder build = BuilderOf(l.cls);
    if (build == nullptr) return UnknownLayer(l);
    const Tensor in = s.tensors.at(l.inbound[0]);  // a copy: adding a layer rehashes `tensors`
    LayerBuild b{s, l, in, in.h, in.w, in.c, in.pads, in.pad_layer};
    if (Status st = (this->*build)(b); !st.ok()) return st;
  }
  const Tensor& out = s.tensors.at(s.model.layers.back().name);
  if (out.pad_layer != nullptr) {
    return LayerFail(*out.pad_layer,
                     "ends the model; it must be followed by a Conv2D with "
                     "padding 'valid'");
  }
  if (s.convs == 0) return Fail("the model has no Conv2D layer between input and output");
  if (s.spec->layers.size() > static_cast<size_t>(model_limits::kMaxLayers)) {
    return Fail("the model gives " + std::to_string(s.spec->layers.size()) + " layers; at most " +
                std::to_string(model_limits::kMaxLayers) + " are supported");
  }
  if (out.index != static_cast<int>(s.spec->layers.size()) - 1) {
    return Fail("the model's output " + Quote(s.model.layers.back().name) +
                " is computed by layer " + Quote(out.layer) +
                ", which is not the last: the network's output must be its last layer");
  }
  ChooseCropRules(s);
  s.spec->input.channels = s.model.channels;
  // The default image order (four RGB images) only fits 12 channels; for any other count the file
  // does not say which images the channels hold, so the spec names none (as the loader accepts).
  if (s.spec->input.channels != 3 * static_cast<int>(s.spec->input.image_order.size())) {
    s.spec->input.image_order.clear();
  }
  s.spec->input.traced_height = s.model.height;
  s.spec->input.traced_width = s.model.width;
  SetOutputChannels(*s.spec, out.c);
  KeepInputNamesOfAGraph(*s.spec, s.model.input_name);
  return Status::Ok();
}

}  // namespace sfrt::exporter::keras_import
