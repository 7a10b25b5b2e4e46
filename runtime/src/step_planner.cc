// The step planner (Session::PlanSteps): what runs each layer, which layers a step fuses, and in
// which type tensors stay between steps. Its rules are named here: SimdFits, Int8Narrow,
// PlanReducedTensors, and the StepPlanner's PlanUpsample (the phase fusion) and PlanConv.
#include "step_planner.h"

#include <algorithm>
#include <span>
#include <vector>

#include "kernels/ref/conv2d_bf16_ref.h"
#include "kernels/ref/conv2d_int8_ref.h"
#include "winograd_run.h"

namespace sfrt {

// Whether a SIMD kernel takes convolution `p`: undilated and ungrouped, and a 3x3 stride-1
// kernel when it reads a fused upsampling (`upsampled`), else at most `max_taps` taps.
bool SimdFits(const ConvParams& p, bool upsampled, int max_taps) {
  if (!UndilatedUngrouped(p)) return false;
  return upsampled ? p.kernel_h == 3 && p.kernel_w == 3 && p.stride_h == 1 && p.stride_w == 1
                   : p.kernel_h * p.kernel_w <= max_taps;
}

// Whether the int8 SIMD step of `p` runs on the kernel table's narrow kernel.
bool Int8Narrow(const KernelTuning& tuning, const IsaInt8Kernels* kernels8, const ConvParams& p,
                bool upsampled) {
  return !upsampled && tuning.few_out && kernels8 != nullptr && kernels8->narrow_name[0] != '\0' &&
         Int8NarrowConv(p);
}

namespace {

// The layer outputs of a graph that a session keeps in a reduced type (uint8 with a
// quantisation, or bf16) rather than float32. A layer's output qualifies when
//   - an int8 or bf16 convolution writes it, or a nearest upsampling, a crop or a Concat of
//     qualifying tensors of one type (which move values without arithmetic), and
//   - every layer that reads it is a convolution of that precision (for int8, all with one and
//     the same input_quant) or a qualifying layer of the same type and quantisation (the
//     model's output never qualifies).
// Converting once where the tensor is written then gives the values that converting the float32
// tensor at each reader gives (the same Int8Quantize, or the same rounding to bf16, of the same
// float), so keeping them changes no result; it saves the converting steps and moves a quarter
// (uint8) or half (bf16) of the bytes. The exporter gives the int8 convolutions that read one
// tensor one quantisation so that this applies.
struct ReducedTensors {
  std::vector<Precision> type;     // per layer output: kFloat32, kInt8 (uint8) or kBFloat16
  std::vector<QuantParams> quant;  // where kInt8
};

ReducedTensors PlanReducedTensors(std::span<const LayerDesc> layers) {
  const int n = static_cast<int>(layers.size());
  // The tensors whose values layer i reads (a crop's second input gives only its size).
  auto data_inputs = [&](int i) {
    const LayerDesc& l = layers[static_cast<size_t>(i)];
    return std::span<const int>(l.inputs).first(l.kind == LayerKind::kCrop ? 1 : l.inputs.size());
  };
  std::vector<std::vector<int>> readers(static_cast<size_t>(n));
  for (int r = 0; r < n; ++r) {
    for (int t : data_inputs(r)) {
      if (t != kModelInput) readers[static_cast<size_t>(t)].push_back(r);
    }
  }
  auto reduced_conv = [&](int i) {
    const LayerDesc& l = layers[static_cast<size_t>(i)];
    return l.kind == LayerKind::kConv2D && l.conv.precision != Precision::kFloat32;
  };
  auto moves_values = [&](int i) {
    const LayerKind k = layers[static_cast<size_t>(i)].kind;
    return k == LayerKind::kUpsample || k == LayerKind::kCrop || k == LayerKind::kConcat;
  };
  // Candidates start reduced (a byte mover's type comes from its readers) and are dropped until
  // every rule holds; every pass only drops, so this ends. Readers come after what they read.
  std::vector<char> candidate(static_cast<size_t>(n), 0);
  for (int i = 0; i + 1 < n; ++i)
    candidate[static_cast<size_t>(i)] = reduced_conv(i) || moves_values(i);
  ReducedTensors out;
  out.type.assign(static_cast<size_t>(n), Precision::kFloat32);
  out.quant.resize(static_cast<size_t>(n));
  for (bool changed = true; changed;) {
    changed = false;
    for (int i = n - 1; i >= 0; --i) {
      if (!candidate[static_cast<size_t>(i)]) continue;
      const std::vector<int>& rs = readers[static_cast<size_t>(i)];
      bool ok = !rs.empty();
      Precision type = Precision::kFloat32;
      QuantParams quant;
      for (size_t k = 0; ok && k < rs.size(); ++k) {
        const int r = rs[k];
        Precision want = Precision::kFloat32;
        QuantParams want_quant;
        if (reduced_conv(r)) {
          want = layers[static_cast<size_t>(r)].conv.precision;
          if (want == Precision::kInt8)
            want_quant = layers[static_cast<size_t>(r)].conv.input_quant;
        } else if (candidate[static_cast<size_t>(r)]) {
          want = out.type[static_cast<size_t>(r)];
          want_quant = out.quant[static_cast<size_t>(r)];
        } else {
          ok = false;
          break;
        }
        if (k > 0 && (want != type || (want == Precision::kInt8 && !(want_quant == quant)))) {
          ok = false;
        }
        type = want;
        quant = want_quant;
      }
      if (ok && reduced_conv(i)) ok = layers[static_cast<size_t>(i)].conv.precision == type;
      if (ok && moves_values(i)) {
        for (int t : data_inputs(i)) {
          if (t == kModelInput || !candidate[static_cast<size_t>(t)]) ok = false;
        }
      }
      if (ok) {
        out.type[static_cast<size_t>(i)] = type;
        out.quant[static_cast<size_t>(i)] = type == Precision::kInt8 ? quant : QuantParams{};
      } else {
        candidate[static_cast<size_t>(i)] = 0;
        out.type[static_cast<size_t>(i)] = Precision::kFloat32;
        changed = true;
      }
    }
  }
  return out;
}

}  // namespace

// Session::PlanSteps, one rule per method: the steps in run order, fusing an upsample 2x (+ crop)
// + 3x3 stride-1 convolution where the ISA can, and (int8, bf16) an upsample 2x (+ crop) + any
// convolution on every ISA; a chain keeps int8 and bf16 tensors between convolutions of one
// precision, a graph where PlanReducedTensors says.
class Session::StepPlanner {
 public:
  explicit StepPlanner(Session& session)
      : layers_(session.model_->layers()),
        n_(static_cast<int>(layers_.size())),
        model_(*session.model_),
        isa_(session.isa_),
        tuning_(session.options_.tuning),
        steps_(session.steps_),
        kernels_(ConvKernelsFor(isa_)),
        kernels8_(Int8KernelsFor(isa_)),
        kernels16_(Bf16KernelsFor(isa_)),
        geometry_(session.geometry_),
        winograd2_(tuning_.winograd_tile == 2 ||
                           tuning_.winograd_tile == KernelTuning::kWinogradAuto
                       ? WinogradKernelsFor(isa_, 2)
                       : nullptr),
        winograd4_(tuning_.winograd_tile == 4 ||
                           tuning_.winograd_tile == KernelTuning::kWinogradAuto
                       ? WinogradKernelsFor(isa_, 4)
                       : nullptr),
        upwinograd_(tuning_.winograd_tile != 0 && tuning_.winograd_upconv
                        ? WinogradUpKernelsFor(isa_)
                        : nullptr),
        graph_(model_.float32_between_layers()),
        reduced_(graph_ ? PlanReducedTensors(layers_)
                        : ReducedTensors{std::vector<Precision>(static_cast<size_t>(n_),
                                                                Precision::kFloat32),
                                         std::vector<QuantParams>(static_cast<size_t>(n_))}),
        converted_(static_cast<size_t>(n_) + 1, -1) {}

