// Session::Run: one walk over the planned steps (Session::StepRun), with no allocation, lock or
// I/O (session.h); the steps' jobs and how their rows spread over the pool.
#include <chrono>
#include <cstdint>
#include <cstring>
#include <string>

#include "conv_packing.h"
#include "kernels/ref/conv2d_bf16_ref.h"
#include "kernels/ref/conv2d_int8_ref.h"
#include "kernels/ref/merge_ref.h"
#include "kernels/ref/resample_ref.h"
#include "session_steps.h"
#include "winograd_run.h"

namespace sfrt {
namespace {

// A SIMD convolution (float32: ConvRowsFn/ConvArgs; int8: Int8ConvRowsFn/Int8ConvArgs) split
// into work items: output-channel block major, then `chunks` row ranges, so threads taking
// consecutive items share one block's weights in cache while they write disjoint rows, and a
// layer with many blocks hands each thread whole blocks.
template <typename Fn, typename Args>
struct BlockedConvJob {
  Fn fn;
  const Args* args;
  int rows;
  int chunks;
};
using ConvJob = BlockedConvJob<ConvRowsFn, ConvArgs>;

template <typename Job>
void BlockedConvTrampoline(void* ctx, int begin, int end) {
  const Job* job = static_cast<const Job*>(ctx);
  for (int item = begin; item < end;) {
    const int blk = item / job->chunks;
    const int chunk = item % job->chunks;
    // Consecutive items of one block are one row range.
    const int last_chunk =
        end - blk * job->chunks < job->chunks ? end - blk * job->chunks : job->chunks;
    const int r0 = static_cast<int>(static_cast<long long>(job->rows) * chunk / job->chunks);
    const int r1 = static_cast<int>(static_cast<long long>(job->rows) * last_chunk / job->chunks);
    job->fn(*job->args, r0, r1, blk, blk + 1);
    item = blk * job->chunks + last_chunk;
  }
}

// A float32 convolution with ConvArgs::rows_first: items are output rows, each call every block.
void RowsFirstTrampoline(void* ctx, int begin, int end) {
  const ConvJob* job = static_cast<const ConvJob*>(ctx);
  job->fn(*job->args, begin, end, 0, job->args->conv->blocks);
}

// Row ranges per output-channel block: about four items per thread.
int ConvChunks(int blocks, int rows, int threads) {
  const int want = 4 * threads;
  int chunks = (want + blocks - 1) / blocks;
  if (chunks > rows) chunks = rows;
  return chunks < 1 ? 1 : chunks;
}

struct QuantizeJob {
  QuantizeRowsFn fn;
  ConstTensorView in;
  ByteView out;
  float inv_scale;
  int zero_point;
};

void QuantizeTrampoline(void* ctx, int begin, int end) {
  const QuantizeJob* job = static_cast<const QuantizeJob*>(ctx);
  job->fn(job->in, job->inv_scale, job->zero_point, job->out, begin, end);
}

struct ToBf16Job {
  ToBf16RowsFn fn;
  ConstTensorView in;
  Bf16View out;
};

void ToBf16Trampoline(void* ctx, int begin, int end) {
  const ToBf16Job* job = static_cast<const ToBf16Job*>(ctx);
  job->fn(job->in, job->out, begin, end);
}

// A kRows step over a range of output rows.
struct RowsJob {
  ops::LayerRowsFn fn;
  ops::LayerRows rows;
};

void RowsTrampoline(void* ctx, int begin, int end) {
  const RowsJob* job = static_cast<const RowsJob*>(ctx);
  job->fn(job->rows, begin, end);
}

// A Concat of uint8 or bf16 views (ref::ConcatRows has an overload for each).
template <typename In, typename Out>
struct ConcatJob {
  const In* inputs;
  int count;
  Out out;
};

template <typename Job>
void ConcatTrampoline(void* ctx, int begin, int end) {
  const Job* job = static_cast<const Job*>(ctx);
  ref::ConcatRows(job->inputs, job->count, job->out, begin, end);
}

// Where a step writes an h x w x c uint8 or bf16 tensor at `data`: densely, or as its slice of a
// Concat's tensor shaped `whole` (Session::PlaceConcatInputs), `data` pointing at its first
// channel.
template <typename T>
PlaneView<T> OutputPlane(T* data, int h, int w, int c, const TensorShape* whole) {
  if (whole == nullptr) return DensePlaneView(data, h, w, c);
  return {data, h, w, c, static_cast<ptrdiff_t>(whole->width) * whole->channels, whole->channels};
}

}  // namespace

Status Session::Run(std::span<const float> input, int height, int width, std::span<float> output) {
  return Execute(input, nullptr, height, width, output, {}, nullptr);
}

Status Session::Run(std::span<const float> input, int height, int width, std::span<float> output,
                    std::span<int64_t> step_end_ns) {
  return Execute(input, nullptr, height, width, output, step_end_ns, nullptr);
}

Status Session::RunQuantized(std::span<const uint8_t> input, int height, int width,
                             std::span<float> output, std::span<int64_t> step_end_ns) {
  if (input_quantize_step_ < 0) {
    return Status::Error(
        "this session takes no quantised input: the model input is not read by int8 "
        "convolutions alone (Session::InputQuantization is empty)");
  }
  if (height > 0 && width > 0 && input.size() < QuantizedInputBytes(height, width)) {
    return Status::Error("quantised input buffer holds " + std::to_string(input.size()) +
                         " bytes; " + std::to_string(height) + "x" + std::to_string(width) +
                         " needs " + std::to_string(QuantizedInputBytes(height, width)));
  }
  return Execute({}, input.data(), height, width, output, step_end_ns, nullptr);
}

Status Session::RunObserved(std::span<const float> input, int height, int width,
                            std::span<float> output, const LayerObserver& observer) {
  if (!observer) return Execute(input, nullptr, height, width, output, {}, nullptr);
  if (observation_ == nullptr) {
    observation_ = std::make_unique<Observation>();
    observation_->quant.resize(model_->layers().size() + 1);
  }
  observation_->observer = &observer;
  const Status s = Execute(input, nullptr, height, width, output, {}, observation_.get());
  observation_->observer = nullptr;
  return s;
}

void Session::Observe(const Step& step, size_t src_slot, Observation& observation) const {
  if (step.kind == Step::Kind::kQuantize) {  // computes no layer; its tensor's quantisation
    observation.quant[src_slot] = step.quant;
    return;
  }
  if (step.kind == Step::Kind::kToBf16) return;
  const auto slot = static_cast<size_t>(step.last_layer);
  // A uint8 tensor: an int8 convolution's own output quantisation; a copy (upsampling, crop,
  // Concat) keeps its input's.
  QuantParams q;
  if (step.out_u8) {
    q = step.kind == Step::Kind::kInt8Conv ? step.quant : observation.quant[src_slot];
    observation.quant[slot] = q;
  }
  // An upsampling that writes only the crop a Concat takes of it (PlaceConcatInputs): its whole
  // output never exists; the crop's step shows what does.
  if (step.slice_crop >= 0) return;
  const TensorShape& shape = geometry_[slot].output;
  const Views& views = *views_;
  const auto row = static_cast<size_t>(shape.width) * static_cast<size_t>(shape.channels);
  if (!step.out_u8 && !step.out_bf16 &&
      views.f32[slot].row_stride == static_cast<ptrdiff_t>(row)) {  // dense float32: as it is
    (*observation.observer)(step.last_layer, shape, {views.f32[slot].data, shape.elements()});
    return;
  }
  observation.values.resize(shape.elements());
  float* out = observation.values.data();
  // Copies a view of any element type dense, each element as `real` makes it a float.
  auto copy_dense = [&](const auto& v, auto real) {
    for (int y = 0; y < shape.height; ++y) {
      for (int x = 0; x < shape.width; ++x) {
        const auto* p = v.pixel(y, x);
        for (int c = 0; c < shape.channels; ++c) *out++ = real(p[c]);
      }
    }
  };
  if (step.out_u8) {
    copy_dense(views.u8[slot], [q](uint8_t v) {
      return q.scale * static_cast<float>(static_cast<int>(v) - q.zero_point);
    });
  } else if (step.out_bf16) {
    copy_dense(views.bf16[slot], Bf16ToFloat);
  } else {
    copy_dense(views.f32[slot], [](float v) { return v; });
  }
  (*observation.observer)(step.last_layer, shape, observation.values);
}

// One Run() over the steps (Execute): each step reads the views of the tensors it names and
// writes its output's, in the element type it writes; its rows are spread over the pool.
struct Session::StepRun {
  Session& s;
  std::span<float> output;

