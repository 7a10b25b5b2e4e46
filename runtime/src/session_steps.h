// Session's inside, shared by its planning (session.cc) and its running (session_run.cc): the
// steps Plan() makes and Run() walks, the tensor views, the observer's state, the pool. Not an
// API.
#pragma once

#include <vector>

#include "bf16_packing.h"
#include "conv_packing.h"
#include "int8_packing.h"
#include "kernels/bf16_job.h"
#include "kernels/conv_job.h"
#include "kernels/int8_job.h"
#include "kernels/winograd_job.h"
#include "ops/layer_op.h"
#include "sfrt/session.h"
#include "thread_pool.h"
#include "winograd_packing.h"

namespace sfrt {

// One entry of the flat list Run() walks.
struct Session::Step {
  enum class Kind {
    kRows,          // a float32 layer's rows as its kind's unit computes them (ops/layer_op.h):
                    // every kind without a faster step, the reference convolution included
    kConv,          // SIMD convolution (packed weights)
    kUpConv,        // SIMD fused upsample 2x (+ crop) + 3x3 convolution
    kUpsample,      // ref::UpsampleNearest
    kCrop,          // a view of the previous tensor (a copy only when it is the model's output)
    kWinograd,      // SIMD Winograd F(m x m, 3 x 3) convolution (kernels/winograd_job.h)
    kQuantize,      // the float32 tensor an int8 convolution reads, to uint8 (ref::QuantizeRows)
    kInt8Conv,      // int8 convolution, fused with the upsample (+ crop) before it when crop_layer
                    // or first_layer says so (kernels/int8_job.h)
    kUpsampleU8,    // ref::UpsampleNearestPlane (an upsampling no int8 convolution fuses)
    kToBf16,        // the float32 tensor a bf16 convolution reads, to bf16 (ToBf16KernelFor)
    kBf16Conv,      // bf16 convolution, fused with the upsample (+ crop) before it as kInt8Conv
                    // (kernels/bf16_job.h)
    kUpsampleBf16,  // ref::UpsampleNearestPlane (an upsampling no bf16 convolution fuses)
    kConcatU8,      // ref::ConcatRows on uint8 tensors (a graph's, PlanReducedTensors)
    kConcatBf16,    // ref::ConcatRows on bf16 tensors (likewise)
  };
  Kind kind = Kind::kRows;
  // A converting step: the float32 tensor a reduced-precision step reads, to uint8 or bf16.
  bool converts() const { return kind == Kind::kQuantize || kind == Kind::kToBf16; }
  int first_layer = 0;
  int last_layer = 0;
  int crop_layer = -1;  // kUpConv: the crop between upsample and convolution, if any
  ConvRowsFn fn = nullptr;
  PackedConv packed;
  ops::LayerRowsFn rows = nullptr;  // kRows
  const char* kernel = "";
  const WinogradKernels* winograd = nullptr;  // kWinograd
  PackedWinograd wpacked;
  size_t scratch_offset = 0;  // kWinograd, upwinograd: bytes from the arena start of v and m
  // kUpConv on the Winograd phase path (interior pixels; the direct kernel does the border):
  const WinogradKernels* upwinograd = nullptr;
  // kWinograd and upwinograd: tile rows per pass, so that v and m stay small (planned at Create)
  int band_rows = 0;
  bool out_u8 = false;    // the step writes uint8
  bool out_bf16 = false;  // the step writes bf16 (float32 when neither)
  Precision precision = Precision::kFloat32;
  // kInt8Conv:
  Int8ConvRowsFn fn8 = nullptr;
  PackedInt8Conv packed8;
  bool upsampled = false;  // reads the nearest-2x upsampling of its input (first_layer)
  // kBf16Conv:
  Bf16ConvRowsFn fn16 = nullptr;
  PackedBf16Conv packed16;
  // kQuantize: what it quantises with; kInt8Conv writing uint8: what its output is quantised
  // with (a chain's output_quant, or a graph's PlanReducedTensors quantisation).
  QuantParams quant;
  QuantizeRowsFn quantize = nullptr;
  // kToBf16:
  ToBf16RowsFn to_bf16 = nullptr;
  // A uint8 Concat in place (Plan, 1b): the Concat step does nothing (in_place), and each step
  // that writes one of its inputs writes it into its slice of the Concat's tensor: slice_of is
  // the Concat step's index, slice_channel the slice's first channel; an upsampling whose crop
  // (slice_crop, keeping the top-left corner) is the input writes only the crop's extent.
  bool in_place = false;
  int slice_of = -1;
  int slice_channel = 0;
  int slice_crop = -1;
};

// Where each tensor is at the size being run: per layer output and element type (the model input
// in the last slot), and a Concat's input views.
struct Session::Views {
  std::vector<ConstTensorView> f32;
  std::vector<ConstByteView> u8;
  std::vector<ConstBf16View> bf16;
  std::vector<ConstTensorView> gather;
  std::vector<ConstByteView> gather8;
  std::vector<ConstBf16View> gather16;
};

// RunObserved()'s state, made by its first call: the observer, the quantisation each uint8 tensor
// slot was written with (indexed as Views), and the dense float32 copy the observer is shown
// (grown to the largest tensor copied, then reused).
struct Session::Observation {
  const LayerObserver* observer = nullptr;
  std::vector<QuantParams> quant;
  std::vector<float> values;
};

class Session::Pool : public ThreadPool {
 public:
  using ThreadPool::ThreadPool;
};

}  // namespace sfrt