  // Appends the steps; returns the most inputs a kRows step or a reduced Concat has.
  size_t Plan() {
    for (int i = 0; i < n_; ++i) i = PlanLayer(i);
    return gather_;
  }

 private:
  // The first convolution at or after `from`, or -1.
  int NextConv(int from) const {
    for (int k = from; k < n_; ++k) {
      if (layers_[k].kind == LayerKind::kConv2D) return k;
    }
    return -1;
  }
  Precision PrecisionOf(int k) const {
    return k >= 0 && layers_[k].kind == LayerKind::kConv2D ? layers_[k].conv.precision
                                                           : Precision::kFloat32;
  }
  static void SetOut(Step& step, Precision element) {
    step.out_u8 = element == Precision::kInt8;
    step.out_bf16 = element == Precision::kBFloat16;
  }
  static Precision OutOf(const Step& step) {
    return step.out_u8     ? Precision::kInt8
           : step.out_bf16 ? Precision::kBFloat16
                           : Precision::kFloat32;
  }
  // Whether layer `reader` is the only one that reads layer t's output (so a step may fuse both
  // and t's output need never exist).
  bool OnlyReader(int reader, int t) const {
    return layers_[reader].inputs[0] == t && model_.consumer_count(static_cast<size_t>(t)) == 1;
  }
  Precision TensorType(int t) const {
    return t == kModelInput ? Precision::kFloat32 : reduced_.type[static_cast<size_t>(t)];
  }

