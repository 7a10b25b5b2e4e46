// Session: runs a Model's forward pass with all memory planned at creation.
//
// Create() infers every layer's shape for the largest input the session must accept
// (SessionOptions::max_height x max_width), plans one arena for all intermediate tensors
// (see memory_planner.h) and allocates it once. Run() accepts any input size up to that maximum
// and performs no heap allocation, no I/O and takes no lock on success. With threads > 1 it makes
// no system call either while the pool's waits stay within SessionOptions::spin_us.
//
// Ownership: a Session shares ownership of its Model; the input and output buffers belong to the
// caller and are only accessed during Run().
// Graphs (schema 1.5): each step reads the tensors its layer names; a tensor stays in the arena
// until its last reader has run, and a fusion applies only where the fused layers' outputs have
// no other reader.
// Kernels: Create() also chooses the instruction set (SessionOptions::isa, see sfrt/isa.h),
// packs every convolution's weights for it into memory the session owns (allocated once), fuses
// each nearest-2x upsample (+ crop) into the 3x3 convolution that reads it (optimised ISAs only;
// the upsampled tensor then never exists), and records the plan as a flat list of steps with
// kernel function pointers. Run() walks that list. With threads > 1, Create() starts a fixed
// pool and Run() splits each step over it: SIMD convolutions into (output-channel block x row
// range) items, block-major, so the threads share a block's weights in cache and write disjoint
// outputs, except float32 ones that read fewer bytes rows first (a large input, small weights:
// kernels/conv_job.h, ConvArgs::rows_first), split by output rows with every block in each
// item; other steps by output rows.
//
// Precision: each convolution runs in the precision its model file gives it (sfrt/model.h,
// Precision). Int8 convolutions run on the ISA's int8 kernels where it has them (AVX-512 VNNI,
// NEON dot products), otherwise on the scalar reference int8 kernel (steps() names it); both give
// the same bytes. Bf16 convolutions run on the ISA's bf16 kernels where it has them (AVX512_BF16,
// NEON BF16), otherwise on the scalar reference bf16 kernel. Tensors between two convolutions of
// the same reduced precision stay uint8 or bf16; a float32 tensor that an int8 or bf16
// convolution reads is converted once by a step of its own.
// Thread-safety: a Session is not thread-safe (Run() writes its arena). Use one Session per
// thread; Sessions created from the same Model share its weights.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "sfrt/isa.h"
#include "sfrt/layer_observer.h"
#include "sfrt/model.h"
#include "sfrt/shapes.h"
#include "sfrt/status.h"

namespace sfrt {

struct BufferRequest;  // runtime/src/memory_planner.h

// Switches for the optimised paths, for A/B measurements and tests; the defaults are the fastest
// measured. Every combination computes the same function (within the kernels' tolerances).
// The library reads no environment variable: the `sfrt` tool maps SFRT_WINOGRAD=auto|off|f2|f4,
// SFRT_WINOGRAD_UPCONV=off, SFRT_FEWOUT=off, SFRT_CONCAT_IN_PLACE=off and SFRT_AMX_PAIRS=off
// onto these fields.
struct KernelTuning {
  // Winograd tile side for the stride-1 3x3 convolutions it suits: 0 (off), 2 (F(2x2,3x3)), 4
  // (F(4x4,3x3)) or kWinogradAuto (per layer: 4 where its output at the planned maximum size is
  // at least kWinogradAutoMinSide pixels on each side, else 2). Other values fail Create().
  // F(4x4) does 1.78x fewer products than F(2x2) at about the same float32 error (both within
  // 5e-6 of PyTorch's largest output on the full-width network), but rounds small outputs up to
  // whole 4x4 tiles, and its transformed weights take 36/16 of F(2x2)'s memory (the full-width
  // network: 120 MiB more). Measured on Zen 4 (AVX2 and AVX-512, 2 threads; `sfrt bench
  // --tuning default --tuning winograd=f2`): the full-width network at 540x960, conv4 and conv5
  // (34x60 outputs) 0.59-0.69x F(2x2)'s time, the network 0.89-0.93x; at 270x480 (17x30) 0.72-0.75x
  // and 0.94x; the 1/16-width default model's conv4 and conv5 at 96x128 (6x8) 1.1-1.2x.
  static constexpr int kWinogradAuto = -1;
  static constexpr int kWinogradAutoMinSide = 16;
  int winograd_tile = kWinogradAuto;
  // The fused upsample->conv phase convolutions through Winograd F(2x2,2x2) (needs a tile > 0).
  bool winograd_upconv = true;
  // The dedicated kernels for convolutions with few outputs (the 64->3 output layer), in every
  // precision that has them (float32; int8 and bf16 on AVX-512). false: the tiles compute them.
  bool few_out = true;
  // uint8 and bf16 Concats in place (docs/model-format.md, "The graph"): no copy, but each Concat's
  // whole tensor lives from its first input's producer on, so the arena can grow (SceneEDNet-U's
  // decoder halves are reserved through the encoder). false: every Concat copies.
  bool concat_in_place = true;
  // The AMX kernels' 2 x 2 tile blocking where a convolution's input channels are a multiple of
  // 64 (kernels/simd/amx_driver_inl.h). false: the 1 x 4 blocking everywhere, as before it. The
  // one default here not yet measured to be the faster: it awaits an AMX CPU (issue 43).
  bool amx_pairs = true;

