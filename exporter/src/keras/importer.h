// The Keras importer's inside (keras_importer.cc reads the HDF5 file and the architecture,
// keras/layer_builders.cc builds the spec, one member per layer class): the Importer class and
// the helpers they share. Not an API.
#pragma once

#include <hdf5.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

#include "batch_norm_fold.h"
#include "crop_rule.h"
#include "hdf5_header_guard.h"
#include "hdf5_vlen_guard.h"
#include "message_text.h"
#include "sfrt/exporter/keras_importer.h"
#include "sfrt/model_limits.h"
#include "sfrt/sha256.h"

// Returns the Status of `expr` from the enclosing function when it is an error.
#define SFRT_KERAS_RETURN_IF_ERROR(expr)        \
  do {                                          \
    ::sfrt::Status sfrt_keras_status_ = (expr); \
    if (!sfrt_keras_status_.ok()) {             \
      return sfrt_keras_status_;                \
    }                                           \
  } while (false)

namespace sfrt::exporter::keras_import {

using nlohmann::json;

constexpr char kSupportedLayers[] =
    "InputLayer, Conv2D (any dilation_rate and groups), DepthwiseConv2D, Conv2DTranspose, "
    "BatchNormalization (folded into the convolution before it), LeakyReLU, Activation, "
    "UpSampling2D (nearest and bilinear), MaxPooling2D, AveragePooling2D, Cropping2D, "
    "ZeroPadding2D, Concatenate (channels), Add (and a multi_gpu_model wrapper: "
    "InputLayer/Lambda/Concatenate around one nested Model)";
// Upper bound on one weight tensor's elements (the largest SceneEDNet kernel has 9.4 M).
constexpr uint64_t kMaxTensorElements = uint64_t{1} << 30;

// Upper bound on dimensions read from the architecture (kernel sizes, strides, crops, ...).
constexpr int64_t kMaxDim = 1 << 20;

std::string DimsText(const std::vector<uint64_t>& dims);

// ------------------------------------------------------------------------------ HDF5 helpers

// Owns one HDF5 identifier.
class H5Handle {
 public:
  using Closer = herr_t (*)(hid_t);
  H5Handle() = default;
  H5Handle(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  H5Handle(const H5Handle&) = delete;
  H5Handle& operator=(const H5Handle&) = delete;
  H5Handle(H5Handle&& other) noexcept : id_(other.id_), closer_(other.closer_) { other.id_ = -1; }
  H5Handle& operator=(H5Handle&& other) noexcept {
    if (this != &other) {
      Reset();
      id_ = other.id_;
      closer_ = other.closer_;
      other.id_ = -1;
    }
    return *this;
  }
  ~H5Handle() { Reset(); }
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }

 private:
  void Reset() {
    if (id_ >= 0 && closer_ != nullptr) closer_(id_);
    id_ = -1;
  }
  hid_t id_ = -1;
  Closer closer_ = nullptr;
};

herr_t FirstErrorText(unsigned /*n*/, const H5E_error2_t* err, void* data);

// The most specific message on HDF5's error stack (then cleared), as " (HDF5: ...)" or "".
std::string Hdf5Error();

// Why a read of variable-length data failed: the guard's refusal (a damaged heap reference it
// stopped before libhdf5 followed it) as ": ...", else HDF5's message.
std::string ReadFailureDetail();

// Turns HDF5's automatic error printing off for the importer's lifetime.
class QuietHdf5 {
 public:
  QuietHdf5() {
    H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }
  QuietHdf5(const QuietHdf5&) = delete;
  QuietHdf5& operator=(const QuietHdf5&) = delete;