  // The int8 or bf16 convolution `conv`, reading the upsampling before it when `upsampled`.
  Step ReducedStep(int conv, bool upsampled, int crop) const {
    Step step;
    const ConvParams& p = layers_[conv].conv;
    step.last_layer = conv;
    step.crop_layer = crop;
    step.upsampled = upsampled;
    step.precision = p.precision;
    const Precision consumer = PrecisionOf(NextConv(conv + 1));
    SetOut(step, consumer == p.precision ? p.precision : Precision::kFloat32);
    step.quant = p.output_quant;
    if (p.precision == Precision::kInt8) {
      Int8Kernel(p, upsampled, step);
    } else {
      Bf16Kernel(p, upsampled, step);
    }
    return step;
  }
  void Int8Kernel(const ConvParams& p, bool upsampled, Step& step) const {
    step.kind = Step::Kind::kInt8Conv;
    if (kernels8_ == nullptr || !SimdFits(p, upsampled, kMaxInt8Taps)) {
      step.fn8 = ref::Conv2dInt8Rows;
      step.kernel = upsampled ? "ref::UpConv2dInt8" : "ref::Conv2dInt8";
      return;
    }
    step.fn8 = upsampled ? kernels8_->upconv : kernels8_->conv;
    step.kernel = upsampled ? kernels8_->upconv_name : kernels8_->conv_name;
    if (!upsampled && tuning_.few_out && kernels8_->few_out_name[0] != '\0' && Int8FewOutputs(p)) {
      step.kernel = kernels8_->few_out_name;
    }
    if (Int8Narrow(tuning_, kernels8_, p, upsampled)) step.kernel = kernels8_->narrow_name;
  }
  void Bf16Kernel(const ConvParams& p, bool upsampled, Step& step) const {
    step.kind = Step::Kind::kBf16Conv;
    if (kernels16_ == nullptr || !SimdFits(p, upsampled, kMaxBf16Taps)) {
      step.fn16 = ref::Conv2dBf16Rows;
      step.kernel = upsampled ? "ref::UpConv2dBf16" : "ref::Conv2dBf16";
      return;
    }
    step.fn16 = upsampled ? kernels16_->upconv : kernels16_->conv;
    step.kernel = upsampled ? kernels16_->upconv_name : kernels16_->conv_name;
    if (!upsampled && tuning_.few_out && kernels16_->few_out_name[0] != '\0' && Bf16FewOutputs(p)) {
      step.kernel = kernels16_->few_out_name;
    }
  }

