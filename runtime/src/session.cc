#include "sfrt/session.h"

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include "cpu_features.h"
#include "kernels/ref/conv2d_bf16_ref.h"
#include "kernels/ref/conv2d_int8_ref.h"
#include "kernels/ref/merge_ref.h"
#include "kernels/ref/resample_ref.h"
#include "memory_planner.h"
#include "session_steps.h"
#include "step_planner.h"
#include "winograd_run.h"

namespace sfrt {

const IsaConvKernels* ConvKernelsFor(Isa isa) {
  switch (VectorIsa(isa)) {
#if SFRT_HAVE_AVX2
    case Isa::kAvx2:
      return &avx2::ConvKernels();
#endif
#if SFRT_HAVE_AVX512
    case Isa::kAvx512:
      return &avx512::ConvKernels();
#endif
#if SFRT_HAVE_NEON
    case Isa::kNeon:
      return &neon::ConvKernels();
#endif
    default:
      return nullptr;
  }
}

namespace {

Result<Isa> ResolveIsa(Isa requested) {
  if (requested == Isa::kAuto) return BestIsa();
  if (!IsaSupported(requested)) {
    return Status::Error(
        std::string("Session::Create: SessionOptions::isa asks for ISA '") + IsaName(requested) +
        "', which this CPU and build cannot run (supported: " + SupportedIsaList() + ")");
  }
  return requested;
}

Status CheckTuning(const KernelTuning& tuning) {
  const int t = tuning.winograd_tile;
  if (t != 0 && t != 2 && t != 4 && t != KernelTuning::kWinogradAuto) {
    return Status::Error("Session::Create: KernelTuning::winograd_tile is " + std::to_string(t) +
                         "; use 0 (off), 2, 4 or KernelTuning::kWinogradAuto (-1)");
  }
  return Status::Ok();
}

}  // namespace

Session::~Session() {
  std::free(arena_);
  std::free(packed_);
  std::free(packed8_);
}

Result<std::unique_ptr<Session>> Session::Create(std::shared_ptr<const Model> model,
                                                 const SessionOptions& options) {
  if (model == nullptr) return Status::Error("Session::Create: no model");
  if (options.max_height <= 0 || options.max_width <= 0) {
    return Status::Error("Session::Create: maximum input size " +
                         std::to_string(options.max_height) + "x" +
                         std::to_string(options.max_width) + " is not positive");
  }
  if (options.threads < 0) {
    return Status::Error("Session::Create: SessionOptions::threads is " +
                         std::to_string(options.threads) + "; use 0 (one per CPU) or more");
  }
  if (Status t = CheckTuning(options.tuning); !t.ok()) return t;
  Result<Isa> isa = ResolveIsa(options.isa);
  if (!isa.ok()) return isa.status();

  std::unique_ptr<Session> session(new Session());
  session->model_ = std::move(model);
  session->options_ = options;
  session->isa_ = *isa;
  session->threads_ = options.threads;
  if (session->threads_ == 0) {
    session->threads_ = static_cast<int>(std::thread::hardware_concurrency());
    if (session->threads_ <= 0) session->threads_ = 1;
  }

  session->geometry_.resize(session->model_->layers().size());
  session->shape_scratch_.resize(session->model_->layers().size());
  Status s =
      InferGeometry(*session->model_, options.max_height, options.max_width, session->geometry_);
  if (!s.ok()) {
    return Status::Error("planning for the maximum input size " +
                         std::to_string(options.max_height) + "x" +
                         std::to_string(options.max_width) + ": " + s.message());
  }
  if (Status planned = session->Plan(); !planned.ok()) return planned;
  if (session->threads_ > 1) {
    session->pool_ =
        std::make_unique<Pool>(session->threads_, options.pin_threads, options.spin_us);
  }
  return session;
}

Status Session::Plan() {
  const size_t gather = PlanSteps();
  if (options_.tuning.concat_in_place) PlaceConcatInputs();
  if (Status s = PackWeights(); !s.ok()) return s;
  if (Status s = PlanTensors(gather); !s.ok()) return s;
  FindInputQuantizeStep();
  return Status::Ok();
}

// 4. The uint8 input path: the step that quantises the model input, when it is the input's only
// reader.
void Session::FindInputQuantizeStep() {
  input_quantize_step_ = -1;
  const auto layers = model_->layers();
  for (size_t k = 0; k < steps_.size(); ++k) {
    const LayerDesc& first = layers[static_cast<size_t>(steps_[k].first_layer)];
    bool reads_input = false;
    for (int t : first.inputs) reads_input = reads_input || t == kModelInput;
    if (!reads_input) continue;
    const Step::Kind kind = steps_[k].kind;
    if (kind == Step::Kind::kInt8Conv || kind == Step::Kind::kUpsampleU8 ||
        kind == Step::Kind::kConcatU8) {
      continue;  // reads the quantised input
    }
    if (kind != Step::Kind::kQuantize || input_quantize_step_ >= 0) {
      input_quantize_step_ = -1;  // a float32 reader, or a second quantisation
      return;
    }
    input_quantize_step_ = static_cast<int>(k);
  }
}

std::optional<QuantParams> Session::InputQuantization() const {
  if (input_quantize_step_ < 0) return std::nullopt;
  return steps_[static_cast<size_t>(input_quantize_step_)].quant;
}

size_t Session::QuantizedInputBytes(int height, int width) const {
  const int channels = model_->metadata().input.channels;
  const size_t elements =
      static_cast<size_t>(height) * static_cast<size_t>(width) * static_cast<size_t>(channels);
  return elements + (channels % 4 != 0 ? kQuantizedInputSlack : 0);
}

uint8_t QuantizeInput(float value, const QuantParams& q) {
  return Int8Quantize(value, 1.0f / q.scale, q.zero_point);
}

// 2. Packed weights for the SIMD steps (one 64-byte-aligned allocation for the float32 ones,
// one for the int8 and bf16 ones) and the steps' kernels. (1, the steps: step_planner.cc.)
Status Session::PackWeights() {
  if (Status s = PackFloatWeights(); !s.ok()) return s;
  if (Status s = PackReducedWeights(); !s.ok()) return s;
  for (const Step& step : steps_) {
    step_info_.push_back(
        {step.first_layer, step.last_layer, step.kernel, step.precision, step.converts()});
  }
  return Status::Ok();
}

// 2a. The float32 convolutions' packings (Winograd's, the few-output kernel's, the SIMD
// kernels'), and each step's float32 kernel.
Status Session::PackFloatWeights() {
  const auto layers = model_->layers();
  const IsaConvKernels* kernels = ConvKernelsFor(isa_);
  const KernelTuning& tuning = options_.tuning;
  auto variant_for = [&](const ConvParams& p) -> const ConvKernelVariant& {
    return PickConvVariant(*kernels, p.out_channels);
  };
  auto few_out = [&](const Step& step) {
    const ConvParams& p = layers[step.last_layer].conv;
    if (!tuning.few_out) return false;
    return step.kind == Step::Kind::kConv && kernels->few_out != nullptr &&
           p.out_channels <= kFewOutChannels && p.in_channels >= kFewOutMinInputs;
  };
  size_t floats = 0;
  for (const Step& step : steps_) {
    const ConvParams& p = layers[step.last_layer].conv;
    if (step.kind == Step::Kind::kWinograd) {
      floats += PackedWinogradFloats(p, step.winograd->m, step.winograd->nr);
    }
    if (step.kind != Step::Kind::kConv && step.kind != Step::Kind::kUpConv) continue;
    if (few_out(step)) {
      floats += PackedConvFewOutFloats(p);
      continue;
    }
    if (step.upwinograd != nullptr) {
      floats += PackedWinogradUpFloats(p, step.upwinograd->nr) +
                PackedConvFloats(p, variant_for(p).nr, false);
      continue;
    }
    floats += PackedConvFloats(p, variant_for(p).nr, step.kind == Step::Kind::kUpConv);
  }
  if (floats > 0) {
    packed_bytes_ = floats * sizeof(float);
    packed_ = static_cast<float*>(std::aligned_alloc(kArenaAlignment, packed_bytes_));
    if (packed_ == nullptr) {
      return Status::Error("cannot allocate " + std::to_string(packed_bytes_) +
                           " bytes for the packed weights");
    }
  }
  float* cursor = packed_;
  for (Step& step : steps_) {
    const ConvParams& p = layers[step.last_layer].conv;
    if (step.kind == Step::Kind::kWinograd) {
      step.wpacked = PackWinograd(p, step.winograd->m, step.winograd->nr, cursor);
      cursor += PackedWinogradFloats(p, step.winograd->m, step.winograd->nr);
      continue;
    }
    if (step.kind != Step::Kind::kConv && step.kind != Step::Kind::kUpConv) continue;
    if (few_out(step)) {
      step.packed = PackConvFewOut(p, cursor);
      cursor += PackedConvFewOutFloats(p);
      step.fn = kernels->few_out;
      step.kernel = kernels->few_out_name;
      continue;
    }
    const ConvKernelVariant& v = variant_for(p);
    if (step.upwinograd != nullptr) {
      // The 3x3 weights for the border, the phase kernels' Winograd weights for the interior.
      step.packed = PackConv(p, v.nr, false, cursor);
      cursor += PackedConvFloats(p, v.nr, false);
      step.wpacked = PackWinogradUp(p, step.upwinograd->nr, cursor);
      cursor += PackedWinogradUpFloats(p, step.upwinograd->nr);
      step.fn = v.upconv;
      step.kernel = step.upwinograd->name;
      continue;
    }
    const bool phases = step.kind == Step::Kind::kUpConv;
    step.packed = PackConv(p, v.nr, phases, cursor);
    cursor += PackedConvFloats(p, v.nr, phases);
    step.fn = phases ? v.upconv : v.conv;
    step.kernel = phases ? v.upconv_name : v.conv_name;
  }
  return Status::Ok();
}

// 2b. Int8 and bf16 packings (the reference layout, and the SIMD one when the step has SIMD
// kernels). A bf16 convolution that reads an upsampling 2x with a 3x3 stride-1 kernel gets its
// phase kernels.
Status Session::PackReducedWeights() {
  const auto layers = model_->layers();
  const KernelTuning& tuning = options_.tuning;
  const IsaInt8Kernels* kernels8 = Int8KernelsFor(isa_);
  const IsaBf16Kernels* kernels16 = Bf16KernelsFor(isa_);
  auto nr8 = [&](const Step& step) { return step.fn8 == ref::Conv2dInt8Rows ? 0 : kernels8->nr; };
  auto nr16 = [&](const Step& step) {
    return step.fn16 == ref::Conv2dBf16Rows ? 0 : kernels16->nr;
  };
  auto phases16 = [&](const Step& step) {
    return step.upsampled && SimdFits(layers[step.last_layer].conv, true, 0);
  };
  auto reduced_bytes = [&](const Step& step) -> size_t {
    const ConvParams& p = layers[step.last_layer].conv;
    if (step.kind == Step::Kind::kInt8Conv) return PackedInt8Bytes(p, nr8(step));
    if (step.kind == Step::Kind::kBf16Conv) return PackedBf16Bytes(p, nr16(step), phases16(step));
    return 0;
  };
  for (const Step& step : steps_) packed8_bytes_ += reduced_bytes(step);
  if (packed8_bytes_ > 0) {
    packed8_ = std::aligned_alloc(kArenaAlignment, packed8_bytes_);
    if (packed8_ == nullptr) {
      return Status::Error("cannot allocate " + std::to_string(packed8_bytes_) +
                           " bytes for the packed int8 and bf16 weights");
    }
  }
  uint8_t* cursor8 = static_cast<uint8_t*>(packed8_);
  for (Step& step : steps_) {
    const ConvParams& p = layers[step.last_layer].conv;
    if (step.kind == Step::Kind::kInt8Conv) {
      step.packed8 = PackInt8Conv(p, nr8(step), step.out_u8 ? &step.quant : nullptr, cursor8);
      if (!tuning.few_out) step.packed8.few_weights = nullptr;  // the tiles compute it
      step.packed8.narrow = nr8(step) > 0 && Int8Narrow(tuning, kernels8, p, step.upsampled);
      step.packed8.amx_1x4 = !tuning.amx_pairs;
    } else if (step.kind == Step::Kind::kBf16Conv) {
      step.packed16 = PackBf16Conv(p, nr16(step), phases16(step), !step.out_bf16, cursor8);
      if (!tuning.few_out) step.packed16.few_weights = nullptr;
      step.packed16.amx_1x4 = !tuning.amx_pairs;
    }
    cursor8 += reduced_bytes(step);
  }
  return Status::Ok();
}

// 3. The arena. Every step but the last writes a tensor of its own, except a crop, which is a
// view of its input. Times are layer indices: a tensor is born with the last layer of the step
// that writes it (a converting step's, with the tensor it converts) and lives until the last
// step that reads it, directly or through crops' views. A uint8 or bf16 tensor gets
// kInt8TensorSlack or kBf16TensorSlack spare bytes that kernels may read. TensorLifetimes turns
// the steps, in order, into the arena's requests.
class Session::TensorLifetimes {
 public:
  explicit TensorLifetimes(Session& s)
      : s_(s),
        layers_(s.model_->layers()),
        holder_f_(layers_.size() + 1, -1),
        holder_u8_(layers_.size() + 1, -1),
        holder_bf16_(layers_.size() + 1, -1),
        concat_request_(s.steps_.size(), -1) {}