 private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

// Whether dataset `ds` (datatype `type`, `count` values) stores its values in the file. Storage
// never written reads as the fill value, so a damaged dataspace could make an import allocate
// gigabytes of fill for a file of kilobytes: a dataset without filters must store every value's
// bytes, inside the file; a filtered (compressed) one at most kMaxCompression times its stored
// bytes. Keras writes contiguous datasets without filters. The message reads "<what is wrong>".
constexpr uint64_t kMaxCompression = 1024;

Status CheckStoredSize(hid_t ds, hid_t type, uint64_t count);

// Reads a string attribute (scalar or 1-D; fixed- or variable-length) of `obj`. `where` names the
// object in errors. Returns std::nullopt-like empty optional when the attribute does not exist.
Result<std::optional<std::vector<std::string>>> ReadStringsAttr(hid_t obj, const char* name,
                                                                const std::string& where);

// A list attribute as Keras writes it: whole, or (when over HDF5's 64 KiB attribute limit) split
// by save_attributes_to_hdf5_group into `<name>0`, `<name>1`, ...
Result<std::optional<std::vector<std::string>>> ReadKerasList(hid_t obj, const std::string& name,
                                                              const std::string& where);

std::string JsonText(const json& v);

bool IsInt(const json& v);

// `v` (may be null) as an integer in [lo, hi].
bool GetInt(const json* v, int64_t lo, int64_t hi, int* out);

// `v` as (a, b): an integer n gives (n, n); a list of two integers gives them.
bool GetPair(const json* v, int64_t lo, int64_t hi, std::array<int, 2>* out);

// Keras' cropping/padding argument: n, (rows, cols) symmetric, or ((top, bottom), (left, right)).
bool GetSidePads(const json* v, Pads* out);

int CeilDiv(int a, int b);

// TensorFlow 'same' amounts for one axis: (before, after).
std::pair<int, int> SameAxis(int in, int stride, int kernel);

bool IsNestedModelClass(const std::string& cls);

// ------------------------------------------------------------------------------ the importer
struct ChainLayer {
  std::string name;
  std::string cls;
  const json* config = nullptr;      // the layer's "config" object
  std::vector<std::string> inbound;  // the layers (or the InputLayer) it reads, in order
};

// The layers from the input to the output: a chain, or a graph whose layers read several.
struct ChainModel {
  std::string name;
  std::string input_name;          // what the first layer reads
  std::vector<ChainLayer> layers;  // each after the layers it reads (the InputLayer not among them)
  int height = 0;                  // built size; 0 when None
  int width = 0;
  int channels = 0;
};

// Where each Conv2D's weights come from.
struct WeightSource {
  std::string root_label;  // "model_weights" or "/" (in messages)
  hid_t root = -1;         // the group holding one group per layer
  // Nested (multi-GPU) mode: all weights listed by one group, taken in order.
  bool nested = false;
  std::string nested_group;  // path relative to root
  std::vector<std::string> nested_names;
  size_t next = 0;
};

// Sets the activation of a convolution, transposed convolution or Add that a following layer
// fuses into.
void SetActivation(LayerSpec* target, Activation act, float slope);

class Importer {
 public:
  Importer(std::string path, KerasImportOptions options)
      : path_(std::move(path)), options_(std::move(options)), guard_(path_), headers_(path_) {}
  // Reads an HDF5 file image held in memory (`image` must outlive the importer); `label` stands
  // for the path in messages.
  Importer(std::string_view image, std::string label, KerasImportOptions options)
      : path_(std::move(label)),
        options_(std::move(options)),
        image_(image),
        in_memory_(true),
        guard_(image),
        headers_(image) {}
  Result<KerasImportResult> Run();

 private:
  Status Fail(const std::string& message) const { return Status::Error(path_ + ": " + message); }
  Status LayerFail(const ChainLayer& l, const std::string& message) const {
    return Fail("layer " + Quote(l.name) + " (" + Printable(l.cls) + "): " + message);
  }
  std::string GroupLabel(const std::string& rel) const {
    return Quote(src_.root_label == "/" ? rel : src_.root_label + "/" + rel);
  }

  Result<ResizeCoordinates> BilinearGrid(const ChainLayer& l);
  Result<bool> PathExists(hid_t loc, const std::string& path);
  Status Open();
  Status OpenFile();
  Result<json> ReadArchitecture();
  Status FindWeightsRoot();
  Result<ChainModel> ParseModel(const json& model, const std::string& label);
  Result<ChainModel> ParseFunctional(const json& config, const std::string& label);
  Result<ChainModel> ParseSequential(const json& layers, const std::string& label);
  Status ReadInputShape(const ChainLayer& l, const json& shape, ChainModel* model);
  Result<std::vector<std::string>> WeightPaths(const ChainLayer& l, size_t count);
  Result<std::vector<float>> ReadDataset(const ChainLayer& l, const std::string& path,
                                         const std::vector<uint64_t>& want,
                                         const std::string& meaning);
  // The layer's 'padding': "same" or "valid" (absent: "valid").
  Result<std::string> SameOrValid(const ChainLayer& l) const;
  // A Conv2DTranspose reading `in_channels`, with its weights, activation and TensorFlow's
  // output size as pads and output padding.
  Result<ConvTransposeSpec> ReadConvTranspose(const ChainLayer& l, int in_channels);
  Status ReadConvTransposeShape(const ChainLayer& l, ConvTransposeSpec* out);
  Status ReadConvTransposeWeights(const ChainLayer& l, ConvTransposeSpec* out);
  Status Build(const ChainModel& model, ModelSpec* spec);