  // The step that converts the float32 tensor layer i reads into what convolution `reader`
  // (int8 or bf16) reads.
  Step ConvertStep(int i, int reader) const {
    Step q;
    q.first_layer = q.last_layer = i;
    q.precision = PrecisionOf(reader);
    SetOut(q, q.precision);
    if (q.precision == Precision::kInt8) {
      q.kind = Step::Kind::kQuantize;
      const QuantizeKernel quantize = QuantizeKernelFor(isa_);
      q.quantize = quantize.fn;
      q.kernel = quantize.name;
      q.quant = layers_[reader].conv.input_quant;
    } else {
      q.kind = Step::Kind::kToBf16;
      const ToBf16Kernel to_bf16 = ToBf16KernelFor(isa_);
      q.to_bf16 = to_bf16.fn;
      q.kernel = to_bf16.name;
    }
    return q;
  }
  // A graph's converting step for layer i's input, unless one already planned for the same
  // tensor gives the same precision and quantisation (a later reader reuses it).
  void ConvertInGraph(int i, int reader) {
    const int t = layers_[i].inputs[0];
    int& slot = converted_[t == kModelInput ? static_cast<size_t>(n_) : static_cast<size_t>(t)];
    const Step q = ConvertStep(i, reader);
    if (slot >= 0) {
      const Step& before = steps_[static_cast<size_t>(slot)];
      if (before.precision == q.precision &&
          (q.precision != Precision::kInt8 || (before.quant.scale == q.quant.scale &&
                                               before.quant.zero_point == q.quant.zero_point))) {
        return;
      }
    }
    slot = static_cast<int>(steps_.size());
    steps_.push_back(q);
  }
  // A graph's int8 or bf16 convolution `conv`: writes its output's type.
  void GraphOut(Step& step, int conv) const {
    SetOut(step, TensorType(conv));
    step.quant = reduced_.quant[static_cast<size_t>(conv)];
  }
  // A layer's float32 rows as its kind computes them.
  void RowsStep(Step& step, const LayerDesc& layer) {
    const ops::LayerOp& op = ops::OpOf(layer.kind);
    step.kind = Step::Kind::kRows;
    step.rows = op.rows;
    step.kernel = op.rows_kernel;
    gather_ = std::max(gather_, layer.inputs.size());
  }

  // Plans layer i (with the layers a fused step takes after it); returns the last layer taken.
  int PlanLayer(int i) {
    const LayerDesc& layer = layers_[i];
    const int consumer = NextConv(i);
    if (!graph_ && cur_ == Precision::kFloat32 && PrecisionOf(consumer) != Precision::kFloat32) {
      // The float32 tensor here is read by an int8 or bf16 convolution: convert it once, before
      // any upsampling makes it larger.
      steps_.push_back(ConvertStep(i, consumer));
      cur_ = steps_.back().precision;
    }
    Step step;
    step.first_layer = step.last_layer = i;
    SetOut(step, graph_ ? TensorType(i) : cur_);
    int last = i;
    if (layer.kind == LayerKind::kCrop) {
      step.kind = Step::Kind::kCrop;
      step.kernel = i + 1 == n_ ? "ref::Copy" : "view";
    } else if (layer.kind == LayerKind::kConcat && (step.out_u8 || step.out_bf16)) {
      // A Concat between int8 or bf16 convolutions (PlanReducedTensors).
      step.kind = step.out_u8 ? Step::Kind::kConcatU8 : Step::Kind::kConcatBf16;
      step.kernel = step.out_u8 ? "ref::ConcatRowsU8" : "ref::ConcatRowsBf16";
      gather_ = std::max(gather_, layer.inputs.size());
    } else if (layer.kind == LayerKind::kUpsample) {
      last = PlanUpsample(i, step);
    } else if (layer.kind == LayerKind::kConv2D) {
      PlanConv(i, step);
    } else {
      RowsStep(step, layer);  // float32 (the loader checks)
    }
    steps_.push_back(step);
    return last;
  }

  // The upsampling at layer i: fused with the convolution that reads it (through a crop or not)
  // where the rule allows, else on its own in the current tensor's type. Returns the last layer
  // the step takes.
  int PlanUpsample(int i, Step& step) {
    const LayerDesc& layer = layers_[i];
    int conv = i + 1;
    int crop = -1;
    if (conv < n_ && layers_[conv].kind == LayerKind::kCrop && OnlyReader(conv, i)) crop = conv++;
    const bool conv_next = conv < n_ && layers_[conv].kind == LayerKind::kConv2D &&
                           OnlyReader(conv, crop >= 0 ? crop : i);
    const bool factor2 = layer.upsample.factor_h == 2 && layer.upsample.factor_w == 2;
    const bool fusable = kernels_ != nullptr && factor2 && conv_next &&
                         cur_ == Precision::kFloat32 && SimdFits(layers_[conv].conv, true, 0);
    if (graph_ && factor2 && conv_next && PrecisionOf(conv) != Precision::kFloat32) {
      if (TensorType(layer.inputs[0]) != PrecisionOf(conv)) ConvertInGraph(i, conv);
      step = ReducedStep(conv, true, crop);
      step.first_layer = i;
      GraphOut(step, conv);
      return conv;
    }
    if (cur_ != Precision::kFloat32 && factor2 && conv_next) {
      step = ReducedStep(conv, true, crop);
      step.first_layer = i;
      cur_ = OutOf(step);
      return conv;
    }
    if (cur_ == Precision::kInt8 || step.out_u8) {
      step.kind = Step::Kind::kUpsampleU8;
      step.kernel = "ref::UpsampleNearestU8";
    } else if (cur_ == Precision::kBFloat16 || step.out_bf16) {
      step.kind = Step::Kind::kUpsampleBf16;
      step.kernel = "ref::UpsampleNearestBf16";
    } else if (fusable) {
      step.kind = Step::Kind::kUpConv;
      step.last_layer = conv;
      step.crop_layer = crop;
      if (upwinograd_ != nullptr && WinogradUpApplies(layers_[conv].conv)) {
        step.upwinograd = upwinograd_;
      }
      return conv;
    } else {
      step.kind = Step::Kind::kUpsample;
      step.kernel = "ref::UpsampleNearest";
    }
    return i;
  }

