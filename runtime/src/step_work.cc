// Session::Work: what each planned step computes and moves at one input size (session.h,
// StepWork), read off the plan and the layers' geometry; for rooflines, never on Run()'s path.
#include <algorithm>
#include <string>

#include "session_steps.h"
#include "winograd_run.h"

namespace sfrt {
namespace {

// Bytes per element of the tensors a step reads and writes.
struct ElementSizes {
  uint64_t in = 4;
  uint64_t out = 4;
};

uint64_t WeightElementBytes(Precision precision) {
  return precision == Precision::kInt8 ? 1 : precision == Precision::kBFloat16 ? 2 : 4;
}

// Output rows (or columns) whose 3-tap window lies inside a map of `c_extent` after `pad_before`
// padding: the pixels a phase kernel computes along one axis.
uint64_t InteriorExtent(int out_extent, int c_extent, int pad_before) {
  const int first = std::max(0, pad_before);
  const int last = std::min(out_extent - 1, c_extent - 3 + pad_before);
  return last >= first ? static_cast<uint64_t>(last - first + 1) : 0;
}

}  // namespace

// The step-kind facts Work() needs; Session's own, as Step is private.
struct Session::WorkCounter {
  using Kind = Step::Kind;
  static ElementSizes SizesOf(const Step& step);
  static bool HasPhases(const Step& step);
  static bool IsConvolution(Kind kind);
};

ElementSizes Session::WorkCounter::SizesOf(const Step& step) {
  const uint64_t out = step.out_u8 ? 1 : step.out_bf16 ? 2 : 4;
  switch (step.kind) {
    case Kind::kQuantize:
    case Kind::kToBf16:
      return {4, out};
    case Kind::kInt8Conv:
    case Kind::kUpsampleU8:
    case Kind::kConcatU8:
      return {1, out};
    case Kind::kBf16Conv:
    case Kind::kUpsampleBf16:
    case Kind::kConcatBf16:
      return {2, out};
    default:
      return {4, out};
  }
}

// Whether the step's fused upsample-conv computes its interior through phase kernels.
bool Session::WorkCounter::HasPhases(const Step& step) {
  switch (step.kind) {
    case Kind::kUpConv:  // direct phase kernels, or the phases through Winograd
      return step.packed.phase_weights != nullptr || step.upwinograd != nullptr;
    case Kind::kInt8Conv:
      return step.upsampled && step.packed8.phase_weights_hwio != nullptr;
    case Kind::kBf16Conv:
      return step.upsampled && step.packed16.phase_weights_hwio != nullptr;
    default:
      return false;
  }
}

bool Session::WorkCounter::IsConvolution(Kind kind) {
  return kind == Kind::kConv || kind == Kind::kUpConv || kind == Kind::kWinograd ||
         kind == Kind::kInt8Conv || kind == Kind::kBf16Conv || kind == Kind::kRows;
}

Result<std::vector<StepWork>> Session::Work(int height, int width, bool quantized_input) const {
  if (height > options_.max_height || width > options_.max_width) {
    return Status::Error("input " + std::to_string(height) + "x" + std::to_string(width) +
                         " exceeds the session's maximum " + std::to_string(options_.max_height) +
                         "x" + std::to_string(options_.max_width));
  }
  std::vector<LayerGeometry> geometry(model_->layers().size());
  if (Status s = InferGeometry(*model_, height, width, geometry); !s.ok()) return s;
  const auto layers = model_->layers();
  auto tensor_elements = [&](int t) -> uint64_t {
    return t == kModelInput ? geometry.front().input.elements()
                            : geometry[static_cast<size_t>(t)].output.elements();
  };
  using Kind = Step::Kind;
  std::vector<StepWork> work(steps_.size());
  for (size_t k = 0; k < steps_.size(); ++k) {
    const Step& step = steps_[k];
    const ElementSizes size = WorkCounter::SizesOf(step);
    const LayerDesc& first = layers[static_cast<size_t>(step.first_layer)];
    const LayerGeometry& g = geometry[static_cast<size_t>(step.last_layer)];
    StepWork& w = work[k];
    uint64_t read = 0;
    for (int t : first.inputs) read += tensor_elements(t);
    if (quantized_input && static_cast<int>(k) == input_quantize_step_) continue;  // skipped
    if (step.converts()) {
      w.bytes_read = read * size.in;  // converts its input in place of the layer reading it
      w.bytes_written = read * size.out;
      continue;
    }
    const bool copies = step.kind != Kind::kCrop || k + 1 == steps_.size();
    if (step.in_place || !copies) continue;  // a view: nothing moves
    w.bytes_read = read * size.in;
    w.bytes_written = g.output.elements() * size.out;
    if (!WorkCounter::IsConvolution(step.kind)) continue;
    for (int i = step.first_layer; i <= step.last_layer; ++i) {
      w.macs += geometry[static_cast<size_t>(i)].macs;
    }
    const LayerDesc& conv = layers[static_cast<size_t>(step.last_layer)];
    if (conv.kind != LayerKind::kConv2D) continue;
    const ConvParams& p = conv.conv;
    const uint64_t per_tap = static_cast<uint64_t>(p.in_channels / std::max(1, p.groups)) *
                             static_cast<uint64_t>(p.out_channels);
    const uint64_t taps = static_cast<uint64_t>(p.kernel_h) * static_cast<uint64_t>(p.kernel_w);
    w.weight_bytes = taps * per_tap * WeightElementBytes(step.precision);
    if (step.kind == Kind::kWinograd) {  // the products of every m x m tile: alpha^2 points
      const PackedWinograd& wp = step.wpacked;
      const uint64_t tiles = static_cast<uint64_t>(WinogradTiles(g.output.height, wp.m)) *
                             static_cast<uint64_t>(WinogradTiles(g.output.width, wp.m));
      w.macs = tiles * static_cast<uint64_t>(wp.alpha * wp.alpha) * per_tap;
      w.weight_bytes = static_cast<uint64_t>(wp.alpha * wp.alpha) * per_tap * sizeof(float);
      continue;
    }
    if (!WorkCounter::HasPhases(step)) continue;
    const LayerGeometry& c =
        geometry[static_cast<size_t>(step.crop_layer >= 0 ? step.crop_layer : step.first_layer)];
    const uint64_t interior = InteriorExtent(g.output.height, c.output.height, g.pads.top) *
                              InteriorExtent(g.output.width, c.output.width, g.pads.left);
    w.macs -= interior * (taps - 4) * per_tap;  // those pixels take the 4 taps of their phase
    if (step.upwinograd == nullptr) {
      w.weight_bytes += 4 * 4 * per_tap * WeightElementBytes(step.precision);
    } else {  // the interior through F(2x2, 2x2) on the phases instead
      w.weight_bytes += static_cast<uint64_t>(step.wpacked.alpha * step.wpacked.alpha) * 4 *
                        per_tap * sizeof(float);
      const int crop_top = step.crop_layer >= 0 ? c.crop.top : 0;
      const int crop_left = step.crop_layer >= 0 ? c.crop.left : 0;
      const UpGrid u = UpGridOf(g.output.height, g.output.width, g.pads, c.output.height,
                                c.output.width, crop_top, crop_left);
      const PackedWinograd& wp = step.wpacked;
      w.macs -= interior * 4 * per_tap;
      w.macs += static_cast<uint64_t>(u.tiles_h) * static_cast<uint64_t>(u.tiles_w) *
                static_cast<uint64_t>(wp.alpha * wp.alpha) * 4 * per_tap;  // the 4 phases' products
    }
  }
  return work;
}

}  // namespace sfrt