  bool operator==(const KernelTuning&) const = default;
};

struct SessionOptions {
  int max_height = 540;
  int max_width = 960;
  // kAuto: BestIsa(). Asking for an ISA this CPU cannot run fails Create(). (The `sfrt` tool
  // maps SFRT_ISA=ref|avx2|avx512|avx512amx|neon onto this field.)
  Isa isa = Isa::kAuto;
  int threads = 1;           // threads Run() uses, the caller's included; 0: one per CPU
  bool pin_threads = false;  // bind thread i to the i-th CPU this process may use
  // With threads > 1: how long, in microseconds, a waiting thread (a worker between steps, or
  // Run() waiting for a chunk a worker runs) busy-waits before it sleeps in the kernel. While
  // waits stay within it, Run() makes no system call. < 0: never sleep (cores reserved for
  // inference); 0: sleep at once (least CPU, a wake-up per worker per step). Run() never waits
  // for a worker that has not started: it does the unclaimed work itself. See
  // runtime/src/thread_pool.h.
  int spin_us = 200;
  KernelTuning tuning{};
};

// One entry of the flat list Run() walks.
struct PlannedStep {
  // The model layers this step computes, [first_layer, last_layer]. A step that converts the
  // float32 tensor an int8 or bf16 convolution reads (quantises it to uint8, or rounds it to
  // bf16) computes no layer: first_layer = last_layer = the layer it precedes, `quantize` is set
  // and `precision` is the one it converts to.
  int first_layer = 0;
  int last_layer = 0;
  const char* kernel = "";  // e.g. "conv2d_f32__avx512_8x32", "ref::Conv2d", "view"
  Precision precision = Precision::kFloat32;  // the arithmetic of its convolution (if any)
  bool quantize = false;                      // the converting step described above
};

// Where each planned tensor lives in the arena (for `--print-plan` and tests).
struct PlannedTensor {
  int producer = -1;       // index of the layer that writes it (quantised tensors: the layer
                           // whose output they quantise; -1 for the model input; a Concat in
                           // place: the first layer that writes a slice of it)
  int last_consumer = -1;  // index of the last layer that reads it
  size_t offset = 0;       // bytes from the arena start
  size_t bytes = 0;        // at the maximum input size
  bool is_u8 = false;      // uint8 (an int8 convolution's input)
  bool is_bf16 = false;    // bf16 (a bf16 convolution's input); float32 when neither
};

// The int8 runtime's quantisation of a float32 value to uint8 (kernels/int8_job.h): round half
// to even of value / q.scale (as value * (1 / q.scale), clamped to +-512 first), plus the zero
// point, clamped to 0..255; NaN gives 0. What the quantise step computes, so a
// table of it lets a caller feed RunQuantized() bit for bit.
uint8_t QuantizeInput(float value, const QuantParams& q);

// Bytes past the end of a quantised input RunQuantized() may read (Session::QuantizedInputBytes).
inline constexpr size_t kQuantizedInputSlack = 64;

// The work one planned step does at one input size, for rooflines (`sfrt bench`): what its
// algorithm computes and the bytes it must move at least (each tensor and weight once).
struct StepWork {
  // Multiply-accumulates the step's algorithm does: a direct convolution's, except that a fused
  // upsample->3x3 convolution with phase kernels counts its interior pixels at their 4 taps
  // (4/9 of the nominal work; the exact shortcut the kernels take), and a Winograd step counts
  // its transformed products (alpha^2 per m x m tile and channel pair: F(2x2, 3x3) 16 for 4
  // pixels, the phases' F(2x2, 2x2) 9 per phase tile), not its transforms' additions. 0 for a
  // step that only moves data.
  uint64_t macs = 0;
  uint64_t bytes_read = 0;     // activations read, in the type the step reads them
  uint64_t bytes_written = 0;  // activations written, in the type the step writes
  uint64_t weight_bytes = 0;   // weights in the step's precision (phase kernels included)
  uint64_t bytes() const { return bytes_read + bytes_written + weight_bytes; }
};

class Session {
 public:
  static Result<std::unique_ptr<Session>> Create(std::shared_ptr<const Model> model,
                                                 const SessionOptions& options);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  // Output shape for an input of height x width. Allocates nothing on success (only an error's
  // message is built on the heap). Not thread-safe (a graph model's uses session scratch).
  Result<TensorShape> OutputShape(int height, int width) const;

