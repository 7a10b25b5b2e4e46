// ModelSpec: the exporter's in-memory model, between a source-format importer (ONNX, later
// Keras) and the .sfrt writer. Importers fill it; SerializeModel() turns it into file bytes.
// Plain data: no I/O, no ownership subtleties.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "sfrt/model.h"
#include "sfrt/vocabulary/stereo_input.h"

namespace sfrt::exporter {

// The layer vocabulary is the runtime's own (sfrt/model.h): one definition of each rule.
using sfrt::Activation;
using sfrt::CalibrationDesc;
using sfrt::CropRule;
using sfrt::PaddingRule;
using sfrt::PoolKind;
using sfrt::Precision;
using sfrt::QuantParams;
using sfrt::TrainingState;
using sfrt::WeightType;
using Pads = sfrt::Padding;

using vocabulary::ColorOrder;  // the shared words (sfrt/vocabulary/stereo_input.h)
using vocabulary::ImageSlot;

// Every layer's `inputs` names the tensors it reads (schema 1.5): earlier layers' names or the
// model input's (InputSpec::name). Empty: the previous layer (layer 0: the input), as in a chain.

struct ConvSpec {
  std::string name;
  std::vector<std::string> inputs;
  int in_channels = 0;
  int out_channels = 0;
  int kernel_h = 3;
  int kernel_w = 3;
  int stride_h = 1;
  int stride_w = 1;
  int dilation_h = 1;  // schema 1.8 (sfrt/model.h, ConvParams); float32 only when not 1
  int dilation_w = 1;
  int groups = 1;  // schema 1.8; divides in_channels and out_channels
  PaddingRule padding_rule = PaddingRule::kExplicit;
  Pads pads;  // the amounts at the traced size; the rule when padding_rule == kExplicit
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  // kFloat32: kernel_h * kernel_w * (in_channels / groups) * out_channels; empty when kInt8.
  std::vector<float> weights_hwio;
  std::vector<float> bias;  // out_channels, every precision
  // Schema 1.3. kInt8: weights_q replaces weights_hwio (same HWIO order, real weight =
  // weight_scales[o] * q, q in -127..127); the input is read as uint8 with input_quant and,
  // when the next convolution is kInt8 too, the output is written with output_quant (which must
  // equal that convolution's input_quant). Both quant fields must be valid whenever kInt8.
  Precision precision = Precision::kFloat32;
  std::vector<int8_t> weights_q;
  std::vector<float> weight_scales;  // out_channels
  QuantParams input_quant;
  QuantParams output_quant;
  // kInt8, 3x3 stride 1, reading a nearest-2x upsampling: optional phase kernels (sfrt/model.h,
  // ConvParams::phase_weights_q): 4 * 2 * 2 * in_channels * out_channels int8 values and
  // 4 * out_channels scales; both empty otherwise.
  std::vector<int8_t> phase_weights_q;
  std::vector<float> phase_scales;
};

struct UpsampleSpec {
  std::string name;
  int factor_h = 1;
  int factor_w = 1;
  std::vector<std::string> inputs;
};

struct CropSpec {
  std::string name;
  CropRule rule = CropRule::kToInputSize;
  Pads amounts;                       // rows/cols removed per side when rule == kExplicit
  bool excess_rows_from_top = true;   // kToInputSize, kToSecondInput: excess rows from the top
  bool excess_cols_from_left = true;  // ... excess columns from the left
  std::vector<std::string> inputs;    // kToSecondInput: two (the second gives the size)
};

struct ConcatSpec {  // schema 1.5: channels stacked in input order
  std::string name;
  std::vector<std::string> inputs;  // two or more
};

struct AddSpec {  // schema 1.5: act(a + b)
  std::string name;
  std::vector<std::string> inputs;  // two
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
};

struct ConvTransposeSpec {  // schema 1.6 (sfrt/model.h, ConvTransposeParams); float32
  std::string name;
  std::vector<std::string> inputs;
  int in_channels = 0;
  int out_channels = 0;
  int kernel_h = 4;
  int kernel_w = 4;
  int stride_h = 2;
  int stride_w = 2;
  int dilation_h = 1;  // schema 1.8
  int dilation_w = 1;
  Pads pads;                 // removed from the full output's borders
  int output_padding_h = 0;  // rows added at the bottom (< stride_h)
  int output_padding_w = 0;  // columns added at the right (< stride_w)
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  std::vector<float> weights_hwio;  // kernel_h * kernel_w * in_channels * out_channels
  std::vector<float> bias;          // out_channels
};

struct PoolSpec {  // schema 1.6 (sfrt/model.h, PoolParams); float32
  std::string name;
  std::vector<std::string> inputs;
  PoolKind kind = PoolKind::kMax;
  int kernel_h = 2;
  int kernel_w = 2;
  int stride_h = 2;
  int stride_w = 2;
  int dilation_h = 1;  // schema 1.8
  int dilation_w = 1;
  PaddingRule padding_rule = PaddingRule::kExplicit;
  Pads pads;  // the amounts at the traced size; the rule when padding_rule == kExplicit
  bool ceil_mode = false;
  bool count_include_pad = false;     // kAverage
  bool indices_column_major = false;  // kArgMax (schema 1.10; sfrt/model.h, PoolParams)
};

struct ResizeSpec {  // schema 1.7 (sfrt/model.h, ResizeParams); float32
  std::string name;
  std::vector<std::string> inputs;
  sfrt::ResizeParams params;
};

struct ChannelAffineSpec {  // schema 1.7 (sfrt/model.h, ChannelAffineParams); float32
  std::string name;
  std::vector<std::string> inputs;
  std::vector<float> scale;  // one per channel
  std::vector<float> shift;  // one per channel
  // Every kind; kElu, kSigmoid, kTanh and kClip need schema 1.8.
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  float elu_alpha = 1.0f;  // kElu
  float clip_min = 0.0f;   // kClip
  float clip_max = 0.0f;
};

using LayerSpec = std::variant<ConvSpec, UpsampleSpec, CropSpec, ConcatSpec, AddSpec,
                               ConvTransposeSpec, PoolSpec, ResizeSpec, ChannelAffineSpec>;

struct InputSpec {
  std::string name = "stereo_pairs";
  int channels = 12;
  std::vector<ImageSlot> image_order = {vocabulary::kDefaultImageOrder.begin(),
                                        vocabulary::kDefaultImageOrder.end()};
  ColorOrder color_order = ColorOrder::kBGR;
  float scale = 1.0f;
  std::array<float, 3> mean = {0.0f, 0.0f, 0.0f};
  std::array<float, 3> std = {1.0f, 1.0f, 1.0f};
  int traced_height = 0;  // 0 when unknown
  int traced_width = 0;
  // RGB-D frames (image slots color0, depth0, color1, depth1; schema 1.11): depth d in metres is
  // fed as (d - depth_mean) / depth_std, a pixel without depth as depth_invalid.
  float depth_mean = 0.0f;
  float depth_std = 1.0f;
  float depth_invalid = 0.0f;
};

struct OutputSpec {
  std::string name = "scene_flow";
  int channels = 3;
  std::vector<std::string> channel_names = {"dX", "dY", "dZ"};
  // What the values measure, as the author states it (sfrt export --units), e.g. "metres".
  // Empty: not stated (the writer stores "unknown").
  std::string units;
};

struct CameraSpec {  // defaults: FlyingThings3D, as the authors trained
  float focal_px = 1050.0f;
  float baseline = 1.0f;
  float cx = 479.5f;
  float cy = 269.5f;
};

struct ProducerSpec {
  std::string exporter_version;
  std::string source_format;  // "onnx", "keras-h5"
  std::string source_file;    // base name
  std::string source_sha256;  // lowercase hex
};

struct ModelSpec {
  std::string name = "sceneednet";
  ProducerSpec producer;
  InputSpec input;
  OutputSpec output;
  CameraSpec camera;
  std::vector<LayerSpec> layers;  // each after the layers it reads; the last is the output
  WeightType weight_type = WeightType::kFloat32;
  TrainingState training = TrainingState::kUnknown;  // written from schema 1.2
  // Schema 1.3: how the quantisation was chosen (sfrt export --calibration); written when set.
  std::optional<CalibrationDesc> calibration;
};

// Whether some layer names its inputs or reads two tensors (a graph, schema 1.5), rather than each
// layer reading the one before it.
inline bool IsGraph(const ModelSpec& spec) {
  for (const LayerSpec& layer : spec.layers) {
    if (std::holds_alternative<ConcatSpec>(layer) || std::holds_alternative<AddSpec>(layer)) {
      return true;
    }
    if (!std::visit([](const auto& l) { return l.inputs.empty(); }, layer)) return true;
  }
  return false;
}

// Whether the convolution has int8 and bf16 forms: dilated and grouped ones run in float32 only.
// Any model may mix them with float32 layers (graphs and float32-only ops too: sfrt/model.h,
// Model::float32_between_layers()).
inline bool ReducibleConv(const ConvSpec& conv) {
  return conv.dilation_h == 1 && conv.dilation_w == 1 && conv.groups == 1;
}

// For importers that name every layer's inputs: a chain (each layer reading the one before it,
// layer 0 reading `input_name`, no Concat or Add) has the names dropped, so that its file is what
// a runtime before schema 1.5 reads; a graph keeps them and names the input `input_name`.
inline void KeepInputNamesOfAGraph(ModelSpec& spec, const std::string& input_name) {
  if (!IsGraph(spec)) return;  // no layer names an input: already a chain's file
  bool chain = true;
  for (size_t k = 0; k < spec.layers.size() && chain; ++k) {
    const std::string previous =
        k == 0 ? input_name : std::visit([](const auto& l) { return l.name; }, spec.layers[k - 1]);
    const auto& inputs = std::visit([](const auto& l) { return l.inputs; }, spec.layers[k]);
    chain = inputs.size() == 1 && inputs[0] == previous &&
            !std::holds_alternative<ConcatSpec>(spec.layers[k]) &&
            !std::holds_alternative<AddSpec>(spec.layers[k]);
  }
  if (chain) {
    for (LayerSpec& layer : spec.layers) std::visit([](auto& l) { l.inputs.clear(); }, layer);
  } else {
    spec.input.name = input_name;
  }
}

// Makes `crop` (whose amounts are those removed at the traced size, on at most one side per
// axis) a crop to the size of `reference`, its second input: a U-Net cutting an upsampled
// tensor to its skip tensor's size. The excess goes from the side removed on each axis; an axis
// with nothing removed takes the other axis' side, or the end (bottom, right) where neither
// removed anything, as PyTorch's x[..., :h, :w] does.
inline void CropToSecondInput(CropSpec& crop, const std::string& reference) {
  const Pads& a = crop.amounts;
  const bool rows_known = a.top > 0 || a.bottom > 0;
  const bool cols_known = a.left > 0 || a.right > 0;
  crop.rule = CropRule::kToSecondInput;
  crop.inputs.push_back(reference);
  crop.excess_rows_from_top = rows_known ? a.top > 0 : cols_known && a.left > 0;
  crop.excess_cols_from_left = cols_known ? a.left > 0 : rows_known && a.top > 0;
}

// Sets the output's channel count as the importer found it. The default names (dX, dY, dZ)
// describe a 3-channel scene flow; any other count is left unnamed rather than misnamed.
inline void SetOutputChannels(ModelSpec& spec, int channels) {
  spec.output.channels = channels;
  if (static_cast<int>(spec.output.channel_names.size()) != channels) {
    spec.output.channel_names.clear();
  }
}

}  // namespace sfrt::exporter
