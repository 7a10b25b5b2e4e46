// Model: a verified, immutable .sfrt model file in memory.
//
// Ownership and lifetime: a Model owns its bytes (a read-only memory mapping of the file, or a
// copy of a caller's buffer) unless loaded with BufferOwnership::kBorrow, in which case the caller
// keeps the buffer alive and unchanged for the Model's whole life. Weight pointers in LayerDesc
// point into those bytes (or, for fp16 files, into fp32 copies the Model owns).
//
// Thread-safety: a Model is never modified after loading; any number of threads and Sessions
// may share one (hold it by std::shared_ptr<const Model>).
//
// Verification on load, in order: size and 64-byte alignment; file identifier "SFRT"; schema
// major version (a different major is rejected naming both versions); the FlatBuffers verifier;
// the CRC-32C of the whole file (schema 1.1; 1.0 files have none); the FlatBuffers verifier; then
// semantic checks (the graph: every input an earlier layer or the model input, every output
// read, channel counts; weight shapes and byte counts, alignment,
// parameter ranges) and the CRC-32C of all weights. Any failure names the layer and field.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/status.h"
#include "sfrt/vocabulary/names.h"

namespace sfrt {

// The schema version this runtime writes and reads (docs/model-format.md, "Versioning").
inline constexpr int kSchemaVersionMajor = 1;
inline constexpr int kSchemaVersionMinor = 11;

// kConcat and kAdd (schema 1.5) make the model a graph rather than a chain; they run in float32,
// as do kConvTranspose2D and kPool2D (schema 1.6).
enum class LayerKind {
  kConv2D,
  kUpsample,
  kCrop,
  kConcat,
  kAdd,
  kConvTranspose2D,
  kPool2D,
  kResize,        // schema 1.7
  kChannelAffine  // schema 1.7
};
// Layers that run in float32 only. A model with one (or a graph) runs its int8 and bf16
// convolutions between float32 tensors: each converts what it reads and writes float32.
// (Each kind's unit says: runtime/src/ops/<kind>.cc; sfrt/layer_kinds.h asks the others.)
bool Float32OnlyKind(LayerKind kind);
// kElu, kSigmoid, kTanh and kClip (schema 1.8) are taken by kChannelAffine layers only (their
// parameters are in ChannelAffineParams); every layer kind takes the first three.
enum class Activation { kNone, kRelu, kLeakyRelu, kElu, kSigmoid, kTanh, kClip };
// "none", "relu", "leaky-relu", "elu", "sigmoid", "tanh", "clip".
const char* ActivationName(Activation activation);
// kSameLower (schema 1.7): ONNX SAME_LOWER, the larger half of an odd total at the top/left.
enum class PaddingRule { kExplicit, kSameUpper, kSameLower };
// "explicit", "same-upper", "same-lower".
const char* PaddingRuleName(PaddingRule rule);
// kToSecondInput (schema 1.5): to the height and width of the crop's second input.
enum class CropRule { kExplicit, kToInputSize, kToSecondInput };
// How a float model file stores its weights: "fp32", "fp16" (as sfrt export --weights says).
enum class WeightType { kFloat32, kFloat16 };
inline constexpr std::array<const char*, 2> kWeightTypeNames = {"fp32", "fp16"};
constexpr const char* WeightTypeName(WeightType type) {
  return vocabulary::NameOf(kWeightTypeNames, type);
}
constexpr std::optional<WeightType> WeightTypeFromName(std::string_view name) {
  return vocabulary::FromName<WeightType>(kWeightTypeNames, name);
}
// The arithmetic a convolution runs in (schema 1.3; every layer of an older file is kFloat32).
// kInt8: see ConvParams and docs/model-format.md, "Int8 arithmetic".
enum class Precision { kFloat32, kInt8, kBFloat16 };
inline constexpr std::array<const char*, 3> kPrecisionNames = {"fp32", "int8", "bf16"};
// "fp32", "int8", "bf16".
constexpr const char* PrecisionName(Precision precision) {
  return vocabulary::NameOf(kPrecisionNames, precision);
}
constexpr std::optional<Precision> PrecisionFromName(std::string_view name) {
  return vocabulary::FromName<Precision>(kPrecisionNames, name);
}
// Affine quantisation of an activation tensor: real = scale * (q - zero_point), q in 0..255.
struct QuantParams {
  float scale = 1.0f;
  int zero_point = 0;
  friend bool operator==(const QuantParams&, const QuantParams&) = default;
};
// Whether a model's weights were learned (schema 1.2; kUnknown in older files).
enum class TrainingState { kUnknown, kTrained, kUntrained };

// The input rows (or columns) a window of `kernel` taps `dilation` apart spans.
constexpr int DilatedExtent(int kernel, int dilation) { return (kernel - 1) * dilation + 1; }

struct Padding {
  int top = 0;
  int left = 0;
  int bottom = 0;
  int right = 0;
  friend bool operator==(const Padding&, const Padding&) = default;
};

struct ConvParams {
  int in_channels = 0;
  int out_channels = 0;
  int kernel_h = 0;
  int kernel_w = 0;
  int stride_h = 1;
  int stride_w = 1;
  // Schema 1.8, float32 only: tap (ky, kx) of output (oy, ox) reads input
  // (oy * stride_h - pads.top + ky * dilation_h, ox * stride_w - pads.left + kx * dilation_w);
  // with `groups` g, output channel co reads only input channels of its group
  // (co / (out_channels / g)), and `weights` hold in_channels / g inputs per tap. Depthwise:
  // g == in_channels.
  int dilation_h = 1;
  int dilation_w = 1;
  int groups = 1;
  PaddingRule padding_rule = PaddingRule::kExplicit;
  Padding pads;  // the rule when kExplicit; as stored (the traced size's amounts) otherwise
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  // HWIO: [kernel_h][kernel_w][in_channels / groups][out_channels]. Null when precision is kInt8.
  // For kBFloat16 the float32 weights, which a session rounds to bf16 (kernels/bf16_job.h).
  const float* weights = nullptr;
  const float* bias = nullptr;  // [out_channels], every precision
  Precision precision = Precision::kFloat32;
  // kInt8 only: weights_q in HWIO like `weights`, real weight = weight_scales[o] * q (symmetric,
  // per output channel); the input is quantised with input_quant; when the next convolution is
  // kInt8 too, the output is quantised with output_quant (which equals that layer's
  // input_quant), otherwise it is float32.
  const int8_t* weights_q = nullptr;
  const float* weight_scales = nullptr;  // [out_channels]
  QuantParams input_quant;
  QuantParams output_quant;
  // kInt8 convolutions (3x3, stride 1) that read a nearest-2x upsampling, optional: the four
  // output phases' 2x2 kernels over the low-resolution map, [4][2][2][in][out] int8 (phase
  // py * 2 + px, taps ty, tx), real weight = phase_scales[p * out_channels + o] * q. Pixels
  // whose 3x3 window lies inside the upsampled (and cropped) map use them (kernels/int8_job.h).
  const int8_t* phase_weights_q = nullptr;
  const float* phase_scales = nullptr;  // [4 * out_channels]
};

// Neither dilated nor grouped: the convolutions that int8, bf16 and every SIMD kernel take (the
// others run in float32 on the reference kernel).
inline bool UndilatedUngrouped(const ConvParams& p) {
  return p.dilation_h == 1 && p.dilation_w == 1 && p.groups == 1;
}

// A transposed convolution (schema 1.6, float32): every input pixel (iy, ix) adds
// in[iy][ix] . weights[ky][kx] to output pixel (iy * stride_h - pads.top + ky,
// ix * stride_w - pads.left + kx); then bias and activation. Output side per axis:
// (in - 1) * stride - pad_before - pad_after + (kernel - 1) * dilation + 1 + output_padding;
// tap ky lands dilation_h * ky rows down rather than ky (schema 1.8).
struct ConvTransposeParams {
  int in_channels = 0;
  int out_channels = 0;
  int kernel_h = 0;
  int kernel_w = 0;
  int stride_h = 1;
  int stride_w = 1;
  int dilation_h = 1;
  int dilation_w = 1;
  Padding pads;
  int output_padding_h = 0;  // < stride_h: rows added at the bottom
  int output_padding_w = 0;  // < stride_w: columns added at the right
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  const float* weights = nullptr;  // HWIO: [kernel_h][kernel_w][in_channels][out_channels]
  const float* bias = nullptr;     // [out_channels]
};

// Max or average pooling (schema 1.6, float32; docs/model-format.md, "Pool2D"): window (y, x)
// covers input rows y * stride_h - pads.top .. + kernel_h - 1 and likewise columns; padded
// positions never win a max; an average divides by the window's input positions, or with
// count_include_pad by its positions up to the end of the padded input. kArgMax (schema 1.10):
// where the max is (the first in row-major window order among equal values), as the float32
// index c * H * W + y * W + x of the input (H x W; c * H * W + x * H + y with
// indices_column_major), ONNX MaxPool's Indices output; exact while the input holds at most 2^24
// values (the session refuses larger ones).
enum class PoolKind { kMax, kAverage, kArgMax };
struct PoolParams {
  PoolKind kind = PoolKind::kMax;
  int kernel_h = 1;
  int kernel_w = 1;
  int stride_h = 1;
  int stride_w = 1;
  // Schema 1.8: tap ky reads row y * stride_h - pads.top + ky * dilation_h; the window's extent
  // (kernel - 1) * dilation + 1 takes the kernel side's place in sizes and padding.
  int dilation_h = 1;
  int dilation_w = 1;
  PaddingRule padding_rule = PaddingRule::kExplicit;
  Padding pads;  // the rule when kExplicit; as stored otherwise
  bool ceil_mode = false;
  bool count_include_pad = false;
  bool indices_column_major = false;  // kArgMax only (schema 1.10)
};

// Resizing as ONNX Resize computes it (schema 1.7, float32; docs/model-format.md, "Resize"):
// output side = floor(in * scale_num / scale_den); output pixel y maps to the source coordinate
// the coordinate mode gives (scale = scale_num / scale_den; align_corners divides by the unrounded
// output length in * scale, as ONNX does), which is rounded (kNearest) or
// interpolated between the 2 (kLinear) or 4 (kCubic) nearest rows, indices clamped to the input;
// likewise along x. kUpsample stays the op for nearest upsampling by integer factors.
// kTfCropAndResize (schema 1.9) maps the output onto a region of interest and gives pixels whose
// source lies outside the input `extrapolation_value`.
enum class ResizeMode { kNearest, kLinear, kCubic };
enum class ResizeCoordinates {
  kHalfPixel,         // (y + 0.5) / scale - 0.5
  kPytorchHalfPixel,  // the same, but 0 when the output side is 1
  kAlignCorners,      // y * (in - 1) / (out - 1), 0 when out is 1
  kAsymmetric,        // y / scale
  kTfHalfPixelForNn,  // (y + 0.5) / scale
  // start * (in - 1) + y * (end - start) * (in - 1) / (out - 1), or (start + end) / 2 * (in - 1)
  // when out is 1; start and end are the region of interest's fractions of the input side.
  kTfCropAndResize
};
enum class NearestRounding { kRoundPreferFloor, kRoundPreferCeil, kFloor, kCeil };
// ONNX's words: "nearest", "linear", "cubic"; "half_pixel", "pytorch_half_pixel",
// "align_corners", "asymmetric", "tf_half_pixel_for_nn", "tf_crop_and_resize";
// "round_prefer_floor", "round_prefer_ceil", "floor", "ceil".
const char* ResizeModeName(ResizeMode mode);
const char* ResizeCoordinatesName(ResizeCoordinates coordinates);
const char* NearestRoundingName(NearestRounding rounding);
struct ResizeParams {
  ResizeMode mode = ResizeMode::kNearest;
  ResizeCoordinates coordinates = ResizeCoordinates::kHalfPixel;
  NearestRounding nearest = NearestRounding::kRoundPreferFloor;  // kNearest
  int64_t scale_num_h = 1;
  int64_t scale_den_h = 1;
  int64_t scale_num_w = 1;
  int64_t scale_den_w = 1;
  float cubic_coeff_a = -0.75f;  // kCubic
  bool exclude_outside = false;  // kCubic: weights of taps outside the input are dropped
  // kTfCropAndResize: the region of interest (ONNX roi) as fractions of the input's height and
  // width (outside [0, 1] allowed), and the value of output pixels whose source coordinate lies
  // outside [0, in - 1] on either axis.
  float roi_start_h = 0.0f;
  float roi_start_w = 0.0f;
  float roi_end_h = 1.0f;
  float roi_end_w = 1.0f;
  float extrapolation_value = 0.0f;
};

struct UpsampleParams {  // nearest neighbour
  int factor_h = 1;
  int factor_w = 1;
};

struct CropParams {
  CropRule rule = CropRule::kToInputSize;
  Padding amounts;                    // kExplicit: removed per side
  bool excess_rows_from_top = true;   // kToInputSize, kToSecondInput
  bool excess_cols_from_left = true;  // kToInputSize, kToSecondInput
};

// Schema 1.7, float32: out[c] = act(in[c] * scale[c] + shift[c]) (docs/model-format.md,
// "ChannelAffine").
struct ChannelAffineParams {
  int channels = 0;
  const float* scale = nullptr;  // [channels]
  const float* shift = nullptr;  // [channels]
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
  float elu_alpha = 1.0f;  // kElu: v > 0 ? v : elu_alpha * (exp(v) - 1)
  float clip_min = 0.0f;   // kClip: min(max(v, clip_min), clip_max)
  float clip_max = 0.0f;
};

struct AddParams {  // out = act(a + b)
  Activation activation = Activation::kNone;
  float leaky_slope = 0.0f;
};

// The model input, where LayerDesc::inputs names it.
inline constexpr int kModelInput = -1;

struct LayerDesc {
  std::string name;
  LayerKind kind = LayerKind::kConv2D;
  // What it reads, in order: indices of earlier layers, or kModelInput. One for kConv2D,
  // kUpsample and kCrop (two for a kToSecondInput crop, which reads only the second's size), two
  // for kAdd, two or more for kConcat (channels stacked in this order), one for
  // kConvTranspose2D, kPool2D, kResize and kChannelAffine.
  std::vector<int> inputs;
  ConvParams conv;             // valid when kind == kConv2D
  UpsampleParams upsample;     // valid when kind == kUpsample
  CropParams crop;             // valid when kind == kCrop
  AddParams add;               // valid when kind == kAdd
  ConvTransposeParams deconv;  // valid when kind == kConvTranspose2D
  PoolParams pool;             // valid when kind == kPool2D
  ResizeParams resize;         // valid when kind == kResize
  ChannelAffineParams affine;  // valid when kind == kChannelAffine
};

// The network's input: images in `image_order` (the vocabulary's slot names, each filling the
// next 3 channels, or 1 for a depth map), or, with no image order, a plain tensor fed as given.
// The slots are four stereo images ("left0", "right0", "left1", "right1") or, since schema 1.11,
// two RGB-D frames ("color0", "depth0", "color1", "depth1"), never a mix.
struct InputDesc {
  std::string name;
  int channels = 0;
  std::vector<std::string> image_order;
  std::string color_order;  // "BGR" or "RGB"
  float scale = 1.0f;       // fed value = (pixel * scale - mean[c]) / std[c]
  float mean[3] = {0, 0, 0};
  float std[3] = {1, 1, 1};
  int traced_height = 0;  // 0 when unknown
  int traced_width = 0;
  // RGB-D frames: depth d in metres is fed as (d - depth_mean) / depth_std, a pixel without
  // depth (d 0, negative or not finite) as depth_invalid.
  float depth_mean = 0.0f;
  float depth_std = 1.0f;
  float depth_invalid = 0.0f;