  // input: height x width x input channels, NHWC float32 in the model's channel order.
  // output: OutputShape(height, width).elements() floats (or more), NHWC.
  // Fails (allocating only for the message) if the size exceeds the planned maximum or a buffer
  // is too small.
  Status Run(std::span<const float> input, int height, int width, std::span<float> output);

  // As above, and records when each planned step ended, for profiling without allocation:
  // step_end_ns[0] is taken as Run() starts its first step, step_end_ns[k + 1] when steps()[k]
  // has finished, in nanoseconds of std::chrono::steady_clock (CLOCK_MONOTONIC on Linux), so
  // the timestamps line up with the caller's own stages. step_end_ns must hold
  // steps().size() + 1 values; on failure its contents are unspecified.
  Status Run(std::span<const float> input, int height, int width, std::span<float> output,
             std::span<int64_t> step_end_ns);

  // The uint8 input path: camera pixels are 8-bit already, so a caller can write the network's
  // input as the uint8 its first int8 convolutions read (camera::Preprocessor tabulates it) and
  // skip the float32 round trip and the quantise step. Set when the model input is read only by
  // one step that quantises it (every layer that reads the input is int8, with one input
  // quantisation): the quantisation that step applies, value -> QuantizeInput(value, it).
  std::optional<QuantParams> InputQuantization() const;
  // The bytes RunQuantized() reads at height x width: the input's elements, and
  // kQuantizedInputSlack more when its channel count is not a multiple of 4 (the kernels read
  // four channels at a time; the extra bytes multiply zero weights).
  size_t QuantizedInputBytes(int height, int width) const;
  // As Run(), from the input quantised with InputQuantization() (height x width x channels
  // uint8, NHWC, QuantizedInputBytes() long): the quantise step does nothing (its timestamp is
  // still taken), and the output is Run()'s, bit for bit, on any float input that quantises to
  // these bytes. Allocates nothing on success; fails when InputQuantization() is empty.
  Status RunQuantized(std::span<const uint8_t> input, int height, int width,
                      std::span<float> output, std::span<int64_t> step_end_ns = {});