  // Step k: the tensors it reads live until its time; the tensor it writes (its own, its slice
  // of an in-place Concat's, none for a crop or the last step) is requested.
  void Add(size_t k) {
    const Step& step = s_.steps_[k];
    const size_t src = SlotOf(layers_[step.first_layer].inputs[0]);
    ReadInputs(step, src);
    if (step.kind == Step::Kind::kCrop || k + 1 == s_.steps_.size()) return;
    const int born = step.converts() ? step.first_layer - 1 : step.last_layer;
    if (step.in_place || step.slice_of >= 0) {
      AddConcatSlice(k, born);
    } else {
      AddTensor(k, src, born);
    }
  }

  std::vector<BufferRequest> requests;
  std::vector<int> producers;  // per request: the time its tensor is born

 private:
  // Per tensor slot (a layer's output; the model input last) and element type, the request that
  // holds it (-1: none, or the caller's input).
  size_t SlotOf(int t) const { return t == kModelInput ? layers_.size() : static_cast<size_t>(t); }
  std::vector<int>& Holders(const Step& step) {
    return step.out_u8 ? holder_u8_ : step.out_bf16 ? holder_bf16_ : holder_f_;
  }
  void Read(int request, int time) {
    if (request < 0) return;
    BufferRequest& r = requests[static_cast<size_t>(request)];
    r.last_use = std::max(r.last_use, time);
  }
  void ReadInputs(const Step& step, size_t src) {
    const int time = step.last_layer;
    const LayerDesc& first = layers_[step.first_layer];
    switch (step.kind) {
      case Step::Kind::kRows:
        for (int t : first.inputs) Read(holder_f_[SlotOf(t)], time);
        break;
      case Step::Kind::kConcatU8:
        for (int t : first.inputs) Read(holder_u8_[SlotOf(t)], time);
        break;
      case Step::Kind::kConcatBf16:
        for (int t : first.inputs) Read(holder_bf16_[SlotOf(t)], time);
        break;
      case Step::Kind::kInt8Conv:
      case Step::Kind::kUpsampleU8:
        Read(holder_u8_[src], time);
        break;
      case Step::Kind::kBf16Conv:
      case Step::Kind::kUpsampleBf16:
        Read(holder_bf16_[src], time);
        break;
      case Step::Kind::kCrop:  // a view: what reads it reads the same memory
        Read(Holders(step)[src], time);
        Holders(step)[static_cast<size_t>(step.last_layer)] = Holders(step)[src];
        break;
      default:  // the float32 readers: converting steps, float32 convolutions, upsamplings
        Read(holder_f_[src], time);
        break;
    }
  }
  // The Concat's tensor, born with the first step that writes a slice of it.
  void AddConcatSlice(size_t k, int born) {
    const Step& step = s_.steps_[k];
    const size_t cat = step.in_place ? k : static_cast<size_t>(step.slice_of);
    int& request = concat_request_[cat];
    if (request < 0) {
      request = static_cast<int>(requests.size());
      const size_t elements = s_.geometry_[s_.steps_[cat].last_layer].output.elements();
      const size_t bytes = step.out_u8 ? elements + kInt8TensorSlack
                                       : elements * sizeof(uint16_t) + kBf16TensorSlack;
      requests.push_back({bytes, born, born});
      producers.push_back(born);
    }
    s_.tensor_of_step_[k] = request;
    Holders(step)[static_cast<size_t>(step.last_layer)] = request;
  }
  void AddTensor(size_t k, size_t src, int born) {
    const Step& step = s_.steps_[k];
    const bool convert = step.converts();
    const TensorShape shape = !convert                ? s_.geometry_[step.last_layer].output
                              : src == layers_.size() ? s_.geometry_[0].input
                                                      : s_.geometry_[src].output;
    const size_t bytes = step.out_u8     ? shape.elements() + kInt8TensorSlack
                         : step.out_bf16 ? shape.elements() * sizeof(uint16_t) + kBf16TensorSlack
                                         : shape.elements() * sizeof(float);
    s_.tensor_of_step_[k] = static_cast<int>(requests.size());
    // A converting step's tensor is the converted form of its input's slot.
    Holders(step)[convert ? src : static_cast<size_t>(step.last_layer)] =
        static_cast<int>(requests.size());
    requests.push_back({bytes, born, born});
    producers.push_back(born);
  }

