#include "sfrt/reference.h"

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "bf16_packing.h"
#include "int8_packing.h"
#include "kernels/bf16_job.h"
#include "kernels/int8_job.h"
#include "kernels/ref/conv2d_bf16_ref.h"
#include "kernels/ref/conv2d_int8_ref.h"
#include "kernels/ref/conv2d_ref.h"
#include "kernels/ref/resample_ref.h"
#include "ops/layer_op.h"
#include "sfrt/layer_kinds.h"

namespace sfrt {
namespace {

// The index of the first convolution at or after layer i, or -1.
int ConvFrom(std::span<const LayerDesc> layers, size_t i) {
  for (size_t k = i; k < layers.size(); ++k) {
    if (layers[k].kind == LayerKind::kConv2D) return static_cast<int>(k);
  }
  return -1;
}

// The index of the next convolution after layer i, or -1.
int NextConv(std::span<const LayerDesc> layers, size_t i) { return ConvFrom(layers, i + 1); }

// A tensor in one of the three element types.
struct Tensor {
  TensorShape shape;
  bool is_u8 = false;
  bool is_bf16 = false;
  QuantParams quant;  // when is_u8
  std::vector<float> f;
  std::vector<uint8_t> q;
  std::vector<uint16_t> h;  // when is_bf16