  bool is_tensor() const { return image_order.empty(); }
  bool is_rgbd() const;  // the slots are RGB-D frames
};

struct OutputDesc {
  std::string name;
  int channels = 0;
  std::vector<std::string> channel_names;
  std::string units;            // as stored
  bool units_declared = false;  // schema 1.2 or later: `units` is what the author stated; older
                                // exporters wrote a fixed text, so the units are unknown
};

struct CameraDesc {
  float focal_px = 0;
  float baseline = 0;
  float cx = 0;
  float cy = 0;
};

// How a reduced-precision file's quantisation was chosen (schema 1.3, `sfrt export
// --calibration`), with the errors the exporter measured against float32.
struct LayerErrorDesc {
  std::string layer;
  Precision precision = Precision::kFloat32;
  float relative_rms = 0;  // RMS(layer output - float32 layer output) / RMS(float32 output)
};
struct CalibrationDesc {
  std::string method;
  std::string data_sha256;
  int frames = 0;
  int height = 0;
  int width = 0;
  float output_max_rel = 0;  // max |out - fp32 out| / max |fp32 out|
  float output_rms_rel = 0;  // RMS(out - fp32 out) / RMS(fp32 out)
  std::vector<LayerErrorDesc> layers;
};

struct ModelMetadata {
  std::string name;
  int schema_major = 0;
  int schema_minor = 0;
  std::string exporter_version;
  std::string source_format;
  std::string source_file;
  std::string source_sha256;
  InputDesc input;
  OutputDesc output;
  CameraDesc camera;
  uint32_t weights_crc32c = 0;
  std::optional<uint32_t> file_crc32c;            // whole-file CRC-32C; absent in schema 1.0 files
  WeightType weight_type = WeightType::kFloat32;  // as stored in the file
  TrainingState training = TrainingState::kUnknown;  // schema 1.2; kUnknown before
  bool has_int8 = false;                             // some convolution is kInt8 (schema 1.3)
  bool has_bf16 = false;                             // some convolution is kBFloat16 (1.4)
  std::optional<CalibrationDesc> calibration;        // schema 1.3, reduced-precision files
};

// The arithmetic a model runs in, for titles and logs: "int8+bf16+fp32" (both reduced
// precisions), "int8 (some layers fp32)", "bf16 (some layers fp32)", "fp32 (fp16 weights)"
// (weights stored as fp16, widened at load) or "fp32".
std::string PrecisionSummary(const ModelMetadata& metadata);

struct LoadOptions {
  // The CRC-32C of the whole file (1.1) and of all weights; costs a pass over each.
  bool verify_checksum = true;
};

enum class BufferOwnership {
  kCopy,    // the Model copies the bytes (into 64-byte-aligned memory)
  kBorrow,  // the Model uses the caller's bytes in place; they must be 64-byte aligned
};

class Model {
 public:
  // Memory-maps `path` read-only and verifies it. Errors name the file.
  static Result<std::shared_ptr<const Model>> LoadFile(const std::string& path,
                                                       const LoadOptions& options = {});
  // Verifies a model held in memory. `label` names it in error messages.
  static Result<std::shared_ptr<const Model>> LoadBuffer(const void* data, size_t size,
                                                         BufferOwnership ownership,
                                                         const LoadOptions& options = {},
                                                         const std::string& label = "<memory>");