  size_t SlotOf(int t) const {
    return t == kModelInput ? s.model_->layers().size() : static_cast<size_t>(t);
  }
  void ParallelRows(int rows, ThreadPool::Fn fn, void* ctx) const {
    if (s.pool_ != nullptr) {
      s.pool_->ParallelFor(rows, fn, ctx);
    } else {
      fn(ctx, 0, rows);
    }
  }
  // An int8 or bf16 step's call (Args: Int8ConvArgs or Bf16ConvArgs with conv and in set): the
  // pads, and the upsampling it fuses (then `in` is the low-resolution map).
  template <typename Args>
  Args Reduced(const Step& step, Args args) const {
    args.pads = s.geometry_[step.last_layer].pads;
    if (step.upsampled) {
      const LayerGeometry& c =
          s.geometry_[step.crop_layer >= 0 ? step.crop_layer : step.first_layer];
      args.upsampled = true;
      if (step.crop_layer >= 0) {
        args.crop_top = c.crop.top;
        args.crop_left = c.crop.left;
      }
      args.c_height = c.output.height;
      args.c_width = c.output.width;
    }
    return args;
  }
  Int8ConvArgs Int8Args(const Step& step, const ConstByteView& in) const {
    Int8ConvArgs args;
    args.conv = &step.packed8;
    args.in = in;
    return Reduced(step, args);
  }
  Bf16ConvArgs Bf16Args(const Step& step, const ConstBf16View& in) const {
    Bf16ConvArgs args;
    args.conv = &step.packed16;
    args.in = in;
    return Reduced(step, args);
  }
  // Runs `fn` over `rows` output rows and every block, split over the pool as BlockedConvJob
  // says.
  template <typename Fn, typename Args>
  void RunBlocked(Fn fn, const Args& args, int rows) const {
    const int blocks = args.conv->blocks;
    if (s.pool_ == nullptr) {
      fn(args, 0, rows, 0, blocks);
    } else {
      using Job = BlockedConvJob<Fn, Args>;
      Job job{fn, &args, rows, ConvChunks(blocks, rows, s.threads_)};
      s.pool_->ParallelFor(blocks * job.chunks, BlockedConvTrampoline<Job>, &job);
    }
  }

