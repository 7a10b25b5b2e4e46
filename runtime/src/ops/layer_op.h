// A layer kind as one unit: everything the runtime does with a kind lives in its own file
// (ops/<kind>.cc) and is found through one table (ops/registry.cc), as TensorFlow Lite Micro's op
// resolver finds an op's registration. Adding a kind is its unit, one line in the table and, where
// the file format changes, the schema.
//
// What a unit holds: how it is read and checked from the model file (parse), its shape rule at a
// given input size (geometry), how it computes output rows in float32 (rows: the reference
// execution, and the session's step for every kind that has no faster kernel), and how it is
// described (sfrt inspect, profiles). How a kind is planned into the session's fused and
// reduced-precision steps stays in Session::Plan, as named rules (session.cc), because those
// rules join several kinds.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "kernels/tensor_view.h"
#include "ops/layer_reader.h"
#include "sfrt/layer_kinds.h"
#include "sfrt/model.h"
#include "sfrt/shapes.h"
#include "sfrt/status.h"

namespace sfrt::ops {

// What a shape rule reads: the shapes of the tensors the layer reads, and the model input's size
// (a crop to the input size).
struct GeometryInputs {
  size_t index = 0;  // the layer's, for messages
  int height = 0;    // the model input's
  int width = 0;
  TensorShape model_input;                 // the model input's shape
  std::span<const LayerGeometry> earlier;  // the layers before it; empty for a chain walk
  TensorShape first;                       // the shape of the layer's first input

  // The shape of tensor t (kModelInput or an earlier layer). A chain walk has no earlier layers'
  // geometry, and no layer of a chain reads anything but the one before it.
  TensorShape Of(int t) const {
    if (t == kModelInput) return model_input;
    return static_cast<size_t>(t) < earlier.size() ? earlier[static_cast<size_t>(t)].output
                                                   : TensorShape{};
  }
};

// Output rows [begin, end) of a layer computed in float32: its inputs (one view per
// LayerDesc::inputs entry), its geometry at this size, the whole output.
struct LayerRows {
  const LayerDesc* layer = nullptr;
  const LayerGeometry* geometry = nullptr;
  const ConstTensorView* inputs = nullptr;
  int input_count = 0;
  TensorView out;
};
using LayerRowsFn = void (*)(const LayerRows& rows, int begin, int end);

struct LayerOp {
  LayerKind kind;
  const char* name;  // the schema's op name
  // Runs in float32 only (Float32OnlyKind): a model with one keeps float32 between its layers.
  bool float32_only;
  // The schema's union members this kind is stored as (the second: its V2 form, or NONE).
  schema::LayerOp stored[2];
  // Fills `layer`'s kind and parameters from the stored op (layer.inputs are resolved already) and
  // returns the output's channel count in `out_channels`; errors name the layer and field.
  Status (*parse)(LayerReader& reader, LayerDesc& layer, int* out_channels);
  // Fills `g` (output shape, pads or crop, MACs, parameters) at this size; errors name the layer.
  Status (*geometry)(const LayerDesc& layer, const GeometryInputs& in, LayerGeometry& g);
  uint64_t (*parameters)(const LayerDesc& layer);
  LayerRowsFn rows;
  const char* rows_kernel;  // the name profiles show for `rows`: "ref::PoolRows"
  std::string (*describe)(const LayerDesc& layer, LayerText detail);
  std::string (*padding)(const LayerDesc& layer, const LayerGeometry& g);
};

// The unit of a kind; the table holds every kind (a test checks it).
const LayerOp& OpOf(LayerKind kind);
// The unit stored as union member `stored`; null for NONE or a member this runtime does not know.
const LayerOp* OpStoredAs(schema::LayerOp stored);

// Each unit, defined in its own file.
extern const LayerOp kConv2DOp;
extern const LayerOp kUpsampleOp;
extern const LayerOp kCropOp;
extern const LayerOp kConcatOp;
extern const LayerOp kAddOp;
extern const LayerOp kConvTranspose2DOp;
extern const LayerOp kPool2DOp;
extern const LayerOp kResizeOp;
extern const LayerOp kChannelAffineOp;

// "layer 3 'conv2'": how messages name a layer.
std::string Quote(const LayerDesc& layer, size_t index);
// "96x128x64".
std::string SizeText(const TensorShape& s);
// Shared pieces of the descriptions: " + relu", " + leaky(0.1)", " + clip(0..6)" (affine: the
// ChannelAffine-only activations' parameters); " dilation 2x2"; "1,1,1,1"; "%g".
std::string ActivationSuffix(Activation activation, float leaky_slope,
                             const ChannelAffineParams* affine = nullptr);
std::string DilationSuffix(int dh, int dw);
std::string PadsText(const Padding& p);
std::string FloatText(double v);
// "-": a kind that neither adds nor removes anything.
std::string NoPadding(const LayerDesc& layer, const LayerGeometry& g);

}  // namespace sfrt::ops