  ~Model();
  Model(const Model&) = delete;
  Model& operator=(const Model&) = delete;

  const ModelMetadata& metadata() const { return metadata_; }
  std::span<const LayerDesc> layers() const { return layers_; }
  // True when every layer reads the one before it (layer 0: the input): the only form before
  // schema 1.5.
  bool is_chain() const { return is_chain_; }
  // True for a graph, or a chain with a float32-only layer (Float32OnlyKind): its tensors between
  // layers are float32, and each int8 or bf16 convolution converts the tensor it reads (before
  // the nearest-2x upsampling it fuses, if any) and writes float32. Otherwise int8 and bf16
  // tensors pass between convolutions of the same precision.
  bool float32_between_layers() const { return float32_between_layers_; }
  // How many layers read layer i's output (the last layer's: 0).
  int consumer_count(size_t i) const { return consumers_[i]; }
  size_t file_bytes() const { return size_; }
  // Number of stored parameters (weights and biases of all layers).
  size_t parameter_count() const;

 private:
  Model() = default;
  struct Storage;  // how the bytes are held (mapping, aligned copy, or borrowed)
  Status Parse(const LoadOptions& options, const std::string& label);

  std::unique_ptr<Storage> storage_;
  const uint8_t* data_ = nullptr;
  size_t size_ = 0;
  ModelMetadata metadata_;
  std::vector<LayerDesc> layers_;
  std::vector<int> consumers_;  // per layer
  bool is_chain_ = true;
  bool float32_between_layers_ = false;
  std::vector<std::vector<float>> widened_;  // fp32 copies of fp16 tensors
};

}  // namespace sfrt