  Session& s_;
  std::span<const LayerDesc> layers_;
  std::vector<int> holder_f_, holder_u8_, holder_bf16_;
  std::vector<int> concat_request_;  // per in-place Concat step
};

// 3. The arena: where each tensor lives.
Status Session::PlanTensors(size_t gather) {
  const size_t slots = model_->layers().size() + 1;
  views_ = std::make_unique<Views>();
  views_->gather.resize(gather);
  views_->gather8.resize(gather);
  views_->gather16.resize(gather);
  views_->f32.resize(slots);
  views_->u8.resize(slots);
  views_->bf16.resize(slots);
  tensor_of_step_.assign(steps_.size(), -1);
  TensorLifetimes lifetimes(*this);
  for (size_t k = 0; k < steps_.size(); ++k) lifetimes.Add(k);
  const size_t tensors = lifetimes.requests.size();
  RequestScratch(lifetimes.requests);
  const ArenaPlan plan = PlanArena(lifetimes.requests);
  for (size_t t = tensors, k = 0; k < steps_.size(); ++k) {
    if (HasScratch(steps_[k])) steps_[k].scratch_offset = plan.offsets[t++];
  }
  plan_.resize(tensors);
  for (size_t t = 0; t < tensors; ++t) {
    plan_[t] = {lifetimes.producers[t], lifetimes.requests[t].last_use, plan.offsets[t],
                lifetimes.requests[t].bytes};
  }
  for (size_t k = 0; k < steps_.size(); ++k) {
    if (tensor_of_step_[k] >= 0) {
      plan_[static_cast<size_t>(tensor_of_step_[k])].is_u8 = steps_[k].out_u8;
      plan_[static_cast<size_t>(tensor_of_step_[k])].is_bf16 = steps_[k].out_bf16;
    }
  }
  arena_bytes_ = plan.total_bytes;
  if (plan.total_bytes > 0) {
    arena_ = static_cast<float*>(std::aligned_alloc(kArenaAlignment, plan.total_bytes));
    if (arena_ == nullptr) {
      return Status::Error("cannot allocate the " + std::to_string(plan.total_bytes) +
                           "-byte arena for " + std::to_string(options_.max_height) + "x" +
                           std::to_string(options_.max_width) + " inputs");
    }
  }
  return Status::Ok();
}

// 3b. Winograd scratch (v and m) lives during its own step only, so it reuses memory that the
// tensors of other steps need; it is not a tensor (plan() lists tensors only). One request per
// step that has it, after the tensors', in step order.
bool Session::HasScratch(const Step& step) {
  return step.kind == Step::Kind::kWinograd || step.upwinograd != nullptr;
}

void Session::RequestScratch(std::vector<BufferRequest>& requests) {
  for (Step& step : steps_) {
    if (!HasScratch(step)) continue;
    const LayerGeometry& g = geometry_[step.last_layer];
    size_t floats_needed = 0;
    if (step.kind == Step::Kind::kWinograd) {
      step.band_rows = WinogradBandRows(step.wpacked, g.output.height, g.output.width);
      floats_needed = WinogradBandScratchFloats(step.wpacked, step.band_rows, g.output.width);
    } else {
      const LayerGeometry& c = geometry_[step.crop_layer >= 0 ? step.crop_layer : step.first_layer];
      const UpGrid u =
          UpGridOf(g.output.height, g.output.width, g.pads, c.output.height, c.output.width,
                   step.crop_layer >= 0 ? c.crop.top : 0, step.crop_layer >= 0 ? c.crop.left : 0);
      step.band_rows = UpWinogradBandRows(step.wpacked, u.tiles_h, u.tiles_w);
      floats_needed = UpWinogradScratchFloats(step.wpacked, step.band_rows, u.tiles_w);
    }
    requests.push_back({floats_needed * sizeof(float), step.last_layer, step.last_layer});
  }
}

// 1b. Concats in place. A uint8 (bf16) Concat whose every input is written by an int8 (bf16)
// convolution or a nearest upsampling (directly, or through a crop that keeps the upsampling's
// top-left corner and is its only reader), none of them the model input, another Concat's slice or
// repeated, and whose channel counts are multiples of 4 (kernels read input channels in groups of 4
// or 2, so no kernel reads a neighbouring slice), needs no copy: each producer writes its slice of
// the Concat's tensor, every other reader reads the slice in place (ByteView::pixel_stride), and
// the Concat step does nothing.
void Session::PlaceConcatInputs() {
  const auto layers = model_->layers();
  std::vector<int> step_of_layer(layers.size(), -1);  // the step that writes a layer's output
  for (size_t k = 0; k < steps_.size(); ++k) {
    const Step& step = steps_[k];
    if (step.kind != Step::Kind::kQuantize && step.kind != Step::Kind::kToBf16) {
      step_of_layer[static_cast<size_t>(step.last_layer)] = static_cast<int>(k);
    }
  }
  auto keeps_corner = [](const CropParams& c) {
    return c.rule == CropRule::kExplicit ? c.amounts.top == 0 && c.amounts.left == 0
                                         : !c.excess_rows_from_top && !c.excess_cols_from_left;
  };
  std::vector<char> placed(layers.size(), 0);  // layer outputs already in a slice
  for (size_t c = 0; c < steps_.size(); ++c) {
    const bool u8 = steps_[c].kind == Step::Kind::kConcatU8;
    if (!u8 && steps_[c].kind != Step::Kind::kConcatBf16) continue;
    const Step::Kind upsampling = u8 ? Step::Kind::kUpsampleU8 : Step::Kind::kUpsampleBf16;
    const Step::Kind convolution = u8 ? Step::Kind::kInt8Conv : Step::Kind::kBf16Conv;
    struct Slice {
      int layer, producer, crop, channel;
    };
    std::vector<Slice> slices;
    int channel = 0;
    bool ok = true;
    for (int t : layers[static_cast<size_t>(steps_[c].last_layer)].inputs) {
      if (t == kModelInput || placed[static_cast<size_t>(t)] ||
          geometry_[static_cast<size_t>(t)].output.channels % 4 != 0) {
        ok = false;
        break;
      }
      int producer = step_of_layer[static_cast<size_t>(t)];
      int crop = -1;
      if (producer >= 0 && steps_[static_cast<size_t>(producer)].kind == Step::Kind::kCrop) {
        const LayerDesc& cut = layers[static_cast<size_t>(t)];
        const int up = cut.inputs[0];
        crop = t;
        producer = up == kModelInput ? -1 : step_of_layer[static_cast<size_t>(up)];
        ok = keeps_corner(cut.crop) && producer >= 0 &&
             steps_[static_cast<size_t>(producer)].kind == upsampling &&
             model_->consumer_count(static_cast<size_t>(up)) == 1 &&
             !placed[static_cast<size_t>(up)];
      } else {
        const Step* p = producer >= 0 ? &steps_[static_cast<size_t>(producer)] : nullptr;
        ok = p != nullptr &&
             ((p->kind == convolution && (p->out_u8 || p->out_bf16)) || p->kind == upsampling);
      }
      for (const Slice& other : slices) ok = ok && other.layer != t && other.producer != producer;
      if (!ok) break;
      slices.push_back({t, producer, crop, channel});
      channel += geometry_[static_cast<size_t>(t)].output.channels;
    }
    if (!ok) continue;
    steps_[c].in_place = true;
    steps_[c].kernel = "in place";
    for (const Slice& slice : slices) {
      Step& producer = steps_[static_cast<size_t>(slice.producer)];
      producer.slice_of = static_cast<int>(c);
      producer.slice_channel = slice.channel;
      producer.slice_crop = slice.crop;
      placed[static_cast<size_t>(slice.layer)] = 1;
      placed[static_cast<size_t>(producer.last_layer)] = 1;
    }
  }
}

Result<TensorShape> Session::OutputShape(int height, int width) const {
  if (height > options_.max_height || width > options_.max_width) {
    return Status::Error("input " + std::to_string(height) + "x" + std::to_string(width) +
                         " exceeds the session's maximum " + std::to_string(options_.max_height) +
                         "x" + std::to_string(options_.max_width));
  }
  if (model_->is_chain()) return InferOutputShape(*model_, height, width);
  if (Status s = InferGeometry(*model_, height, width, shape_scratch_); !s.ok()) return s;
  return shape_scratch_.back().output;
}

}  // namespace sfrt