  // Step `at`'s output tensor in the arena, as elements of type T.
  template <typename T>
  T* OutputTensor(size_t at) const {
    return reinterpret_cast<T*>(reinterpret_cast<uint8_t*>(s.arena_) +
                                s.plan_[static_cast<size_t>(s.tensor_of_step_[at])].offset);
  }
  // Where a reduced-type step writes in its output tensor `dst`: all of it, or its slice of a
  // Concat's tensor (PlaceConcatInputs: that tensor's shape), over the extent the step writes
  // (an upsampling into a slice: only its crop's).
  template <typename T>
  PlaneView<T> OutputSlice(const Step& step, T* dst) const {
    const TensorShape* whole =
        step.slice_of < 0
            ? nullptr
            : &s.geometry_[s.steps_[static_cast<size_t>(step.slice_of)].last_layer].output;
    const TensorShape& extent = step.slice_crop >= 0
                                    ? s.geometry_[static_cast<size_t>(step.slice_crop)].output
                                    : s.geometry_[step.last_layer].output;
    return OutputPlane(dst + step.slice_channel, extent.height, extent.width, extent.channels,
                       whole);
  }

  // Step k, by the element type it writes.
  void Do(const Step& step, size_t k) {
    if (step.kind == Step::Kind::kCrop) return Crop(step, k);
    if (step.kind == Step::Kind::kToBf16 || step.kind == Step::Kind::kUpsampleBf16 ||
        step.kind == Step::Kind::kConcatBf16 ||
        (step.kind == Step::Kind::kBf16Conv && step.out_bf16)) {
      return WriteBf16(step, k);
    }
    if (step.kind == Step::Kind::kQuantize || step.kind == Step::Kind::kUpsampleU8 ||
        step.kind == Step::Kind::kConcatU8 || (step.kind == Step::Kind::kInt8Conv && step.out_u8)) {
      return WriteU8(step, k);
    }
    WriteF32(step, k);
  }
  // A view of its input (a copy only when it is the model's output).
  void Crop(const Step& step, size_t k);
  void WriteBf16(const Step& step, size_t k);
  void WriteU8(const Step& step, size_t k);
  void WriteF32(const Step& step, size_t k);
};

void Session::StepRun::Crop(const Step& step, size_t at) {
  const LayerDesc& first = s.model_->layers()[static_cast<size_t>(step.first_layer)];
  const size_t src = SlotOf(first.inputs[0]);
  const LayerGeometry& g = s.geometry_[step.last_layer];
  const size_t dst_slot = static_cast<size_t>(step.last_layer);
  Views& views = *s.views_;
  const ConstTensorView cur = views.f32[src];
  const ConstByteView cur8 = views.u8[src];
  const ConstBf16View cur16 = views.bf16[src];
  const bool last = at + 1 == s.steps_.size();
  if (step.out_u8) {
    // A uint8 tensor is never the model's output: an int8 convolution whose output no int8
    // convolution reads writes float32.
    ConstByteView view = cur8;
    view.data = cur8.pixel(g.crop.top, g.crop.left);
    view.height = g.output.height;
    view.width = g.output.width;
    views.u8[dst_slot] = view;
    return;
  }
  if (step.out_bf16) {
    ConstBf16View view = cur16;
    view.data = cur16.pixel(g.crop.top, g.crop.left);
    view.height = g.output.height;
    view.width = g.output.width;
    views.bf16[dst_slot] = view;
    return;
  }
  ConstTensorView view = cur;
  view.data = cur.pixel(g.crop.top, g.crop.left);
  view.height = g.output.height;
  view.width = g.output.width;
  if (last) {
    ref::Copy(view, DenseView(output.data(), g.output.height, g.output.width, g.output.channels));
  }
  views.f32[dst_slot] = view;
}

void Session::StepRun::WriteBf16(const Step& step, size_t at) {
  const LayerGeometry& g = s.geometry_[step.last_layer];
  const LayerDesc& first = s.model_->layers()[static_cast<size_t>(step.first_layer)];
  const size_t src = SlotOf(first.inputs[0]);
  const size_t dst_slot = static_cast<size_t>(step.last_layer);
  Views& views = *s.views_;
  const ConstTensorView cur = views.f32[src];
  const ConstBf16View cur16 = views.bf16[src];
  uint16_t* dst16 = OutputTensor<uint16_t>(at);
  Bf16View written;
  const Bf16View out16 = OutputSlice(step, dst16);
  if (step.kind == Step::Kind::kToBf16) {
    ToBf16Job job{step.to_bf16, cur, DenseBf16View(dst16, cur.height, cur.width, cur.channels)};
    ParallelRows(cur.height, ToBf16Trampoline, &job);
    written = job.out;
    views.bf16[src] = written;
  } else if (step.kind == Step::Kind::kUpsampleBf16) {
    written = out16;
    const UpsampleParams& u = s.model_->layers()[static_cast<size_t>(step.last_layer)].upsample;
    ref::UpsampleNearestPlane(cur16, u.factor_h, u.factor_w, written);
    views.bf16[dst_slot] = written;
  } else if (step.in_place) {  // the producers wrote the slices
    written = out16;
    views.bf16[dst_slot] = written;
  } else if (step.kind == Step::Kind::kConcatBf16) {
    for (size_t k = 0; k < first.inputs.size(); ++k)
      views.gather16[k] = views.bf16[SlotOf(first.inputs[k])];
    using Job = ConcatJob<ConstBf16View, Bf16View>;
    Job job{views.gather16.data(), static_cast<int>(first.inputs.size()), out16};
    ParallelRows(g.output.height, ConcatTrampoline<Job>, &job);
    written = job.out;
    views.bf16[dst_slot] = written;
  } else {
    Bf16ConvArgs args = Bf16Args(step, cur16);
    args.out_bf16 = out16;
    RunBlocked(step.fn16, args, g.output.height);
    written = args.out_bf16;
    views.bf16[dst_slot] = written;
  }
  // The slack a kernel may read past the tensor: finite (bf16_job.h). A slice of a Concat's
  // tensor has none of its own (its channels are even: no kernel reads past its pixels); the
  // Concat's is zeroed by its step.
  if (step.slice_of < 0) {
    std::memset(dst16 + static_cast<size_t>(written.height) * written.width * written.channels, 0,
                kBf16TensorSlack);
  }
}

void Session::StepRun::WriteU8(const Step& step, size_t at) {
  const LayerGeometry& g = s.geometry_[step.last_layer];
  const LayerDesc& first = s.model_->layers()[static_cast<size_t>(step.first_layer)];
  const size_t src = SlotOf(first.inputs[0]);
  const size_t dst_slot = static_cast<size_t>(step.last_layer);
  Views& views = *s.views_;
  const ConstTensorView cur = views.f32[src];
  const ConstByteView cur8 = views.u8[src];
  uint8_t* dst8 = OutputTensor<uint8_t>(at);
  const ByteView out8 = OutputSlice(step, dst8);
  if (step.kind == Step::Kind::kQuantize) {
    QuantizeJob job{step.quantize, cur, DenseByteView(dst8, cur.height, cur.width, cur.channels),
                    1.0f / step.quant.scale, step.quant.zero_point};
    ParallelRows(cur.height, QuantizeTrampoline, &job);
    views.u8[src] = job.out;
  } else if (step.kind == Step::Kind::kUpsampleU8) {
    const UpsampleParams& u = s.model_->layers()[static_cast<size_t>(step.last_layer)].upsample;
    ref::UpsampleNearestPlane(cur8, u.factor_h, u.factor_w, out8);
    views.u8[dst_slot] = out8;
  } else if (step.in_place) {  // the producers wrote the slices
    views.u8[dst_slot] = out8;
  } else if (step.kind == Step::Kind::kConcatU8) {
    for (size_t k = 0; k < first.inputs.size(); ++k)
      views.gather8[k] = views.u8[SlotOf(first.inputs[k])];
    using Job = ConcatJob<ConstByteView, ByteView>;
    Job job{views.gather8.data(), static_cast<int>(first.inputs.size()), out8};
    ParallelRows(g.output.height, ConcatTrampoline<Job>, &job);
    views.u8[dst_slot] = job.out;
  } else {
    Int8ConvArgs args = Int8Args(step, cur8);
    args.out_u8 = out8;
    RunBlocked(step.fn8, args, g.output.height);
    views.u8[dst_slot] = args.out_u8;
  }
}

void Session::StepRun::WriteF32(const Step& step, size_t at) {
  const LayerGeometry& g = s.geometry_[step.last_layer];
  const LayerDesc& first = s.model_->layers()[static_cast<size_t>(step.first_layer)];
  const size_t src = SlotOf(first.inputs[0]);
  const size_t dst_slot = static_cast<size_t>(step.last_layer);
  Views& views = *s.views_;
  const ConstTensorView cur = views.f32[src];
  const ConstByteView cur8 = views.u8[src];
  const ConstBf16View cur16 = views.bf16[src];
  const bool last = at + 1 == s.steps_.size();
  float* dst =
      last ? output.data()
           : s.arena_ + s.plan_[static_cast<size_t>(s.tensor_of_step_[at])].offset / sizeof(float);
  const TensorView out = DenseView(dst, g.output.height, g.output.width, g.output.channels);
  switch (step.kind) {
    case Step::Kind::kConv:
    case Step::Kind::kUpConv: {
      ConvArgs args;
      args.conv = &step.packed;
      args.in = cur;
      args.out = out;
      args.pads = g.pads;
      if (step.kind == Step::Kind::kUpConv) {
        const LayerGeometry& c =
            s.geometry_[step.crop_layer >= 0 ? step.crop_layer : step.first_layer];
        if (step.crop_layer >= 0) {
          args.crop_top = c.crop.top;
          args.crop_left = c.crop.left;
        }
        args.c_height = c.output.height;
        args.c_width = c.output.width;
      }
      if (step.upwinograd != nullptr) {
        RunUpWinogradBands(
            *step.upwinograd, step.wpacked, step.band_rows,
            s.arena_ + step.scratch_offset / sizeof(float), args,
            [this](int rows, ThreadPool::Fn fn, void* ctx) { ParallelRows(rows, fn, ctx); });
        args.skip_interior = true;
      }
      if (step.kind == Step::Kind::kConv) {
        args.rows_first = ConvRowsFirst(step.packed, cur, out.height);
      }
      if (s.pool_ == nullptr) {
        step.fn(args, 0, out.height, 0, step.packed.blocks);
      } else if (args.rows_first) {
        ConvJob job{step.fn, &args, out.height, 1};
        s.pool_->ParallelFor(out.height, RowsFirstTrampoline, &job);
      } else {
        ConvJob job{step.fn, &args, out.height,
                    ConvChunks(step.packed.blocks, out.height, s.threads_)};
        s.pool_->ParallelFor(step.packed.blocks * job.chunks, BlockedConvTrampoline<ConvJob>, &job);
      }
      break;
    }
    case Step::Kind::kWinograd:
      RunWinogradBands(
          *step.winograd, step.wpacked, step.band_rows,
          s.arena_ + step.scratch_offset / sizeof(float), cur, out, g.pads,
          [this](int rows, ThreadPool::Fn fn, void* ctx) { ParallelRows(rows, fn, ctx); });
      break;
    case Step::Kind::kRows: {
      for (size_t k = 0; k < first.inputs.size(); ++k) {
        views.gather[k] = views.f32[SlotOf(first.inputs[k])];
      }
      RowsJob job{step.rows,
                  {&first, &g, views.gather.data(), static_cast<int>(first.inputs.size()), out}};
      ParallelRows(out.height, RowsTrampoline, &job);
      break;
    }
    case Step::Kind::kUpsample: {
      const UpsampleParams& u = s.model_->layers()[static_cast<size_t>(step.last_layer)].upsample;
      ref::UpsampleNearest(cur, u.factor_h, u.factor_w, out);
      break;
    }
    case Step::Kind::kInt8Conv: {  // float32 output
      Int8ConvArgs args = Int8Args(step, cur8);
      args.out_f32 = out;
      RunBlocked(step.fn8, args, out.height);
      break;
    }
    case Step::Kind::kBf16Conv: {  // float32 output
      Bf16ConvArgs args = Bf16Args(step, cur16);
      args.out_f32 = out;
      RunBlocked(step.fn16, args, out.height);
      break;
    }
    case Step::Kind::kCrop:
    case Step::Kind::kQuantize:
    case Step::Kind::kUpsampleU8:
    case Step::Kind::kConcatU8:
    case Step::Kind::kConcatBf16:
    case Step::Kind::kToBf16:
    case Step::Kind::kUpsampleBf16:
      break;
  }
  views.f32[dst_slot] = out;
}

Status Session::Execute(std::span<const float> input, const uint8_t* input_u8, int height,
                        int width, std::span<float> output, std::span<int64_t> step_end_ns,
                        Observation* observation) {
  if (!step_end_ns.empty() && step_end_ns.size() < steps_.size() + 1) {
    return Status::Error("step timestamp buffer holds " + std::to_string(step_end_ns.size()) +
                         " values; this plan needs " + std::to_string(steps_.size() + 1));
  }
  const bool timed = !step_end_ns.empty();
  auto stamp = [&](size_t k) {
    step_end_ns[k] = std::chrono::duration_cast<std::chrono::nanoseconds>(
                         std::chrono::steady_clock::now().time_since_epoch())
                         .count();
  };
  if (height <= 0 || width <= 0 || height > options_.max_height || width > options_.max_width) {
    return Status::Error("input " + std::to_string(height) + "x" + std::to_string(width) +
                         " is outside the session's planned range 1x1.." +
                         std::to_string(options_.max_height) + "x" +
                         std::to_string(options_.max_width));
  }
  if (Status s = InferGeometry(*model_, height, width, geometry_); !s.ok()) return s;
  const TensorShape in_shape = geometry_.front().input;
  const TensorShape out_shape = geometry_.back().output;
  if (input_u8 == nullptr && input.size() < in_shape.elements()) {
    return Status::Error("input buffer holds " + std::to_string(input.size()) + " floats; " +
                         std::to_string(height) + "x" + std::to_string(width) + "x" +
                         std::to_string(in_shape.channels) + " needs " +
                         std::to_string(in_shape.elements()));
  }
  if (output.size() < out_shape.elements()) {
    return Status::Error("output buffer holds " + std::to_string(output.size()) + " floats; " +
                         "the output needs " + std::to_string(out_shape.elements()));
  }

  const auto layers = model_->layers();
  const TensorShape& in = geometry_.front().input;
  views_->f32[layers.size()] = {input.data(), in.height, in.width, in.channels,
                                static_cast<ptrdiff_t>(in.width) * in.channels};
  // The quantised input is what the quantise step would have written.
  const size_t skipped = input_u8 != nullptr ? static_cast<size_t>(input_quantize_step_) : SIZE_MAX;
  if (input_u8 != nullptr) {
    views_->u8[layers.size()] = {input_u8, in.height, in.width, in.channels,
                                 static_cast<ptrdiff_t>(in.width) * in.channels};
  }
  StepRun run{*this, output};
  if (timed) stamp(0);
  for (size_t k = 0; k < steps_.size(); ++k) {
    const Step& step = steps_[k];
    if (k != skipped) run.Do(step, k);
    // After the step: its timestamp, and what RunObserved shows.
    if (timed) stamp(k + 1);
    if (observation != nullptr) {
      Observe(step, run.SlotOf(layers[static_cast<size_t>(step.first_layer)].inputs[0]),
              *observation);
    }
  }
  return Status::Ok();
}

}  // namespace sfrt