  ConstTensorView fview() const {
    return {f.data(), shape.height, shape.width, shape.channels,
            static_cast<ptrdiff_t>(shape.width) * shape.channels};
  }
  ConstByteView qview() const {
    return {q.data(), shape.height, shape.width, shape.channels,
            static_cast<ptrdiff_t>(shape.width) * shape.channels};
  }
  ConstBf16View hview() const {
    return {h.data(), shape.height, shape.width, shape.channels,
            static_cast<ptrdiff_t>(shape.width) * shape.channels};
  }
  std::vector<float> Real() const {
    if (is_bf16) {
      std::vector<float> r(h.size());
      for (size_t k = 0; k < h.size(); ++k) r[k] = Bf16ToFloat(h[k]);
      return r;
    }
    if (!is_u8) return f;
    std::vector<float> r(q.size());
    for (size_t k = 0; k < q.size(); ++k) {
      r[k] = quant.scale * static_cast<float>(static_cast<int>(q[k]) - quant.zero_point);
    }
    return r;
  }
};

Tensor Quantized(const Tensor& t, const QuantParams& quant) {
  Tensor out;
  out.shape = t.shape;
  out.is_u8 = true;
  out.quant = quant;
  out.q.resize(t.shape.elements());
  ref::QuantizeRows(t.fview(), 1.0f / quant.scale, quant.zero_point,
                    DenseByteView(out.q.data(), t.shape.height, t.shape.width, t.shape.channels), 0,
                    t.shape.height);
  return out;
}

Tensor ToBf16(const Tensor& t) {
  Tensor out;
  out.shape = t.shape;
  out.is_bf16 = true;
  out.h.resize(t.shape.elements());
  ref::ToBf16Rows(t.fview(),
                  DenseBf16View(out.h.data(), t.shape.height, t.shape.width, t.shape.channels), 0,
                  t.shape.height);
  return out;
}

// 64-byte-aligned scratch of `bytes` bytes inside `storage`.
void* AlignedScratch(std::vector<uint8_t>& storage, size_t bytes) {
  storage.resize(bytes + 64);
  return storage.data() + (64 - reinterpret_cast<uintptr_t>(storage.data()) % 64) % 64;
}

// Where a graph's convolution i reads a nearest-2x upsampling (through a crop or not) that only
// it reads, in the layers just before it, as the session fuses them: the upsampling's index, and
// the crop's in `crop` (-1: none); -1 when it does not.
int FusedUpsampling(const Model& model, size_t i, int& crop) {
  const auto layers = model.layers();
  const int up = ReadsNearest2xUpsampling(layers, layers[i].inputs[0], &crop);
  // Just before it, each read by the next layer only.
  const int reader_of_up = crop >= 0 ? crop : static_cast<int>(i);
  const bool fused = up >= 0 && up + 1 == reader_of_up &&
                     model.consumer_count(static_cast<size_t>(up)) == 1 &&
                     (crop < 0 || (static_cast<size_t>(crop) + 1 == i &&
                                   model.consumer_count(static_cast<size_t>(crop)) == 1));
  if (fused) return up;
  crop = -1;
  return -1;
}

// A graph's int8 or bf16 convolution (float32 tensors between layers): `in` converted to what it
// reads, float32 written to `dst`. With `up`, `in` is the map before a nearest-2x upsampling that
// the convolution reads through the phase rule (`c`: the upsampling's or its crop's geometry), as
// the session does.
void ReducedGraphConv(const ConvParams& p, const LayerGeometry& g, ConstTensorView in, bool up,
                      const LayerGeometry& c, TensorView dst) {
  Tensor t;
  t.shape = {in.height, in.width, in.channels};
  t.f.resize(t.shape.elements());
  ref::Copy(in, DenseView(t.f.data(), in.height, in.width, in.channels));
  auto fused = [&](auto& args) {
    args.pads = g.pads;
    args.out_f32 = dst;
    if (!up) return;
    args.upsampled = true;
    args.crop_top = c.crop.top;
    args.crop_left = c.crop.left;
    args.c_height = c.output.height;
    args.c_width = c.output.width;
  };
  std::vector<uint8_t> packing;
  if (p.precision == Precision::kInt8) {
    const Tensor q = Quantized(t, p.input_quant);
    const PackedInt8Conv packed =
        PackInt8Conv(p, 0, nullptr, AlignedScratch(packing, PackedInt8Bytes(p, 0)));
    Int8ConvArgs args;
    args.conv = &packed;
    args.in = q.qview();
    fused(args);
    ref::Conv2dInt8Rows(args, 0, dst.height, 0, 1);
    return;
  }
  const Tensor h = ToBf16(t);
  const bool phases =
      up && p.kernel_h == 3 && p.kernel_w == 3 && p.stride_h == 1 && p.stride_w == 1;
  const PackedBf16Conv packed =
      PackBf16Conv(p, 0, phases, true, AlignedScratch(packing, PackedBf16Bytes(p, 0, phases)));
  Bf16ConvArgs args;
  args.conv = &packed;
  args.in = h.hview();
  fused(args);
  ref::Conv2dBf16Rows(args, 0, dst.height, 0, 1);
}

// A graph, or a chain with a float32-only layer (Model::float32_between_layers()): each layer
// reads the outputs its inputs name, and each output is freed after its last reader.
void ForwardGraph(const Model& model, std::span<const float> input,
                  const std::vector<LayerGeometry>& g, std::span<float> output,
                  const LayerObserver& observer) {
  const auto layers = model.layers();
  const size_t n = layers.size();
  std::vector<std::vector<float>> outputs(n);
  std::vector<int> last_reader(n, -1);
  for (size_t i = 0; i < n; ++i) {
    std::vector<int> reads = layers[i].inputs;
    int crop = -1;
    const int up =
        layers[i].kind == LayerKind::kConv2D && layers[i].conv.precision != Precision::kFloat32
            ? FusedUpsampling(model, i, crop)
            : -1;
    if (up >= 0) reads.push_back(layers[static_cast<size_t>(up)].inputs[0]);
    for (int t : reads) {
      if (t != kModelInput) last_reader[static_cast<size_t>(t)] = static_cast<int>(i);
    }
  }
  const TensorShape in_shape = g.front().input;  // layer 0 can read only the model input
  auto view_of = [&](int t) -> ConstTensorView {
    const TensorShape& s = t == kModelInput ? in_shape : g[static_cast<size_t>(t)].output;
    const float* data = t == kModelInput ? input.data() : outputs[static_cast<size_t>(t)].data();
    return {data, s.height, s.width, s.channels, static_cast<ptrdiff_t>(s.width) * s.channels};
  };
  for (size_t i = 0; i < n; ++i) {
    const LayerDesc& layer = layers[i];
    const TensorShape& s = g[i].output;
    std::vector<float>& out = outputs[i];
    out.resize(s.elements());
    const TensorView dst = DenseView(out.data(), s.height, s.width, s.channels);
    const ConstTensorView src = view_of(layer.inputs[0]);
    if (layer.kind == LayerKind::kConv2D && layer.conv.precision != Precision::kFloat32) {
      int crop = -1;
      const int up = FusedUpsampling(model, i, crop);
      if (up < 0) {
        ReducedGraphConv(layer.conv, g[i], src, false, g[i], dst);
      } else {
        ReducedGraphConv(layer.conv, g[i], view_of(layers[static_cast<size_t>(up)].inputs[0]), true,
                         g[static_cast<size_t>(crop >= 0 ? crop : up)], dst);
      }
    } else {  // every other layer: its kind's float32 rows (ops/layer_op.h)
      std::vector<ConstTensorView> ins;
      for (int t : layer.inputs) ins.push_back(view_of(t));
      const ops::LayerRows rows{&layer, &g[i], ins.data(), static_cast<int>(ins.size()), dst};
      ops::OpOf(layer.kind).rows(rows, 0, s.height);
    }
    if (observer) observer(static_cast<int>(i), s, out);
    for (size_t t = 0; t < i; ++t) {
      if (last_reader[t] == static_cast<int>(i)) outputs[t] = {};
    }
  }
  std::copy(outputs.back().begin(), outputs.back().end(), output.begin());
}

}  // namespace

// The uint8 or bf16 map before a chain's last nearest-2x upsampling, and what crops after it
// removed: an int8 or bf16 convolution with phase weights reads it (int8_job.h); a convolution
// ends it.
struct LowMap {
  Tensor tensor;
  bool have = false;
  int crop_top = 0;
  int crop_left = 0;
};

// A convolution that reads the LowMap through its phases (`view`, the map) instead of the
// upsampled tensor of shape `upsampled`, with what crops after the upsampling removed.
template <typename Args, typename View>
void ReadThroughPhases(Args& args, View view, const LowMap& low, const TensorShape& upsampled) {
  args.in = view;
  args.upsampled = true;
  args.crop_top = low.crop_top;
  args.crop_left = low.crop_left;
  args.c_height = upsampled.height;
  args.c_width = upsampled.width;
}

// Whether a chain's int8 or bf16 convolution at layer i writes float32: no convolution reads its
// output, or the next one runs in another precision (the session's rule, StepPlanner).
bool WritesFloat(std::span<const LayerDesc> layers, size_t i) {
  const int next = NextConv(layers, i);
  return next < 0 || layers[static_cast<size_t>(next)].conv.precision != layers[i].conv.precision;
}

// A chain's bf16 convolution at layer i, reading `cur` (or `low` through the phase kernels, as the
// session fuses a nearest-2x upsampling into the 3x3 stride-1 convolution after it).
Tensor ChainBf16Conv(std::span<const LayerDesc> layers, size_t i, const LayerGeometry& g,
                     const Tensor& cur, const LowMap& low) {
  const LayerDesc& layer = layers[i];
  Tensor next;
  next.shape = g.output;
  const TensorShape& s = next.shape;
  const ptrdiff_t row = static_cast<ptrdiff_t>(s.width) * s.channels;
  const ConvParams& p = layer.conv;
  const bool out_float = WritesFloat(layers, i);
  // The session fuses a nearest-2x upsampling into the 3x3 stride-1 convolution after it and
  // computes its interior from the phase kernels: so does the reference.
  const bool phases = low.have && low.tensor.is_bf16 && p.kernel_h == 3 && p.kernel_w == 3 &&
                      p.stride_h == 1 && p.stride_w == 1;
  std::vector<uint8_t> packing;
  const PackedBf16Conv packed =
      PackBf16Conv(p, 0, phases, out_float, AlignedScratch(packing, PackedBf16Bytes(p, 0, phases)));
  Bf16ConvArgs args;
  args.conv = &packed;
  args.in = cur.hview();
  args.pads = g.pads;
  if (phases) {
    ReadThroughPhases(args, low.tensor.hview(), low, cur.shape);
  }
  if (out_float) {
    next.f.resize(s.elements());
    args.out_f32 = {next.f.data(), s.height, s.width, s.channels, row};
  } else {
    next.is_bf16 = true;
    next.h.resize(s.elements());
    args.out_bf16 = {next.h.data(), s.height, s.width, s.channels, row};
  }
  ref::Conv2dBf16Rows(args, 0, s.height, 0, 1);
  return next;
}

// A chain's int8 convolution at layer i, reading `cur` (or `low` through its phase weights).
Tensor ChainInt8Conv(std::span<const LayerDesc> layers, size_t i, const LayerGeometry& g,
                     const Tensor& cur, const LowMap& low) {
  const LayerDesc& layer = layers[i];
  Tensor next;
  next.shape = g.output;
  const TensorShape& s = next.shape;
  const ptrdiff_t row = static_cast<ptrdiff_t>(s.width) * s.channels;
  const ConvParams& p = layer.conv;
  const bool out_float = WritesFloat(layers, i);
  std::vector<uint8_t> packing;
  const PackedInt8Conv packed = PackInt8Conv(p, 0, out_float ? nullptr : &p.output_quant,
                                             AlignedScratch(packing, PackedInt8Bytes(p, 0)));
  Int8ConvArgs args;
  args.conv = &packed;
  args.in = cur.qview();
  args.pads = g.pads;
  if (p.phase_weights_q != nullptr && low.have && low.tensor.is_u8) {
    ReadThroughPhases(args, low.tensor.qview(), low, cur.shape);
  }
  if (out_float) {
    next.f.resize(s.elements());
    args.out_f32 = {next.f.data(), s.height, s.width, s.channels, row};
  } else {
    next.is_u8 = true;
    next.quant = p.output_quant;
    next.q.resize(s.elements());
    args.out_u8 = {next.q.data(), s.height, s.width, s.channels, row};
  }
  ref::Conv2dInt8Rows(args, 0, s.height, 0, 1);
  return next;
}

// A chain's nearest upsampling, in the current tensor's type; a 2x one of a uint8 or bf16
// tensor starts a LowMap.
Tensor ChainUpsample(const LayerDesc& layer, const LayerGeometry& g, const Tensor& cur,
                     LowMap* low) {
  Tensor next;
  next.shape = g.output;
  const TensorShape& s = next.shape;
  const ptrdiff_t row = static_cast<ptrdiff_t>(s.width) * s.channels;
  if ((cur.is_u8 || cur.is_bf16) && layer.upsample.factor_h == 2 && layer.upsample.factor_w == 2) {
    low->tensor = cur;
    low->have = true;
    low->crop_top = low->crop_left = 0;
  }
  next.is_u8 = cur.is_u8;
  next.is_bf16 = cur.is_bf16;
  next.quant = cur.quant;
  if (cur.is_bf16) {
    next.h.resize(s.elements());
    ref::UpsampleNearestPlane(cur.hview(), layer.upsample.factor_h, layer.upsample.factor_w,
                              Bf16View{next.h.data(), s.height, s.width, s.channels, row});
  } else if (cur.is_u8) {
    next.q.resize(s.elements());
    ref::UpsampleNearestPlane(cur.qview(), layer.upsample.factor_h, layer.upsample.factor_w,
                              ByteView{next.q.data(), s.height, s.width, s.channels, row});
  } else {
    next.f.resize(s.elements());
    ref::UpsampleNearest(cur.fview(), layer.upsample.factor_h, layer.upsample.factor_w,
                         {next.f.data(), s.height, s.width, s.channels, row});
  }
  return next;
}

// A chain's crop, in the current tensor's type; a LowMap remembers what it removed.
Tensor ChainCrop(const LayerGeometry& g, const Tensor& cur, LowMap* low) {
  Tensor next;
  next.shape = g.output;
  const TensorShape& s = next.shape;
  const ptrdiff_t row = static_cast<ptrdiff_t>(s.width) * s.channels;
  next.is_u8 = cur.is_u8;
  next.is_bf16 = cur.is_bf16;
  next.quant = cur.quant;
  const Padding& c = g.crop;
  low->crop_top += c.top;
  low->crop_left += c.left;
  if (cur.is_bf16) {
    next.h.resize(s.elements());
    ConstBf16View v = cur.hview();
    v.data = v.pixel(c.top, c.left);
    v.height = s.height;
    v.width = s.width;
    ref::CopyPlane(v, Bf16View{next.h.data(), s.height, s.width, s.channels, row});
  } else if (cur.is_u8) {
    next.q.resize(s.elements());
    ConstByteView v = cur.qview();
    v.data = v.pixel(c.top, c.left);
    v.height = s.height;
    v.width = s.width;
    ref::CopyPlane(v, ByteView{next.q.data(), s.height, s.width, s.channels, row});
  } else {
    next.f.resize(s.elements());
    ConstTensorView v = cur.fview();
    v.data = v.pixel(c.top, c.left);
    v.height = s.height;
    v.width = s.width;
    ref::Copy(v, {next.f.data(), s.height, s.width, s.channels, row});
  }
  return next;
}

Status RunReferenceForward(const Model& model, std::span<const float> input, int height, int width,
                           std::span<float> output, const LayerObserver& observer) {
  Result<std::vector<LayerGeometry>> geometry = InferGeometry(model, height, width);
  if (!geometry.ok()) return geometry.status();
  const std::vector<LayerGeometry>& g = *geometry;
  const auto layers = model.layers();
  if (input.size() < g.front().input.elements()) {
    return Status::Error("reference forward: input holds " + std::to_string(input.size()) +
                         " floats; " + std::to_string(g.front().input.elements()) + " needed");
  }
  if (output.size() < g.back().output.elements()) {
    return Status::Error("reference forward: output holds " + std::to_string(output.size()) +
                         " floats; " + std::to_string(g.back().output.elements()) + " needed");
  }
  if (model.float32_between_layers()) {
    ForwardGraph(model, input, g, output, observer);
    return Status::Ok();
  }
  Tensor cur;
  cur.shape = g.front().input;
  LowMap low;
  cur.f.assign(input.begin(), input.begin() + static_cast<ptrdiff_t>(cur.shape.elements()));
  for (size_t i = 0; i < layers.size(); ++i) {
    const LayerDesc& layer = layers[i];
    // A float32 tensor that an int8 or bf16 convolution reads is converted where the session
    // converts it: before the upsamplings and crops between them.
    const int reader = ConvFrom(layers, i);
    if (!cur.is_u8 && !cur.is_bf16 && reader >= 0) {
      const ConvParams& c = layers[static_cast<size_t>(reader)].conv;
      if (c.precision == Precision::kInt8) cur = Quantized(cur, c.input_quant);
      if (c.precision == Precision::kBFloat16) cur = ToBf16(cur);
    }
    Tensor next;
    if (layer.kind == LayerKind::kConv2D && layer.conv.precision == Precision::kBFloat16) {
      next = ChainBf16Conv(layers, i, g[i], cur, low);
    } else if (layer.kind == LayerKind::kConv2D && layer.conv.precision == Precision::kInt8) {
      next = ChainInt8Conv(layers, i, g[i], cur, low);
    } else if (layer.kind == LayerKind::kConv2D) {
      next.shape = g[i].output;
      const TensorShape& s = next.shape;
      next.f.resize(s.elements());
      ref::Conv2d(cur.fview(), layer.conv, g[i].pads,
                  {next.f.data(), s.height, s.width, s.channels,
                   static_cast<ptrdiff_t>(s.width) * s.channels});
    } else if (layer.kind == LayerKind::kUpsample) {
      next = ChainUpsample(layer, g[i], cur, &low);
    } else {
      next = ChainCrop(g[i], cur, &low);
    }
    if (layer.kind == LayerKind::kConv2D) low.have = false;
    cur = std::move(next);
    if (observer) {
      const std::vector<float> real = cur.Real();
      observer(static_cast<int>(i), cur.shape, real);
    }
  }
  const std::vector<float> out = cur.Real();
  std::copy(out.begin(), out.end(), output.begin());
  return Status::Ok();
}

}  // namespace sfrt