  // The convolution at layer i: int8 or bf16 in a graph or a chain, else Winograd, a SIMD
  // kernel, or the reference rows.
  void PlanConv(int i, Step& step) {
    const LayerDesc& layer = layers_[i];
    if (graph_ && layer.conv.precision != Precision::kFloat32) {
      if (TensorType(layer.inputs[0]) != layer.conv.precision) ConvertInGraph(i, i);
      step = ReducedStep(i, false, -1);
      step.first_layer = i;
      GraphOut(step, i);
    } else if (layer.conv.precision != Precision::kFloat32) {
      step = ReducedStep(i, false, -1);
      step.first_layer = i;
      cur_ = OutOf(step);
    } else if (const WinogradKernels* w = WinogradFor(i); w != nullptr) {
      step.kind = Step::Kind::kWinograd;
      step.winograd = w;
      step.kernel = w->name;
    } else if (kernels_ != nullptr && SimdFits(layer.conv, false, kMaxConvTaps)) {
      step.kind = Step::Kind::kConv;
    } else {
      RowsStep(step, layer);
    }
  }

  // The Winograd kernels for convolution layer i, or nullptr: the tuning's tile, or under
  // kWinogradAuto F(4x4) where the layer's output at the planned size has at least
  // kWinogradAutoMinSide pixels on each side and F(2x2) where not.
  const WinogradKernels* WinogradFor(int i) const {
    if (!WinogradApplies(layers_[i].conv)) return nullptr;
    if (tuning_.winograd_tile != KernelTuning::kWinogradAuto) {
      return tuning_.winograd_tile == 4 ? winograd4_ : winograd2_;
    }
    const TensorShape& out = geometry_[static_cast<size_t>(i)].output;
    const bool wide = out.height >= KernelTuning::kWinogradAutoMinSide &&
                      out.width >= KernelTuning::kWinogradAutoMinSide;
    return wide && winograd4_ != nullptr ? winograd4_ : winograd2_;
  }

  std::span<const LayerDesc> layers_;
  const int n_;
  const Model& model_;
  const Isa isa_;
  const KernelTuning& tuning_;
  std::vector<Step>& steps_;
  const IsaConvKernels* kernels_;
  const IsaInt8Kernels* kernels8_;
  const IsaBf16Kernels* kernels16_;
  const std::vector<LayerGeometry>& geometry_;  // at the planned maximum size
  const WinogradKernels* winograd2_;            // F(2x2, 3x3), where the tuning may take it
  const WinogradKernels* winograd4_;            // F(4x4, 3x3), likewise
  const WinogradKernels* upwinograd_;
  // A graph, or a model with a float32-only op, keeps float32 tensors between layers: each int8
  // or bf16 convolution converts the tensor it reads (before the upsampling it fuses, if any)
  // and writes float32, so that Concat, Add and the other ops read float32, except the tensors
  // that stay uint8 or bf16 between convolutions of that precision (PlanReducedTensors).
  const bool graph_;
  const ReducedTensors reduced_;
  // Per tensor slot (layer i's output at i, the model input at n), the converting step already
  // planned for it in a graph.
  std::vector<int> converted_;
  // A chain's current tensor: float32, uint8 (kInt8) or bf16 (kBFloat16). An int8 or bf16
  // convolution writes its own type for a following convolution of the same precision, float32
  // otherwise.
  Precision cur_ = Precision::kFloat32;
  size_t gather_ = 0;
};

size_t Session::PlanSteps() { return StepPlanner(*this).Plan(); }

}  // namespace sfrt