  // As Run(), and shows `observer` the output of each step's last layer after the step, in
  // step order, on the calling thread (sfrt/layer_observer.h): the tensor as this session holds
  // it (a uint8 tensor dequantised with the quantisation it was written with, a bf16 one
  // widened, a strided view copied dense). Layers a step fuses before its last (a nearest
  // upsampling and crop that a convolution reads through) have no tensor and are not shown; nor
  // are the steps that convert a float32 tensor for an int8 or bf16 convolution, nor an
  // upsampling that writes only the crop a Concat in place takes of it (the crop is shown). A
  // Concat is shown once all its inputs are written. For calibration and debugging: this call
  // allocates (the dequantised copies, kept for the next call), unlike Run().
  Status RunObserved(std::span<const float> input, int height, int width, std::span<float> output,
                     const LayerObserver& observer);

  // One entry per steps() for an input of height x width (at most the planned maximum), as
  // Run() does it, or, with `quantized_input`, as RunQuantized() does (the input's quantise step
  // then does nothing). For profiling: it allocates, so keep it off the per-frame path.
  Result<std::vector<StepWork>> Work(int height, int width, bool quantized_input = false) const;

  const Model& model() const { return *model_; }
  const SessionOptions& options() const { return options_; }
  size_t arena_bytes() const { return arena_bytes_; }
  std::span<const PlannedTensor> plan() const { return plan_; }
  Isa isa() const { return isa_; }
  int threads() const { return threads_; }
  std::span<const PlannedStep> steps() const { return step_info_; }
  // Bytes of weights packed for the chosen kernels (0 on the reference path), int8 layers'
  // included.
  size_t packed_weight_bytes() const { return packed_bytes_ + packed8_bytes_; }

 private:
  struct Step;
  struct Views;
  struct Observation;
  struct StepRun;      // one Run() over the steps
  struct WorkCounter;  // Work()'s accounting (step_work.cc)
  // The input is `input`, or, when `input_u8` is not null, the quantised input (RunQuantized).
  Status Execute(std::span<const float> input, const uint8_t* input_u8, int height, int width,
                 std::span<float> output, std::span<int64_t> step_end_ns, Observation* observation);
  void FindInputQuantizeStep();  // Plan, step 4: input_quantize_step_
  void Observe(const Step& step, size_t src_slot, Observation& observation) const;
  class Pool;
  Session() = default;
  Status Plan();
  class StepPlanner;
  size_t PlanSteps();                 // Plan, step 1 (step_planner.cc)
  void PlaceConcatInputs();           // Plan, step 1b
  Status PackWeights();               // Plan, step 2
  Status PackFloatWeights();          // Plan, step 2a
  Status PackReducedWeights();        // Plan, step 2b: int8 and bf16
  Status PlanTensors(size_t gather);  // Plan, step 3
  class TensorLifetimes;              // Plan, step 3: the tensors' arena requests
  static bool HasScratch(const Step& step);
  void RequestScratch(std::vector<BufferRequest>& requests);  // Plan, step 3b
  std::shared_ptr<const Model> model_;
  SessionOptions options_;
  std::vector<PlannedTensor> plan_;      // one per layer output, except the last and crops
  std::vector<LayerGeometry> geometry_;  // scratch for Run(), sized at creation
  std::vector<int> tensor_of_step_;      // step -> index into plan_ (-1: none)
  std::unique_ptr<Views> views_;         // where each tensor is during Run(), sized at creation
  mutable std::vector<LayerGeometry> shape_scratch_;  // OutputShape() of a graph model
  size_t arena_bytes_ = 0;
  float* arena_ = nullptr;  // 64-byte aligned, arena_bytes_ long
  Isa isa_ = Isa::kRef;
  int threads_ = 1;
  std::vector<Step> steps_;
  std::vector<PlannedStep> step_info_;
  int input_quantize_step_ = -1;  // the one step that reads the model input, quantising it
  size_t packed_bytes_ = 0;
  float* packed_ = nullptr;  // 64-byte aligned packed weights
  size_t packed8_bytes_ = 0;
  void* packed8_ = nullptr;  // 64-byte aligned int8 and bf16 packings (int8_, bf16_packing.h)
  std::unique_ptr<Pool> pool_;
  std::unique_ptr<Observation> observation_;  // RunObserved's, from its first call
};

}  // namespace sfrt