  // What each Keras layer's output is in the spec while Build runs: its size at the built size
  // (0 when unknown), the spec layer that computes it (or the input), and ZeroPadding2D amounts
  // waiting for the Conv2D that reads it.
  struct Tensor {
    int h = 0;
    int w = 0;
    int c = 0;
    std::string layer;
    int index = -1;  // into spec->layers; -1: the input
    Pads pads;
    const ChainLayer* pad_layer = nullptr;
  };
  struct CropTrace {
    size_t layer = 0;
    std::string output;  // the Cropping2D layer's name
    int out_h = 0;
    int out_w = 0;
  };
  // Build's state over the layers.
  struct BuildState {
    const ChainModel& model;
    ModelSpec* spec;
    bool known;  // the built size is known
    std::unordered_map<std::string, Tensor> tensors;
    std::unordered_map<std::string, std::vector<const ChainLayer*>> readers;
    std::vector<CropTrace> crops;
    int convs = 0;
  };
  // One Keras layer being built: the tensor it reads, and its output's size and the padding
  // waiting for a convolution as its builder goes.
  struct LayerBuild {
    BuildState& s;
    const ChainLayer& l;
    Tensor in;
    int h;
    int w;
    int c;
    Pads pending;
    const ChainLayer* pending_pad;
  };
  // Each Keras layer class is built by one member, found by class name (BuilderOf).
  using LayerBuilder = Status (Importer::*)(LayerBuild& b);
  static LayerBuilder BuilderOf(std::string_view cls);
  Status BuildConvolution(LayerBuild& b);
  Status ReadConvConfig(const LayerBuild& b, bool depthwise, ConvSpec* conv, bool* use_bias);
  Status PadConvolution(LayerBuild& b, ConvSpec* conv);
  Status ReadConvWeights(const LayerBuild& b, bool depthwise, bool use_bias, ConvSpec* conv);
  Status BuildBatchNormalization(LayerBuild& b);
  Status BuildLeakyRelu(LayerBuild& b);
  Status BuildActivation(LayerBuild& b);
  Status BuildConvTranspose(LayerBuild& b);
  Status BuildPooling(LayerBuild& b);
  Status BuildUpSampling(LayerBuild& b);
  Status BuildCropping(LayerBuild& b);
  Status BuildZeroPadding(LayerBuild& b);
  Status BuildMerge(LayerBuild& b);
  Status UnknownLayer(const ChainLayer& l) const;
  Status CheckInbound(const BuildState& s, const ChainLayer& l) const;
  Status OneInput(const LayerBuild& b, const char* what) const;
  // A new spec layer computing b's Keras layer's output.
  void AddLayer(LayerBuild& b, LayerSpec layer);
  // The Conv2D (or, for activations, Add) that computes b's input when b's layer may fold or
  // fuse into it: no activation yet, and no other layer reads its output.
  LayerSpec* FusionTarget(LayerBuild& b, bool add_too);
  Status FusionRefused(LayerBuild& b, const std::string& what);
  void ChooseCropRules(BuildState& s);
  void NoteKeptCrop(const CropSpec& crop, const std::string& why);
  Status CheckAllWeightsUsed();

  Status OpenImage();

  std::string path_;
  KerasImportOptions options_;
  std::string_view image_;
  bool in_memory_ = false;
  QuietHdf5 quiet_;
  // Checks every global-heap reference before libhdf5 follows it (hdf5_vlen_guard.h); declared
  // before file_, so it stays installed until the file is closed.
  hdf5::VlenGuard guard_;
  // Checks object headers before libhdf5 loads them (hdf5_header_guard.h).
  hdf5::HeaderGuard headers_;
  H5Handle file_;
  H5Handle weights_group_;
  std::string backend_;
  std::string keras_version_;
  std::vector<std::string> layer_names_;  // attribute layer_names of the weights root
  std::set<std::string> used_groups_;     // layer groups whose weights were read
  WeightSource src_;
  std::vector<std::string> notes_;
};

// Keras 2.4 and later run only on TensorFlow 2 ("2.4.0", "2.9.0", "3.1.0"); 2.0-2.3 (and the
// "-tf" versions tf.keras wrote up to TensorFlow 2.1) may have run on TensorFlow 1.
bool SavedOnTensorFlow2(const std::string& keras_version);

// obj[key], or nullptr when `obj` is not an object or has no such key.
const json* Find(const json& obj, const char* key);

// One entry of a layer list: name, class and config.
Result<ChainLayer> ReadLayerEntry(const json& entry, const std::string& where);

// The layer names of "input_layers"/"output_layers": [[name, node, tensor], ...] or, as some
// Keras versions write a single one, [name, node, tensor].
std::optional<std::vector<std::string>> EndpointNames(const json* v);

Status CheckChannelsLast(const ChainLayer& l, const std::string& path);

}  // namespace sfrt::exporter::keras_import
