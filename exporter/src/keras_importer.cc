// Keras 2 HDF5 -> ModelSpec. Method, in order:
//  1. Open the file with the HDF5 C library (automatic error printing off; HDF5's own message
//     for a failure is appended to ours; every global-heap reference is checked before libhdf5
//     follows it: hdf5_vlen_guard.h; every object header, the root's before H5Fopen, is checked
//     before libhdf5 loads it: hdf5_header_guard.h). Read `backend` and `keras_version`.
//  2. Parse the architecture JSON (the file's `model_config`, or the --architecture file).
//  3. Find the layers: walk back from the single output layer to the InputLayer along every
//     inbound tensor (functional; a graph when a Concatenate or Add reads several), or take the
//     list (Sequential). A multi_gpu_model wrapper is recognised first and replaced by its nested
//     model.
//  4. Turn them into ModelSpec layers in the layer list's order, reading each Conv2D's kernel
//     and bias datasets and tracking every tensor's shape at the built size; fold ZeroPadding2D
//     and BatchNormalization, fuse activations where the layer before has no other reader. A
//     chain names no inputs; a graph names them (schema 1.5).
//  5. Check that every weighted layer of the weights group was used, then decide crop rules.
#include "sfrt/exporter/keras_importer.h"

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
#include "sfrt/exporter/sha256.h"
#include "sfrt/model_limits.h"

// Returns the Status of `expr` from the enclosing function when it is an error.
#define SFRT_KERAS_RETURN_IF_ERROR(expr)        \
  do {                                          \
    ::sfrt::Status sfrt_keras_status_ = (expr); \
    if (!sfrt_keras_status_.ok()) {             \
      return sfrt_keras_status_;                \
    }                                           \
  } while (false)

namespace sfrt::exporter {
namespace {

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

std::string DimsText(const std::vector<uint64_t>& dims) {
  std::string s = "(";
  for (size_t i = 0; i < dims.size(); ++i) {
    if (i > 0) s += ", ";
    s += std::to_string(dims[i]);
  }
  return s + (dims.size() == 1 ? ",)" : ")");
}

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

herr_t FirstErrorText(unsigned /*n*/, const H5E_error2_t* err, void* data) {
  auto* text = static_cast<std::string*>(data);
  if (text->empty() && err != nullptr && err->desc != nullptr) *text = err->desc;
  return 0;
}

// The most specific message on HDF5's error stack (then cleared), as " (HDF5: ...)" or "".
std::string Hdf5Error() {
  std::string text;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, FirstErrorText, &text);
  H5Eclear2(H5E_DEFAULT);
  return text.empty() ? "" : " (HDF5: " + Printable(text) + ")";
}

// Why a read of variable-length data failed: the guard's refusal (a damaged heap reference it
// stopped before libhdf5 followed it) as ": ...", else HDF5's message.
std::string ReadFailureDetail() {
  hdf5::VlenGuard* guard = hdf5::VlenGuard::Current();
  std::string refusal = guard != nullptr ? guard->TakeRefusal() : std::string();
  if (refusal.empty()) return Hdf5Error();
  H5Eclear2(H5E_DEFAULT);
  return ": " + Printable(refusal);
}

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
Status CheckStoredSize(hid_t ds, hid_t type, uint64_t count) {
  if (count == 0) return Status::Ok();
  const size_t element = H5Tget_size(type);
  H5Handle dcpl(H5Dget_create_plist(ds), H5Pclose);
  const int filters = dcpl.valid() ? H5Pget_nfilters(dcpl.get()) : -1;
  H5Handle file(H5Iget_file_id(ds), H5Fclose);
  hsize_t file_size = 0;
  if (element == 0 || element > 16 || filters < 0 || !file.valid() ||
      H5Fget_filesize(file.get(), &file_size) < 0) {
    return Status::Error("has an unreadable layout" + Hdf5Error());
  }
  const uint64_t bytes = count * element;  // count <= 2^30
  const uint64_t stored = H5Dget_storage_size(ds);
  const std::string holds = "holds " + std::to_string(count) + " values of " +
                            std::to_string(element) + " bytes (" + std::to_string(bytes) +
                            " bytes)";
  if (filters == 0 && stored < bytes) {
    return Status::Error(holds + " but stores " + std::to_string(stored) +
                         " (values never written: a damaged file)");
  }
  if (filters == 0 && bytes > file_size) {
    return Status::Error(holds + ", more than the file's " + std::to_string(file_size));
  }
  if (filters > 0 && bytes / kMaxCompression > stored) {
    return Status::Error(holds + " from " + std::to_string(stored) +
                         " compressed bytes (more than " + std::to_string(kMaxCompression) +
                         " times)");
  }
  return Status::Ok();
}

// Reads a string attribute (scalar or 1-D; fixed- or variable-length) of `obj`. `where` names the
// object in errors. Returns std::nullopt-like empty optional when the attribute does not exist.
Result<std::optional<std::vector<std::string>>> ReadStringsAttr(hid_t obj, const char* name,
                                                                const std::string& where) {
  const htri_t exists = H5Aexists(obj, name);
  if (exists < 0)
    return Status::Error(where + ": cannot look up attribute " + Quote(name) + Hdf5Error());
  if (exists == 0) return std::optional<std::vector<std::string>>();
  const std::string what = "attribute " + Quote(name) + " of " + where;
  H5Handle attr(H5Aopen(obj, name, H5P_DEFAULT), H5Aclose);
  if (!attr.valid()) return Status::Error("cannot open " + what + Hdf5Error());
  H5Handle type(H5Aget_type(attr.get()), H5Tclose);
  H5Handle space(H5Aget_space(attr.get()), H5Sclose);
  if (!type.valid() || !space.valid()) return Status::Error("cannot read " + what + Hdf5Error());
  const int rank = H5Sget_simple_extent_ndims(space.get());
  const hssize_t count = H5Sget_simple_extent_npoints(space.get());
  if (rank < 0 || rank > 1 || count < 0 || count > (1 << 24)) {
    return Status::Error(what + " is not a scalar or a list of strings");
  }
  std::vector<std::string> values;
  // Keras writes an empty list (a layer without weights) as an empty float64 array.
  if (count == 0) return std::optional<std::vector<std::string>>(values);
  if (H5Tget_class(type.get()) != H5T_STRING) {
    return Status::Error(what + " is not a string");
  }
  const htri_t variable = H5Tis_variable_str(type.get());
  if (variable < 0) return Status::Error("cannot read " + what + Hdf5Error());
  if (variable > 0) {
    H5Handle mem(H5Tcopy(H5T_C_S1), H5Tclose);
    if (!mem.valid() || H5Tset_size(mem.get(), H5T_VARIABLE) < 0 ||
        H5Tset_cset(mem.get(), H5Tget_cset(type.get())) < 0) {
      return Status::Error("cannot read " + what + Hdf5Error());
    }
    std::vector<char*> ptrs(static_cast<size_t>(count), nullptr);
    if (H5Aread(attr.get(), mem.get(), ptrs.data()) < 0) {
      // A read that fails part way (a damaged heap) leaves the strings it did read allocated.
      const std::string detail = ReadFailureDetail();
      H5Dvlen_reclaim(mem.get(), space.get(), H5P_DEFAULT, ptrs.data());
      H5Eclear2(H5E_DEFAULT);
      return Status::Error("cannot read " + what + detail);
    }
    for (char* p : ptrs) values.emplace_back(p != nullptr ? p : "");
    H5Dvlen_reclaim(mem.get(), space.get(), H5P_DEFAULT, ptrs.data());
  } else {
    const size_t size = H5Tget_size(type.get());
    if (size == 0 || size > (size_t{1} << 28) / static_cast<size_t>(count)) {
      return Status::Error(what + " has an unreasonable string size " + std::to_string(size));
    }
    H5Handle mem(H5Tcopy(H5T_C_S1), H5Tclose);
    if (!mem.valid() || H5Tset_size(mem.get(), size) < 0 ||
        H5Tset_strpad(mem.get(), H5T_STR_NULLPAD) < 0 ||
        H5Tset_cset(mem.get(), H5Tget_cset(type.get())) < 0) {
      return Status::Error("cannot read " + what + Hdf5Error());
    }
    std::vector<char> buf(size * static_cast<size_t>(count), '\0');
    if (H5Aread(attr.get(), mem.get(), buf.data()) < 0) {
      return Status::Error("cannot read " + what + Hdf5Error());
    }
    for (hssize_t i = 0; i < count; ++i) {
      const char* p = buf.data() + static_cast<size_t>(i) * size;
      size_t len = 0;
      while (len < size && p[len] != '\0') ++len;
      values.emplace_back(p, len);
    }
  }
  return std::optional<std::vector<std::string>>(std::move(values));
}

// A list attribute as Keras writes it: whole, or (when over HDF5's 64 KiB attribute limit) split
// by save_attributes_to_hdf5_group into `<name>0`, `<name>1`, ...
Result<std::optional<std::vector<std::string>>> ReadKerasList(hid_t obj, const std::string& name,
                                                              const std::string& where) {
  auto whole = ReadStringsAttr(obj, name.c_str(), where);
  if (!whole.ok() || whole->has_value()) return whole;
  std::optional<std::vector<std::string>> all;
  for (int i = 0; i < (1 << 16); ++i) {
    const std::string chunk = name + std::to_string(i);
    auto part = ReadStringsAttr(obj, chunk.c_str(), where);
    if (!part.ok()) return part;
    if (!part->has_value()) break;
    if (!all) all.emplace();
    all->insert(all->end(), (*part)->begin(), (*part)->end());
  }
  return all;
}

// --------------------------------------------------------------------------- JSON helpers

std::string JsonText(const json& v) {
  std::string s = v.dump();
  if (s.size() > 80) s = s.substr(0, 77) + "...";
  return Printable(s);
}

bool IsInt(const json& v) {
  return v.is_number_integer() ||
         (v.is_number_float() && std::isfinite(v.get<double>()) &&
          v.get<double>() == std::floor(v.get<double>()) && std::fabs(v.get<double>()) < 1e15);
}

// `v` (may be null) as an integer in [lo, hi].
bool GetInt(const json* v, int64_t lo, int64_t hi, int* out) {
  if (v == nullptr || !IsInt(*v)) return false;
  const auto i = v->is_number_float() ? static_cast<int64_t>(v->get<double>()) : v->get<int64_t>();
  if (i < lo || i > hi) return false;
  *out = static_cast<int>(i);
  return true;
}

// `v` as (a, b): an integer n gives (n, n); a list of two integers gives them.
bool GetPair(const json* v, int64_t lo, int64_t hi, std::array<int, 2>* out) {
  int n = 0;
  if (GetInt(v, lo, hi, &n)) {
    *out = {n, n};
    return true;
  }
  if (v == nullptr || !v->is_array() || v->size() != 2) return false;
  return GetInt(&(*v)[0], lo, hi, &(*out)[0]) && GetInt(&(*v)[1], lo, hi, &(*out)[1]);
}

// Keras' cropping/padding argument: n, (rows, cols) symmetric, or ((top, bottom), (left, right)).
bool GetSidePads(const json* v, Pads* out) {
  int n = 0;
  if (GetInt(v, 0, kMaxDim, &n)) {
    *out = Pads{n, n, n, n};
    return true;
  }
  if (v == nullptr || !v->is_array() || v->size() != 2) return false;
  std::array<int, 2> rows{};
  std::array<int, 2> cols{};
  if (!GetPair(&(*v)[0], 0, kMaxDim, &rows) || !GetPair(&(*v)[1], 0, kMaxDim, &cols)) return false;
  *out = Pads{rows[0], cols[0], rows[1], cols[1]};
  return true;
}

int CeilDiv(int a, int b) { return (a + b - 1) / b; }

// TensorFlow 'same' amounts for one axis: (before, after).
std::pair<int, int> SameAxis(int in, int stride, int kernel) {
  const int total = std::max((CeilDiv(in, stride) - 1) * stride + kernel - in, 0);
  return {total / 2, total - total / 2};
}

bool IsNestedModelClass(const std::string& cls) {
  return cls == "Model" || cls == "Functional" || cls == "Sequential";
}

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
void SetActivation(LayerSpec* target, Activation act, float slope) {
  if (auto* conv = std::get_if<ConvSpec>(target)) {
    conv->activation = act;
    conv->leaky_slope = slope;
  } else if (auto* deconv = std::get_if<ConvTransposeSpec>(target)) {
    deconv->activation = act;
    deconv->leaky_slope = slope;
  } else {
    auto& add = std::get<AddSpec>(*target);
    add.activation = act;
    add.leaky_slope = slope;
  }
}

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

// Whether `path` ("a/b/c", relative to `loc`: the file or the weights group) names an existing
// object, checking each component (H5Lexists fails rather than answering "no" when an
// intermediate group is missing). Each component's object header is checked before the next
// lookup (which loads it) or the caller's open: H5Lget_info gives a hard link's address without
// loading the header. An error when a header is damaged or a component is not a hard link.
Result<bool> Importer::PathExists(hid_t loc, const std::string& path) {
  const std::string base = loc == file_.get() ? "" : src_.root_label + "/";
  std::string prefix;
  size_t start = 0;
  while (start <= path.size()) {
    const size_t slash = path.find('/', start);
    const std::string part = path.substr(start, slash == std::string::npos ? slash : slash - start);
    if (part.empty()) return false;
    prefix += (prefix.empty() ? "" : "/") + part;
    if (H5Lexists(loc, prefix.c_str(), H5P_DEFAULT) <= 0) {
      H5Eclear2(H5E_DEFAULT);
      return false;
    }
    H5L_info_t info;
    if (H5Lget_info(loc, prefix.c_str(), &info, H5P_DEFAULT) < 0) {
      return Fail("cannot look up link " + Quote(base + prefix) + Hdf5Error());
    }
    if (info.type != H5L_TYPE_HARD) {
      return Fail(Quote(base + prefix) + " is a soft or external link (link type " +
                  std::to_string(static_cast<int>(info.type)) + "); Keras files use hard links");
    }
    if (Status s = headers_.CheckObject(info.u.address, Quote(base + prefix)); !s.ok()) {
      return Fail(s.message());
    }
    if (slash == std::string::npos) break;
    start = slash + 1;
  }
  return !prefix.empty();
}

// The file image through HDF5's core (in-memory) driver: HDF5 copies the bytes and never
// touches the disk.
Status Importer::OpenImage() {
  static constexpr char kSignature[] = "\x89HDF\r\n\x1a\n";
  // The superblock sits at offset 0, 512, 1024, 2048, ... (after a user block).
  bool signature = false;
  for (size_t at = 0; at + 8 <= image_.size() && !signature; at = at == 0 ? 512 : at * 2) {
    signature = image_.compare(at, 8, std::string_view(kSignature, 8)) == 0;
  }
  if (!signature) {
    return Fail("not an HDF5 file (no HDF5 signature in its " + std::to_string(image_.size()) +
                " bytes)");
  }
  // libhdf5 loads the root group's header in H5Fopen.
  if (Status root = headers_.CheckRoot(); !root.ok()) return Fail(root.message());
  H5Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  if (!fapl.valid() || H5Pset_fapl_core(fapl.get(), 1 << 16, /*backing_store=*/0) < 0 ||
      H5Pset_file_image(fapl.get(), const_cast<char*>(image_.data()), image_.size()) < 0) {
    return Fail("cannot set up an in-memory HDF5 file" + Hdf5Error());
  }
  // The name only has to differ from every file HDF5 has open (it compares names first).
  static std::atomic<unsigned> images{0};
  const std::string name = "sfrt-memory-image-" + std::to_string(images++);
  file_ = H5Handle(H5Fopen(name.c_str(), H5F_ACC_RDONLY, fapl.get()), H5Fclose);
  if (!file_.valid()) {
    return Fail("HDF5 file cannot be opened: truncated or damaged (" +
                std::to_string(image_.size()) + " bytes)" + Hdf5Error());
  }
  return Status::Ok();
}

Status Importer::Open() {
  if (Status installed = guard_.Install(); !installed.ok()) return Fail(installed.message());
  if (in_memory_) {
    SFRT_KERAS_RETURN_IF_ERROR(OpenImage());
  } else {
    SFRT_KERAS_RETURN_IF_ERROR(OpenFile());
  }
  for (auto [name, out] :
       {std::pair<const char*, std::string*>{"backend", &backend_},
        std::pair<const char*, std::string*>{"keras_version", &keras_version_}}) {
    auto value = ReadStringsAttr(file_.get(), name, "the file root");
    if (!value.ok()) return Fail(value.message());
    if (value->has_value() && (*value)->size() == 1) *out = (**value)[0];
  }
  return Status::Ok();
}

// Keras 2.4 and later run only on TensorFlow 2 ("2.4.0", "2.9.0", "3.1.0"); 2.0-2.3 (and the
// "-tf" versions tf.keras wrote up to TensorFlow 2.1) may have run on TensorFlow 1.
bool SavedOnTensorFlow2(const std::string& keras_version) {
  int major = 0;
  int minor = 0;
  char dot = 0;
  std::istringstream in(keras_version);
  if (!(in >> major >> dot >> minor) || dot != '.') return false;
  return major > 2 || (major == 2 && minor >= 4);
}

Result<ResizeCoordinates> Importer::BilinearGrid(const ChainLayer& l) {
  switch (options_.bilinear_grid) {
    case KerasBilinearGrid::kHalfPixel:
      return ResizeCoordinates::kHalfPixel;
    case KerasBilinearGrid::kAsymmetric:
      return ResizeCoordinates::kAsymmetric;
    case KerasBilinearGrid::kFromKerasVersion:
      break;
  }
  if (SavedOnTensorFlow2(keras_version_)) {
    notes_.push_back("bilinear UpSampling2D " + Quote(l.name) +
                     " samples on TensorFlow 2's half-pixel grid (the file was saved by Keras " +
                     Printable(keras_version_) + ")");
    return ResizeCoordinates::kHalfPixel;
  }
  return LayerFail(l,
                   "bilinear interpolation samples on a grid that depends on the TensorFlow "
                   "the model ran on, which a file saved by Keras " +
                       Printable(keras_version_.empty() ? "(no version)" : keras_version_) +
                       " does not record: TensorFlow 2 uses half-pixel centres, TensorFlow 1 "
                       "the asymmetric grid (align_corners=False); say which with "
                       "KerasImportOptions::bilinear_grid (sfrt export --keras-bilinear "
                       "half-pixel or asymmetric)");
}

Status Importer::OpenFile() {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path_, ec)) return Fail("no such file");
  const auto size = std::filesystem::file_size(path_, ec);
  const htri_t is_hdf5 = H5Fis_hdf5(path_.c_str());
  if (is_hdf5 <= 0) {
    const std::string detail = Hdf5Error();
    return Fail("not an HDF5 file (no HDF5 signature" +
                (ec ? std::string() : " in its " + std::to_string(size) + " bytes") + ")" + detail);
  }
  // libhdf5 loads the root group's header in H5Fopen.
  if (Status root = headers_.CheckRoot(); !root.ok()) return Fail(root.message());
  file_ = H5Handle(H5Fopen(path_.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file_.valid()) {
    return Fail("HDF5 file cannot be opened: truncated or damaged (" + std::to_string(size) +
                " bytes)" + Hdf5Error());
  }
  return Status::Ok();
}

Status Importer::FindWeightsRoot() {
  const Result<bool> has_weights = PathExists(file_.get(), "model_weights");
  if (!has_weights.ok()) return has_weights.status();
  if (*has_weights) {
    weights_group_ = H5Handle(H5Gopen2(file_.get(), "model_weights", H5P_DEFAULT), H5Gclose);
    if (!weights_group_.valid()) {
      return Fail("cannot open group 'model_weights'" + Hdf5Error());
    }
    src_.root_label = "model_weights";
    src_.root = weights_group_.get();
  } else {
    src_.root_label = "/";
    src_.root = file_.get();
  }
  const std::string where = src_.root_label == "/" ? "the file root" : "group 'model_weights'";
  auto names = ReadKerasList(src_.root, "layer_names", where);
  if (!names.ok()) return Fail(names.message());
  if (!names->has_value()) {
    return Fail(src_.root_label == "/"
                    ? "no group 'model_weights' and no attribute 'layer_names' at the root: not a "
                      "Keras model or weights file"
                    : "group 'model_weights' has no attribute 'layer_names'");
  }
  layer_names_ = std::move(**names);
  return Status::Ok();
}

Result<json> Importer::ReadArchitecture() {
  std::string text;
  std::string source;
  if (!options_.architecture_json.empty()) {
    std::ifstream in(options_.architecture_json, std::ios::binary);
    if (!in) return Status::Error(options_.architecture_json + ": cannot open architecture JSON");
    std::ostringstream buf;
    buf << in.rdbuf();
    text = buf.str();
    source = options_.architecture_json;
    const Result<bool> has_weights = PathExists(file_.get(), "model_weights");
    if (!has_weights.ok()) return has_weights.status();
    if (*has_weights) {
      notes_.push_back("the architecture comes from " + options_.architecture_json +
                       ", not from the file's own model_config");
    }
  } else {
    auto config = ReadStringsAttr(file_.get(), "model_config", "the file root");
    if (!config.ok()) return Fail(config.message());
    if (!config->has_value()) {
      return Fail(
          "no attribute 'model_config': a weights-only file (save_weights); pass the "
          "architecture JSON from model.to_json() (sfrt export --architecture FILE)");
    }
    if ((*config)->size() != 1) return Fail("attribute 'model_config' is not one string");
    text = (**config)[0];
    source = path_ + ": attribute 'model_config'";
  }
  json parsed = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (parsed.is_discarded()) return Status::Error(source + ": not valid JSON");
  if (!parsed.is_object() || !parsed.contains("class_name") || !parsed.contains("config")) {
    return Status::Error(source + ": not a Keras model description (no class_name/config)");
  }
  return parsed;
}

// obj[key], or nullptr when `obj` is not an object or has no such key.
const json* Find(const json& obj, const char* key) {
  if (!obj.is_object()) return nullptr;
  auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

// One entry of a layer list: name, class and config.
Result<ChainLayer> ReadLayerEntry(const json& entry, const std::string& where) {
  const json* cls = Find(entry, "class_name");
  const json* config = Find(entry, "config");
  if (cls == nullptr || !cls->is_string() || config == nullptr || !config->is_object()) {
    return Status::Error(where + ": a layer entry has no class_name/config: " + JsonText(entry));
  }
  ChainLayer l;
  l.cls = cls->get<std::string>();
  l.config = config;
  const json* name = Find(entry, "name");
  if (name == nullptr || !name->is_string()) name = Find(*config, "name");
  if (name == nullptr || !name->is_string() || name->get<std::string>().empty()) {
    return Status::Error(where + ": a " + Printable(l.cls) + " layer has no name");
  }
  l.name = name->get<std::string>();
  return l;
}

Result<ChainModel> Importer::ParseModel(const json& model, const std::string& label) {
  const json* cls = Find(model, "class_name");
  const json* config = Find(model, "config");
  if (cls == nullptr || !cls->is_string() || config == nullptr) {
    return Fail(label + ": no class_name/config");
  }
  const std::string c = cls->get<std::string>();
  Result<ChainModel> result = Status::Error("unset");
  if (c == "Sequential") {
    if (config->is_array()) {  // Keras <= 2.2.2: the config is the layer list
      result = ParseSequential(*config, label);
    } else if (const json* layers = Find(*config, "layers")) {
      result = ParseSequential(*layers, label);
    } else {
      return Fail(label + ": Sequential config has no layer list");
    }
  } else if (c == "Model" || c == "Functional") {
    if (!config->is_object()) return Fail(label + ": " + c + " config is not an object");
    result = ParseFunctional(*config, label);
  } else {
    return Fail(label + ": model class " + Quote(c) +
                " is not supported (supported: Model/Functional, Sequential)");
  }
  if (result.ok()) {
    if (const json* name = Find(*config, "name"); name != nullptr && name->is_string()) {
      result->name = name->get<std::string>();
    }
  }
  return result;
}

Status Importer::ReadInputShape(const ChainLayer& l, const json& shape, ChainModel* model) {
  if (!shape.is_array() || shape.size() != 4) {
    return LayerFail(
        l, "batch_input_shape " + JsonText(shape) + " is not (batch, height, width, channels)");
  }
  auto dim = [&](size_t i, int* out) {
    if (shape[i].is_null()) {
      *out = 0;
      return true;
    }
    return GetInt(&shape[i], 1, kMaxDim, out);
  };
  if (!dim(1, &model->height) || !dim(2, &model->width) || !dim(3, &model->channels) ||
      model->channels == 0 || model->channels > model_limits::kMaxChannels) {
    return LayerFail(l, "batch_input_shape " + JsonText(shape) +
                            ": height and width must be positive or None, channels in 1.." +
                            std::to_string(model_limits::kMaxChannels));
  }
  if (model->height == 0 || model->width == 0) model->height = model->width = 0;
  return Status::Ok();
}

Result<ChainModel> Importer::ParseSequential(const json& layers, const std::string& label) {
  if (!layers.is_array() || layers.empty()) return Fail(label + ": Sequential has no layers");
  ChainModel model;
  bool have_input = false;
  for (const json& entry : layers) {
    Result<ChainLayer> l = ReadLayerEntry(entry, path_ + ": " + label);
    if (!l.ok()) return l.status();
    if (!have_input) {
      const json* shape = Find(*l->config, "batch_input_shape");
      if (shape == nullptr) {
        return LayerFail(*l,
                         "the first layer of a Sequential has no batch_input_shape (the input "
                         "channels are unknown)");
      }
      SFRT_KERAS_RETURN_IF_ERROR(ReadInputShape(*l, *shape, &model));
      have_input = true;
      model.input_name = l->cls == "InputLayer" ? l->name : "input";
      if (l->cls == "InputLayer") continue;
    } else if (l->cls == "InputLayer") {
      return LayerFail(*l, "a second InputLayer inside a Sequential");
    }
    l->inbound = {model.layers.empty() ? model.input_name : model.layers.back().name};
    model.layers.push_back(*l);
  }
  return model;
}

// The layer names of "input_layers"/"output_layers": [[name, node, tensor], ...] or, as some
// Keras versions write a single one, [name, node, tensor].
std::optional<std::vector<std::string>> EndpointNames(const json* v) {
  if (v == nullptr || !v->is_array()) return std::nullopt;
  std::vector<std::string> names;
  if (!v->empty() && (*v)[0].is_string()) {
    names.push_back((*v)[0].get<std::string>());
    return names;
  }
  for (const json& e : *v) {
    if (!e.is_array() || e.empty() || !e[0].is_string()) return std::nullopt;
    names.push_back(e[0].get<std::string>());
  }
  return names;
}

Result<ChainModel> Importer::ParseFunctional(const json& config, const std::string& label) {
  const json* layers = Find(config, "layers");
  if (layers == nullptr || !layers->is_array() || layers->empty()) {
    return Fail(label + ": no layer list");
  }
  std::vector<ChainLayer> all;
  std::vector<const json*> entries;
  std::unordered_map<std::string, size_t> index;
  for (const json& entry : *layers) {
    Result<ChainLayer> l = ReadLayerEntry(entry, path_ + ": " + label);
    if (!l.ok()) return l.status();
    if (!index.emplace(l->name, all.size()).second) {
      return Fail(label + ": two layers are named " + Quote(l->name));
    }
    all.push_back(*l);
    entries.push_back(&entry);
  }
  auto inputs = EndpointNames(Find(config, "input_layers"));
  auto outputs = EndpointNames(Find(config, "output_layers"));
  if (!inputs || inputs->size() != 1) {
    return Fail(label + ": input_layers " + JsonText(config.value("input_layers", json())) +
                " is not one input (the network takes one 12-channel tensor)");
  }
  if (!outputs || outputs->size() != 1) {
    return Fail(label + ": output_layers " + JsonText(config.value("output_layers", json())) +
                " is not one output");
  }

  // The layers the output depends on: walk back along every inbound tensor.
  std::vector<bool> reached(all.size(), false);
  std::vector<size_t> input_layers;
  for (std::vector<std::string> stack{(*outputs)[0]}; !stack.empty();) {
    const std::string name = std::move(stack.back());
    stack.pop_back();
    auto it = index.find(name);
    if (it == index.end()) {
      return Fail(label + ": layer " + Quote(name) + " is referenced but not in the layer list");
    }
    if (reached[it->second]) continue;
    reached[it->second] = true;
    ChainLayer& l = all[it->second];
    if (l.cls == "InputLayer") {
      input_layers.push_back(it->second);
      continue;
    }
    const json* nodes = Find(*entries[it->second], "inbound_nodes");
    if (nodes == nullptr || !nodes->is_array() || nodes->empty()) {
      return LayerFail(l, "has no inbound node and is not an InputLayer");
    }
    if (nodes->size() != 1) {
      return LayerFail(l, "is called " + std::to_string(nodes->size()) +
                              " times; shared layers are not supported");
    }
    const json& node = (*nodes)[0];
    if (!node.is_array() || node.empty()) {
      return LayerFail(l, "inbound node " + JsonText(node) + " is not in Keras 2 format");
    }
    for (const json& tensor : node) {
      if (!tensor.is_array() || tensor.empty() || !tensor[0].is_string()) {
        return LayerFail(l, "inbound node " + JsonText(node) + " is not in Keras 2 format");
      }
      l.inbound.push_back(tensor[0].get<std::string>());
      stack.push_back(l.inbound.back());
    }
  }
  if (input_layers.size() != 1 || all[input_layers[0]].name != (*inputs)[0]) {
    std::string found;
    for (size_t i : input_layers) found += (found.empty() ? "" : ", ") + Quote(all[i].name);
    return Fail(label + ": the output depends on InputLayer " + found +
                ", not on the model input " + Quote((*inputs)[0]) + " alone");
  }
  // Keras lists a model's layers so that each comes after the layers it reads.
  for (size_t i = 0; i < all.size(); ++i) {
    if (!reached[i]) continue;
    for (const std::string& in : all[i].inbound) {
      if (index.at(in) >= i) {
        return LayerFail(all[i], "reads layer " + Quote(in) +
                                     ", which the layer list gives after it (the layer graph has "
                                     "a cycle or is out of order)");
      }
    }
  }
  const ChainLayer& input = all[input_layers[0]];
  ChainModel model;
  model.input_name = input.name;
  const json* shape = Find(*input.config, "batch_input_shape");
  if (shape == nullptr) return LayerFail(input, "has no batch_input_shape");
  SFRT_KERAS_RETURN_IF_ERROR(ReadInputShape(input, *shape, &model));
  for (size_t i = 0; i < all.size(); ++i) {
    if (reached[i] && i != input_layers[0]) model.layers.push_back(all[i]);
  }
  return model;
}

Result<std::vector<std::string>> Importer::WeightPaths(const ChainLayer& l, size_t count) {
  std::vector<std::string> paths;
  if (src_.nested) {
    if (src_.next + count > src_.nested_names.size()) {
      return LayerFail(l, "group " + GroupLabel(src_.nested_group) + " lists " +
                              std::to_string(src_.nested_names.size()) +
                              " weights, too few for the nested model's layers");
    }
    for (size_t i = 0; i < count; ++i) {
      paths.push_back(src_.nested_group + "/" + src_.nested_names[src_.next++]);
    }
    return paths;
  }
  const std::string group = GroupLabel(l.name);
  const Result<bool> exists = PathExists(src_.root, l.name);
  if (!exists.ok()) return exists.status();
  if (!*exists) {
    return LayerFail(l, "weights group " + group + " is missing");
  }
  if (std::find(layer_names_.begin(), layer_names_.end(), l.name) == layer_names_.end()) {
    return LayerFail(l, "weights group " + group + " is not listed in attribute 'layer_names'");
  }
  H5Handle g(H5Gopen2(src_.root, l.name.c_str(), H5P_DEFAULT), H5Gclose);
  if (!g.valid()) return LayerFail(l, "cannot open weights group " + group + Hdf5Error());
  auto names = ReadKerasList(g.get(), "weight_names", "group " + group);
  if (!names.ok()) return LayerFail(l, names.message());
  if (!names->has_value()) {
    return LayerFail(l, "weights group " + group + " has no attribute 'weight_names'");
  }
  const std::vector<std::string>& listed = **names;
  if (listed.size() != count) {
    std::string text;
    for (const std::string& n : listed) text += (text.empty() ? "" : ", ") + Quote(n);
    return LayerFail(l, "weights group " + group + " lists " + std::to_string(listed.size()) +
                            " weights [" + text + "]; expected " + std::to_string(count) +
                            (count == 2 ? " (kernel, bias)" : " (kernel; use_bias is false)"));
  }
  for (const std::string& n : listed) paths.push_back(l.name + "/" + n);
  used_groups_.insert(l.name);
  return paths;
}

Result<std::vector<float>> Importer::ReadDataset(const ChainLayer& l, const std::string& path,
                                                 const std::vector<uint64_t>& want,
                                                 const std::string& meaning) {
  const std::string label = "dataset " + GroupLabel(path);
  const Result<bool> exists = PathExists(src_.root, path);
  if (!exists.ok()) return exists.status();
  if (!*exists) return LayerFail(l, label + " is missing");
  H5Handle ds(H5Dopen2(src_.root, path.c_str(), H5P_DEFAULT), H5Dclose);
  if (!ds.valid()) return LayerFail(l, "cannot open " + label + Hdf5Error());
  H5Handle type(H5Dget_type(ds.get()), H5Tclose);
  H5Handle space(H5Dget_space(ds.get()), H5Sclose);
  if (!type.valid() || !space.valid()) return LayerFail(l, "cannot read " + label + Hdf5Error());
  if (H5Tget_class(type.get()) != H5T_FLOAT) {
    return LayerFail(l, label + " is not floating point");
  }
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0 || rank > 8) return LayerFail(l, label + " has an unreadable shape" + Hdf5Error());
  std::vector<hsize_t> dims(static_cast<size_t>(rank));
  if (rank > 0 && H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr) < 0) {
    return LayerFail(l, label + " has an unreadable shape" + Hdf5Error());
  }
  const std::vector<uint64_t> have(dims.begin(), dims.end());
  if (have != want) {
    return LayerFail(
        l, label + " has shape " + DimsText(have) + "; expected " + DimsText(want) + " " + meaning);
  }
  uint64_t n = 1;
  for (uint64_t d : want) {
    if (d != 0 && n > kMaxTensorElements / d) return LayerFail(l, label + " is too large");
    n *= d;
  }
  if (Status stored = CheckStoredSize(ds.get(), type.get(), n); !stored.ok()) {
    return LayerFail(l, label + " " + stored.message());
  }
  std::vector<float> values(static_cast<size_t>(n));
  if (n > 0 &&
      H5Dread(ds.get(), H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0) {
    return LayerFail(l, "cannot read " + label + Hdf5Error());
  }
  for (float v : values) {
    if (!std::isfinite(v)) return LayerFail(l, label + " holds non-finite values");
  }
  return values;
}

Status CheckChannelsLast(const ChainLayer& l, const std::string& path) {
  const json* f = Find(*l.config, "data_format");
  if (f == nullptr || f->is_null() ||
      (f->is_string() && f->get<std::string>() == "channels_last")) {
    return Status::Ok();
  }
  return Status::Error(path + ": layer " + Quote(l.name) + " (" + Printable(l.cls) +
                       "): data_format " + JsonText(*f) + " is not supported (only channels_last)");
}

Result<std::string> Importer::SameOrValid(const ChainLayer& l) const {
  const json* p = Find(*l.config, "padding");
  if (p == nullptr) return std::string("valid");
  if (!p->is_string()) return LayerFail(l, "padding " + JsonText(*p) + " is not a string");
  std::string padding = p->get<std::string>();
  if (padding != "same" && padding != "valid") {
    return LayerFail(l, "padding " + Quote(padding) + " is not supported (same, valid)");
  }
  return padding;
}

// Keras' Conv2DTranspose is TensorFlow's conv2d_transpose: input pixel i scatters kernel tap k
// to output row i * stride + k * dilation - top, kernel (kh, kw, filters, in). Its output length
// L (Keras' deconv_output_length, with the dilated extent e = (k - 1) * d + 1) is in * stride
// (+ max(e - stride, 0) for 'valid') without output_padding, else (in - 1) * stride + e -
// 2 * pad + output_padding with pad = e / 2 for 'same' and 0 for 'valid'. TensorFlow places
// it like the forward convolution of an L-long input: 'valid' crops nothing at the top, 'same'
// crops top = total / 2 of total = max((in - 1) * stride + e - L, 0). The full output
// ((in - 1) * stride + e rows) then loses `top` rows at the top and what exceeds L at the
// bottom, or gains zero rows (bias only) there up to L. Neither amount depends on `in`.
Result<ConvTransposeSpec> Importer::ReadConvTranspose(const ChainLayer& l, int in_channels) {
  const json& cfg = *l.config;
  ConvTransposeSpec d;
  d.name = l.name;
  d.in_channels = in_channels;
  if (!GetInt(Find(cfg, "filters"), 1, model_limits::kMaxChannels, &d.out_channels)) {
    return LayerFail(l, "'filters' is missing or not an integer in 1.." +
                            std::to_string(model_limits::kMaxChannels));
  }
  std::array<int, 2> kernel{};
  if (!GetPair(Find(cfg, "kernel_size"), 1, model_limits::kMaxKernel, &kernel)) {
    return LayerFail(l, "'kernel_size' is missing or not integers in 1.." +
                            std::to_string(model_limits::kMaxKernel));
  }
  std::array<int, 2> strides{1, 1};
  if (const json* st = Find(cfg, "strides");
      st != nullptr && !GetPair(st, 1, model_limits::kMaxStride, &strides)) {
    return LayerFail(l, "strides " + JsonText(*st) + " are not integers in 1.." +
                            std::to_string(model_limits::kMaxStride));
  }
  std::array<int, 2> dilation{1, 1};
  if (const json* dr = Find(cfg, "dilation_rate");
      dr != nullptr && !GetPair(dr, 1, model_limits::kMaxDilation, &dilation)) {
    return LayerFail(l, "dilation_rate " + JsonText(*dr) + " is not integers in 1.." +
                            std::to_string(model_limits::kMaxDilation));
  }
  Result<std::string> padding = SameOrValid(l);
  if (!padding.ok()) return padding.status();
  const json* op = Find(cfg, "output_padding");
  std::array<int, 2> output_padding{};
  const bool has_output_padding = op != nullptr && !op->is_null();
  if (has_output_padding && !GetPair(op, 0, model_limits::kMaxStride, &output_padding)) {
    return LayerFail(l, "output_padding " + JsonText(*op) + " is not integers >= 0");
  }
  d.kernel_h = kernel[0];
  d.kernel_w = kernel[1];
  d.stride_h = strides[0];
  d.stride_w = strides[1];
  d.dilation_h = dilation[0];
  d.dilation_w = dilation[1];
  const bool same = *padding == "same";
  // Per axis: the rows cropped at the top and bottom and added at the bottom, from the output
  // length at an input of one pixel (the amounts are the same at every length).
  struct Placement {
    int top = 0, bottom = 0, added = 0;
  };
  auto place = [&](int k, int s, int dil, int out_pad) {
    const int e = DilatedExtent(k, dil);
    const int length = !has_output_padding ? s + (same ? 0 : std::max(e - s, 0))
                                           : e - 2 * (same ? e / 2 : 0) + out_pad;
    Placement p;
    p.top = same ? std::max(e - length, 0) / 2 : 0;
    const int rest = e - p.top;  // full rows after the top crop
    p.bottom = std::max(rest - length, 0);
    p.added = std::max(length - rest, 0);
    return p;
  };
  const Placement ph = place(d.kernel_h, d.stride_h, d.dilation_h, output_padding[0]);
  const Placement pw = place(d.kernel_w, d.stride_w, d.dilation_w, output_padding[1]);
  if (ph.added >= d.stride_h || pw.added >= d.stride_w) {
    return LayerFail(l, "its output gains " + std::to_string(std::max(ph.added, pw.added)) +
                            " zero rows or columns beyond the kernel's reach; the model format "
                            "takes fewer than the stride");
  }
  d.pads = Pads{ph.top, pw.top, ph.bottom, pw.bottom};
  d.output_padding_h = ph.added;
  d.output_padding_w = pw.added;
  bool use_bias = true;
  if (const json* b = Find(cfg, "use_bias")) {
    if (!b->is_boolean()) return LayerFail(l, "use_bias " + JsonText(*b) + " is not a bool");
    use_bias = b->get<bool>();
  }
  std::string activation = "linear";
  if (const json* a = Find(cfg, "activation")) {
    activation = a->is_string() ? a->get<std::string>() : JsonText(*a);
  }
  if (activation != "linear" && activation != "relu") {
    return LayerFail(l, "activation " + Quote(activation) + " is not supported (linear, relu)");
  }
  d.activation = activation == "relu" ? Activation::kRelu : Activation::kNone;
  Result<std::vector<std::string>> paths = WeightPaths(l, use_bias ? 2 : 1);
  if (!paths.ok()) return paths.status();
  const auto kh = static_cast<size_t>(d.kernel_h), kw = static_cast<size_t>(d.kernel_w);
  const auto ci = static_cast<size_t>(in_channels), co = static_cast<size_t>(d.out_channels);
  auto kernel_values =
      ReadDataset(l, (*paths)[0], {kh, kw, co, ci},
                  "(kernel_size " + std::to_string(kh) + "x" + std::to_string(kw) + ", filters " +
                      std::to_string(co) + ", " + std::to_string(ci) + " input channels)");
  if (!kernel_values.ok()) return kernel_values.status();
  // (kh, kw, out, in) -> HWIO (kh, kw, in, out).
  d.weights_hwio.resize(kernel_values->size());
  for (size_t t = 0; t < kh * kw; ++t) {
    for (size_t o = 0; o < co; ++o) {
      for (size_t i = 0; i < ci; ++i) {
        d.weights_hwio[(t * ci + i) * co + o] = (*kernel_values)[(t * co + o) * ci + i];
      }
    }
  }
  if (use_bias) {
    auto bias = ReadDataset(l, (*paths)[1], {co}, "(filters " + std::to_string(co) + ")");
    if (!bias.ok()) return bias.status();
    d.bias = std::move(bias).value();
  } else {
    d.bias.assign(co, 0.0f);
  }
  return d;
}

// Every layer a layer reads is computed before it, and a ZeroPadding2D is read only by the
// convolution it folds into (or another ZeroPadding2D).
Status Importer::CheckInbound(const BuildState& s, const ChainLayer& l) const {
  for (const std::string& name : l.inbound) {
    const auto found = s.tensors.find(name);
    if (found == s.tensors.end()) {
      return LayerFail(l, "reads layer " + Quote(name) + ", which is not computed before it");
    }
    const Tensor& t = found->second;
    if (t.pad_layer != nullptr && l.cls != "Conv2D" && l.cls != "DepthwiseConv2D" &&
        l.cls != "ZeroPadding2D") {
      return LayerFail(*t.pad_layer,
                       "must be followed by a Conv2D with padding 'valid' (it is "
                       "folded into the convolution), but is followed by layer " +
                           Quote(l.name) + " (" + Printable(l.cls) + ")");
    }
  }
  return Status::Ok();
}

Status Importer::OneInput(const LayerBuild& b, const char* what) const {
  if (b.l.inbound.size() == 1) return Status::Ok();
  return LayerFail(
      b.l, "reads " + std::to_string(b.l.inbound.size()) + " tensors; " + what + " reads one");
}

void Importer::AddLayer(LayerBuild& b, LayerSpec layer) {
  b.s.tensors[b.l.name] =
      Tensor{b.h, b.w, b.c, b.l.name, static_cast<int>(b.s.spec->layers.size()), {}, nullptr};
  b.s.spec->layers.push_back(std::move(layer));
}

LayerSpec* Importer::FusionTarget(LayerBuild& b, bool add_too) {
  const Tensor& in = b.in;
  if (in.index < 0 || in.pad_layer != nullptr || b.s.readers[b.l.inbound[0]].size() != 1) {
    return nullptr;
  }
  LayerSpec* target = &b.s.spec->layers[static_cast<size_t>(in.index)];
  if (const auto* conv = std::get_if<ConvSpec>(target)) {
    return conv->activation == Activation::kNone ? target : nullptr;
  }
  if (const auto* deconv = std::get_if<ConvTransposeSpec>(target)) {
    return deconv->activation == Activation::kNone ? target : nullptr;
  }
  if (const auto* add = std::get_if<AddSpec>(target); add != nullptr && add_too) {
    return add->activation == Activation::kNone ? target : nullptr;
  }
  return nullptr;
}

Status Importer::FusionRefused(LayerBuild& b, const std::string& what) {
  std::string also;
  for (const ChainLayer* r : b.s.readers[b.l.inbound[0]]) {
    if (r != &b.l) also += (also.empty() ? "" : ", ") + Quote(r->name);
  }
  return LayerFail(b.l, what + (also.empty() ? "" : "; its input is also read by layer " + also));
}

Importer::LayerBuilder Importer::BuilderOf(std::string_view cls) {
  static constexpr std::pair<std::string_view, LayerBuilder> kBuilders[] = {
      {"Conv2D", &Importer::BuildConvolution},
      {"DepthwiseConv2D", &Importer::BuildConvolution},
      {"BatchNormalization", &Importer::BuildBatchNormalization},
      {"LeakyReLU", &Importer::BuildLeakyRelu},
      {"Activation", &Importer::BuildActivation},
      {"Conv2DTranspose", &Importer::BuildConvTranspose},
      {"MaxPooling2D", &Importer::BuildPooling},
      {"AveragePooling2D", &Importer::BuildPooling},
      {"UpSampling2D", &Importer::BuildUpSampling},
      {"Cropping2D", &Importer::BuildCropping},
      {"ZeroPadding2D", &Importer::BuildZeroPadding},
      {"Concatenate", &Importer::BuildMerge},
      {"Add", &Importer::BuildMerge},
  };
  for (const auto& [name, builder] : kBuilders) {
    if (name == cls) return builder;
  }
  return nullptr;
}

// Conv2D and DepthwiseConv2D.
Status Importer::BuildConvolution(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& h = b.h;
  int& w = b.w;
  int& c = b.c;
  Pads& pending = b.pending;
  const ChainLayer*& pending_pad = b.pending_pad;
  // DepthwiseConv2D: depth_multiplier outputs per input channel, kernel (kh, kw, in,
  // multiplier), which is HWIO with one input per group (output c * multiplier + m).
  const bool depthwise = l.cls == "DepthwiseConv2D";
  if (Status s = OneInput(b, depthwise ? "a DepthwiseConv2D" : "a Conv2D"); !s.ok()) return s;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  auto field = [&](const char* key) { return Find(cfg, key); };
  int filters_value = 0;
  std::array<int, 2> kernel_value{};
  int groups = 1;
  if (depthwise) {
    int multiplier = 1;
    if (const json* m = field("depth_multiplier");
        m != nullptr && !GetInt(m, 1, model_limits::kMaxChannels / c, &multiplier)) {
      return LayerFail(l, "depth_multiplier " + JsonText(*m) + " is not an integer in 1.." +
                              std::to_string(model_limits::kMaxChannels / c));
    }
    filters_value = c * multiplier;
    groups = c;
  } else if (!GetInt(field("filters"), 1, model_limits::kMaxChannels, &filters_value)) {
    return LayerFail(l, "'filters' is missing or not an integer in 1.." +
                            std::to_string(model_limits::kMaxChannels));
  }
  if (!GetPair(field("kernel_size"), 1, model_limits::kMaxKernel, &kernel_value)) {
    return LayerFail(l, "'kernel_size' is missing or not integers in 1.." +
                            std::to_string(model_limits::kMaxKernel));
  }
  const int* filters = &filters_value;
  const std::array<int, 2>* kernel = &kernel_value;
  std::array<int, 2> strides{1, 1};
  if (const json* s = field("strides")) {
    if (!GetPair(s, 1, model_limits::kMaxStride, &strides)) {
      return LayerFail(l, "strides " + JsonText(*s) + " are not integers in 1.." +
                              std::to_string(model_limits::kMaxStride));
    }
  }
  std::array<int, 2> dilation{1, 1};
  if (const json* d = field("dilation_rate")) {
    if (!GetPair(d, 1, model_limits::kMaxDilation, &dilation)) {
      return LayerFail(l, "dilation_rate " + JsonText(*d) + " is not integers in 1.." +
                              std::to_string(model_limits::kMaxDilation));
    }
  }
  if (const json* g = field("groups"); g != nullptr && !depthwise) {
    if (!GetInt(g, 1, c, &groups) || c % groups != 0 || filters_value % groups != 0) {
      return LayerFail(l, "groups " + JsonText(*g) + " does not divide its " + std::to_string(c) +
                              " input channels and " + std::to_string(filters_value) + " filters");
    }
  }
  Result<std::string> padding_value = SameOrValid(l);
  if (!padding_value.ok()) return padding_value.status();
  const std::string& padding = *padding_value;
  bool use_bias = true;
  if (const json* flag = field("use_bias")) {
    if (!flag->is_boolean()) return LayerFail(l, "use_bias " + JsonText(*flag) + " is not a bool");
    use_bias = flag->get<bool>();
  }
  std::string activation = "linear";
  if (const json* a = field("activation")) {
    if (!a->is_string()) {
      return LayerFail(l, "activation " + JsonText(*a) + " is not supported (linear, relu)");
    }
    activation = a->get<std::string>();
  }
  if (activation != "linear" && activation != "relu") {
    return LayerFail(l, "activation " + Quote(activation) + " is not supported (linear, relu)");
  }

  ConvSpec conv;
  conv.name = l.name;
  conv.in_channels = c;
  conv.out_channels = *filters;
  conv.kernel_h = (*kernel)[0];
  conv.kernel_w = (*kernel)[1];
  conv.stride_h = strides[0];
  conv.stride_w = strides[1];
  conv.dilation_h = dilation[0];
  conv.dilation_w = dilation[1];
  conv.groups = groups;
  conv.activation = activation == "relu" ? Activation::kRelu : Activation::kNone;
  // The window's rows and columns (the kernel's dilated extent).
  const int extent_h = DilatedExtent(conv.kernel_h, conv.dilation_h);
  const int extent_w = DilatedExtent(conv.kernel_w, conv.dilation_w);
  if (padding == "same") {
    if (pending_pad != nullptr) {
      return LayerFail(l, "follows ZeroPadding2D " + Quote(pending_pad->name) +
                              " but pads 'same'; only padding 'valid' can absorb it");
    }
    conv.padding_rule = PaddingRule::kSameUpper;
    if (b.s.known) {
      const auto [top, bottom] = SameAxis(h, conv.stride_h, extent_h);
      const auto [left, right] = SameAxis(w, conv.stride_w, extent_w);
      conv.pads = Pads{top, left, bottom, right};
    }
  } else {
    conv.padding_rule = PaddingRule::kExplicit;
    conv.pads = pending;
    // The model format takes explicit pads of at most kernel - 1 per side (as the loader).
    for (const auto& [amount, side, size] : {std::tuple{conv.pads.top, "top", extent_h},
                                             std::tuple{conv.pads.bottom, "bottom", extent_h},
                                             std::tuple{conv.pads.left, "left", extent_w},
                                             std::tuple{conv.pads.right, "right", extent_w}}) {
      if (amount > model_limits::MaxPad(size)) {
        return LayerFail(
            l, "follows ZeroPadding2D " + Quote(pending_pad != nullptr ? pending_pad->name : "") +
                   " whose padding gives it " + std::to_string(amount) + " on the " + side +
                   "; a " + std::to_string(conv.kernel_h) + "x" + std::to_string(conv.kernel_w) +
                   " kernel takes at most " + std::to_string(model_limits::MaxPad(size)));
      }
    }
  }
  pending = Pads{};
  pending_pad = nullptr;
  if (b.s.known) {
    const int ph = h + conv.pads.top + conv.pads.bottom;
    const int pw = w + conv.pads.left + conv.pads.right;
    if (ph < extent_h || pw < extent_w) {
      return LayerFail(l, "its " + std::to_string(ph) + "x" + std::to_string(pw) +
                              " input at the built size is smaller than the kernel");
    }
    h = (ph - extent_h) / conv.stride_h + 1;
    w = (pw - extent_w) / conv.stride_w + 1;
  }
  Result<std::vector<std::string>> paths = WeightPaths(l, use_bias ? 2 : 1);
  if (!paths.ok()) return paths.status();
  const std::string meaning =
      "(kernel_size " + std::to_string(conv.kernel_h) + "x" + std::to_string(conv.kernel_w) + ", " +
      std::to_string(c) + " input channels, " +
      (depthwise ? "depth_multiplier " + std::to_string(*filters / c)
                 : "filters " + std::to_string(*filters) +
                       (groups > 1 ? ", groups " + std::to_string(groups) : "")) +
      ")";
  // Conv2D: (kh, kw, in / groups, filters); DepthwiseConv2D: (kh, kw, in, multiplier).
  const uint64_t third = depthwise ? static_cast<uint64_t>(c) : static_cast<uint64_t>(c / groups);
  const uint64_t fourth =
      depthwise ? static_cast<uint64_t>(*filters / c) : static_cast<uint64_t>(*filters);
  auto kernel_values = ReadDataset(
      l, (*paths)[0],
      {static_cast<uint64_t>(conv.kernel_h), static_cast<uint64_t>(conv.kernel_w), third, fourth},
      meaning);
  if (!kernel_values.ok()) return kernel_values.status();
  conv.weights_hwio = std::move(kernel_values).value();
  if (use_bias) {
    auto bias = ReadDataset(l, (*paths)[1], {static_cast<uint64_t>(*filters)},
                            "(filters " + std::to_string(*filters) + ")");
    if (!bias.ok()) return bias.status();
    conv.bias = std::move(bias).value();
  } else {
    conv.bias.assign(static_cast<size_t>(*filters), 0.0f);
  }
  c = *filters;
  conv.inputs = {in.layer};
  ++b.s.convs;
  AddLayer(b, std::move(conv));
  return Status::Ok();
}

// Inference normalisation with the moving statistics, folded into the convolution before it.
Status Importer::BuildBatchNormalization(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& c = b.c;
  // Inference normalisation with the moving statistics, folded into the Conv2D before it:
  // weights * gamma / sqrt(var + epsilon) per output channel, bias shifted.
  if (Status s = OneInput(b, "a BatchNormalization"); !s.ok()) return s;
  LayerSpec* target = FusionTarget(b, false);
  if (target == nullptr) {
    return FusionRefused(
        b,
        "must directly follow a Conv2D, DepthwiseConv2D or Conv2DTranspose with activation "
        "'linear' (it is folded into the convolution's weights and bias)");
  }
  const json* axis = Find(cfg, "axis");
  const json* axis_value =
      axis != nullptr && axis->is_array() && axis->size() == 1 ? &(*axis)[0] : axis;
  if (axis_value != nullptr &&
      !(axis_value->is_number_integer() &&
        (axis_value->get<int64_t>() == -1 || axis_value->get<int64_t>() == 3))) {
    return LayerFail(
        l, "axis " + JsonText(*axis) + " is not supported (only the channels axis, -1 or 3)");
  }
  auto flag = [&](const char* key) {
    const json* v = Find(cfg, key);
    return v == nullptr || !v->is_boolean() || v->get<bool>();
  };
  const bool scale = flag("scale"), center = flag("center");
  const json* eps = Find(cfg, "epsilon");
  const double epsilon = eps != nullptr && eps->is_number() ? eps->get<double>() : 1e-3;
  if (!(epsilon >= 0) || !std::isfinite(epsilon)) {
    return LayerFail(l, "epsilon " + JsonText(*eps) + " is not a finite number >= 0");
  }
  const size_t count = (scale ? 1 : 0) + (center ? 1 : 0) + 2;
  Result<std::vector<std::string>> paths = WeightPaths(l, count);
  if (!paths.ok()) return paths.status();
  std::vector<float> values[4];  // gamma, beta, moving_mean, moving_variance
  static const char* const kNames[4] = {"gamma", "beta", "moving_mean", "moving_variance"};
  size_t next = 0;
  for (int k = 0; k < 4; ++k) {
    if ((k == 0 && !scale) || (k == 1 && !center)) {
      values[k].assign(static_cast<size_t>(c), k == 0 ? 1.0f : 0.0f);
      return Status::Ok();
    }
    auto v = ReadDataset(l, (*paths)[next++], {static_cast<uint64_t>(c)},
                         std::string("(") + kNames[k] + ", " + std::to_string(c) + " channels)");
    if (!v.ok()) return v.status();
    values[k] = std::move(v).value();
  }
  ChannelAffine affine;
  const long bad = BatchNormAffine(values[0], values[1], values[2], values[3], epsilon, &affine);
  if (bad >= 0) {
    return LayerFail(
        l, "channel " + std::to_string(bad) + ": moving_variance + epsilon = " +
               std::to_string(static_cast<double>(values[3][static_cast<size_t>(bad)]) + epsilon) +
               " is not positive");
  }
  if (auto* conv = std::get_if<ConvSpec>(target)) {
    FoldIntoConv(affine, conv);
  } else {
    FoldIntoConv(affine, &std::get<ConvTransposeSpec>(*target));
  }
  b.s.tensors[l.name] = in;  // an activation may still follow and fuse
  return Status::Ok();
}

// LeakyReLU, fused into the convolution or Add before it.
Status Importer::BuildLeakyRelu(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  if (Status s = OneInput(b, "a LeakyReLU"); !s.ok()) return s;
  const json* alpha = Find(cfg, "alpha");
  if (alpha == nullptr) {
    return LayerFail(l,
                     "config has no 'alpha' (the negative slope; Keras 2 always stores "
                     "it, default 0.3)");
  }
  if (!alpha->is_number() || !std::isfinite(alpha->get<double>())) {
    return LayerFail(l, "alpha " + JsonText(*alpha) + " is not a finite number");
  }
  LayerSpec* target = FusionTarget(b, true);
  if (target == nullptr) {
    return FusionRefused(
        b,
        "must directly follow a convolution with activation 'linear' or an Add (it is "
        "fused into it)");
  }
  SetActivation(target, Activation::kLeakyRelu, static_cast<float>(alpha->get<double>()));
  b.s.tensors[l.name] = in;
  return Status::Ok();
}

// Activation: linear (nothing) or relu, fused into the convolution or Add before it.
Status Importer::BuildActivation(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  if (Status s = OneInput(b, "an Activation"); !s.ok()) return s;
  const json* a = Find(cfg, "activation");
  const std::string act = a != nullptr && a->is_string() ? a->get<std::string>() : "";
  if (act == "linear") {  // identity
    b.s.tensors[l.name] = in;
    return Status::Ok();
  }
  if (act != "relu") {
    return LayerFail(l, "activation " + (a ? JsonText(*a) : std::string("(missing)")) +
                            " is not supported (linear, relu)");
  }
  LayerSpec* target = FusionTarget(b, true);
  if (target == nullptr) {
    return FusionRefused(
        b,
        "must directly follow a convolution with activation 'linear' or an Add (it is "
        "fused into it)");
  }
  SetActivation(target, Activation::kRelu, 0.0f);
  b.s.tensors[l.name] = in;
  return Status::Ok();
}

// Conv2DTranspose.
Status Importer::BuildConvTranspose(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const Tensor& in = b.in;
  int& h = b.h;
  int& w = b.w;
  int& c = b.c;
  if (Status st = OneInput(b, "a Conv2DTranspose"); !st.ok()) return st;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  Result<ConvTransposeSpec> deconv = ReadConvTranspose(l, c);
  if (!deconv.ok()) return deconv.status();
  if (b.s.known) {
    h = (h - 1) * deconv->stride_h + DilatedExtent(deconv->kernel_h, deconv->dilation_h) -
        deconv->pads.top - deconv->pads.bottom + deconv->output_padding_h;
    w = (w - 1) * deconv->stride_w + DilatedExtent(deconv->kernel_w, deconv->dilation_w) -
        deconv->pads.left - deconv->pads.right + deconv->output_padding_w;
    if (h < 1 || w < 1) {
      return LayerFail(l, "crops its output at the built size to nothing");
    }
  }
  c = deconv->out_channels;
  deconv->inputs = {in.layer};
  ++b.s.convs;
  AddLayer(b, std::move(deconv).value());
  return Status::Ok();
}

// MaxPooling2D and AveragePooling2D.
Status Importer::BuildPooling(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& h = b.h;
  int& w = b.w;
  if (Status st = OneInput(b, l.cls == "MaxPooling2D" ? "a MaxPooling2D" : "an AveragePooling2D");
      !st.ok()) {
    return st;
  }
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  std::array<int, 2> size{2, 2};
  if (const json* ps = Find(cfg, "pool_size");
      ps != nullptr && !GetPair(ps, 1, model_limits::kMaxKernel, &size)) {
    return LayerFail(l, "pool_size " + JsonText(*ps) + " is not integers in 1.." +
                            std::to_string(model_limits::kMaxKernel));
  }
  std::array<int, 2> strides = size;  // Keras: strides None means pool_size
  if (const json* st = Find(cfg, "strides");
      st != nullptr && !st->is_null() && !GetPair(st, 1, model_limits::kMaxStride, &strides)) {
    return LayerFail(l, "strides " + JsonText(*st) + " are not integers in 1.." +
                            std::to_string(model_limits::kMaxStride));
  }
  Result<std::string> padding = SameOrValid(l);
  if (!padding.ok()) return padding.status();
  PoolSpec pool;
  pool.name = l.name;
  pool.kind = l.cls == "MaxPooling2D" ? PoolKind::kMax : PoolKind::kAverage;
  pool.kernel_h = size[0];
  pool.kernel_w = size[1];
  pool.stride_h = strides[0];
  pool.stride_w = strides[1];
  // TensorFlow's 'same' pads the larger half at the bottom/right; its averages count only
  // the input positions under the window.
  pool.count_include_pad = false;
  if (*padding == "same") {
    pool.padding_rule = PaddingRule::kSameUpper;
    if (b.s.known) {
      const auto [top, bottom] = SameAxis(h, pool.stride_h, pool.kernel_h);
      const auto [left, right] = SameAxis(w, pool.stride_w, pool.kernel_w);
      pool.pads = Pads{top, left, bottom, right};
    }
  }
  if (b.s.known) {
    const int ph = h + pool.pads.top + pool.pads.bottom;
    const int pw = w + pool.pads.left + pool.pads.right;
    if (ph < pool.kernel_h || pw < pool.kernel_w) {
      return LayerFail(l, "its " + std::to_string(h) + "x" + std::to_string(w) +
                              " input at the built size is smaller than the pool");
    }
    h = (ph - pool.kernel_h) / pool.stride_h + 1;
    w = (pw - pool.kernel_w) / pool.stride_w + 1;
  }
  pool.inputs = {in.layer};
  AddLayer(b, std::move(pool));
  return Status::Ok();
}

// UpSampling2D: nearest (Upsample) or bilinear (Resize).
Status Importer::BuildUpSampling(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& h = b.h;
  int& w = b.w;
  if (Status s = OneInput(b, "an UpSampling2D"); !s.ok()) return s;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  std::array<int, 2> factors_value{};
  const std::array<int, 2>* factors = &factors_value;
  if (!GetPair(Find(cfg, "size"), 1, model_limits::kMaxUpsample, &factors_value)) {
    return LayerFail(
        l, "'size' is missing or not integers in 1.." + std::to_string(model_limits::kMaxUpsample));
  }
  bool bilinear = false;
  if (const json* interp = Find(cfg, "interpolation")) {
    bilinear = interp->is_string() && interp->get<std::string>() == "bilinear";
    if (!bilinear && (!interp->is_string() || interp->get<std::string>() != "nearest")) {
      return LayerFail(
          l, "interpolation " + JsonText(*interp) + " is not supported (nearest or bilinear)");
    }
  }
  h *= (*factors)[0];
  w *= (*factors)[1];
  if (bilinear) {
    Result<ResizeCoordinates> grid = BilinearGrid(l);
    if (!grid.ok()) return grid.status();
    ResizeSpec resize;
    resize.name = l.name;
    resize.params.mode = ResizeMode::kLinear;
    resize.params.coordinates = *grid;
    resize.params.scale_num_h = (*factors)[0];
    resize.params.scale_num_w = (*factors)[1];
    resize.inputs = {in.layer};
    AddLayer(b, std::move(resize));
  } else {
    UpsampleSpec up;
    up.name = l.name;
    up.factor_h = (*factors)[0];
    up.factor_w = (*factors)[1];
    up.inputs = {in.layer};
    AddLayer(b, std::move(up));
  }
  return Status::Ok();
}

// Cropping2D: its amounts now; its rule after every layer is built (ChooseCropRules).
Status Importer::BuildCropping(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& h = b.h;
  int& w = b.w;
  if (Status s = OneInput(b, "a Cropping2D"); !s.ok()) return s;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  Pads amounts_value;
  const Pads* amounts = &amounts_value;
  if (!GetSidePads(Find(cfg, "cropping"), &amounts_value)) {
    return LayerFail(l, "'cropping' is missing or not ((top, bottom), (left, right))");
  }
  if (b.s.known) {
    const int oh = h - amounts->top - amounts->bottom;
    const int ow = w - amounts->left - amounts->right;
    if (oh < 1 || ow < 1) {
      return LayerFail(l, "crops its " + std::to_string(h) + "x" + std::to_string(w) +
                              " input at the built size to nothing");
    }
    h = oh;
    w = ow;
  }
  CropSpec crop;
  crop.name = l.name;
  crop.rule = CropRule::kExplicit;
  crop.amounts = *amounts;
  crop.inputs = {in.layer};
  b.s.crops.push_back({b.s.spec->layers.size(), l.name, h, w});
  AddLayer(b, std::move(crop));
  return Status::Ok();
}

// ZeroPadding2D: amounts waiting for the convolution that reads it.
Status Importer::BuildZeroPadding(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  if (Status s = OneInput(b, "a ZeroPadding2D"); !s.ok()) return s;
  SFRT_KERAS_RETURN_IF_ERROR(CheckChannelsLast(l, path_));
  Pads amounts_value;
  const Pads* amounts = &amounts_value;
  if (!GetSidePads(Find(cfg, "padding"), &amounts_value)) {
    return LayerFail(l, "'padding' is missing or not ((top, bottom), (left, right))");
  }
  Tensor padded = in;
  padded.pads.top += amounts->top;
  padded.pads.left += amounts->left;
  padded.pads.bottom += amounts->bottom;
  padded.pads.right += amounts->right;
  padded.pad_layer = &l;
  b.s.tensors[l.name] = padded;
  return Status::Ok();
}

// Concatenate (channels) and Add.
Status Importer::BuildMerge(LayerBuild& b) {
  const ChainLayer& l = b.l;
  const json& cfg = *l.config;
  const Tensor& in = b.in;
  int& c = b.c;
  const bool concat = l.cls == "Concatenate";
  if (concat) {
    const json* axis = Find(cfg, "axis");
    if (axis != nullptr &&
        !(axis->is_number_integer() && (axis->get<int64_t>() == -1 || axis->get<int64_t>() == 3))) {
      return LayerFail(
          l, "axis " + JsonText(*axis) + " is not supported (only the channels axis, -1 or 3)");
    }
  }
  if (l.inbound.size() < 2 || (!concat && l.inbound.size() != 2)) {
    return LayerFail(l, "reads " + std::to_string(l.inbound.size()) + " tensors; " +
                            (concat ? "a Concatenate reads two or more" : "an Add reads two"));
  }
  std::vector<std::string> names;
  int channels = 0;
  for (const std::string& name : l.inbound) {
    const Tensor& t = b.s.tensors.at(name);
    const bool size_differs = b.s.known && (t.h != in.h || t.w != in.w);
    if (size_differs || (!concat && t.c != in.c)) {
      return LayerFail(
          l, "reads " + Quote(l.inbound[0]) + " (" + std::to_string(in.h) + "x" +
                 std::to_string(in.w) + "x" + std::to_string(in.c) + ") and " + Quote(name) + " (" +
                 std::to_string(t.h) + "x" + std::to_string(t.w) + "x" + std::to_string(t.c) +
                 "); " +
                 (concat ? "their heights and widths must match" : "their shapes must match"));
    }
    channels += t.c;
    names.push_back(t.layer);
  }
  if (concat) {
    if (channels > model_limits::kMaxChannels) {
      return LayerFail(l, "concatenates " + std::to_string(channels) + " channels; at most " +
                              std::to_string(model_limits::kMaxChannels));
    }
    c = channels;
    AddLayer(b, ConcatSpec{l.name, std::move(names)});
  } else {
    AddLayer(b, AddSpec{l.name, std::move(names), Activation::kNone, 0.0f});
  }
  return Status::Ok();
}

// Why layer class `l.cls` has no builder: a nested model, or a class the importer does not know.
Status Importer::UnknownLayer(const ChainLayer& l) const {
  if (IsNestedModelClass(l.cls)) {
    return LayerFail(l, std::string("nested models are supported only as a multi_gpu_model "
                                    "wrapper (InputLayer/Lambda/Concatenate around one nested "
                                    "model); supported layers: ") +
                            kSupportedLayers);
  }
  return LayerFail(
      l, std::string("layer class is not supported (supported: ") + kSupportedLayers + ")");
}

// The crop rule of every Cropping2D (crop_rule.h), traced at the built size: the skip its only
// reader, a Concatenate, also reads at its size; a note for each that keeps its amounts.
void Importer::ChooseCropRules(BuildState& s) {
  for (const CropTrace& t : s.crops) {
    auto& crop = std::get<CropSpec>(s.spec->layers[t.layer]);
    if (!s.known) {
      NoteKeptCrop(crop,
                   "the model's input height/width are None, so the size it was built for "
                   "is unknown");
      continue;
    }
    TracedCrop traced{t.out_h, t.out_w, ""};
    const auto& crop_readers = s.readers[t.output];
    if (crop_readers.size() == 1 && crop_readers[0]->cls == "Concatenate") {
      for (const std::string& name : crop_readers[0]->inbound) {
        const Tensor& other = s.tensors.at(name);
        if (name != t.output && other.pad_layer == nullptr &&
            other.index < static_cast<int>(t.layer) && other.h == t.out_h && other.w == t.out_w) {
          traced.skip = other.layer;
          break;
        }
      }
    }
    const std::string why = ChooseCropRule(crop, traced, s.model.height, s.model.width);
    if (!why.empty()) NoteKeptCrop(crop, why);
  }
}

void Importer::NoteKeptCrop(const CropSpec& crop, const std::string& why) {
  const Pads& a = crop.amounts;
  notes_.push_back("Cropping2D " + Quote(crop.name) + " keeps its amounts (top " +
                   std::to_string(a.top) + ", bottom " + std::to_string(a.bottom) + ", left " +
                   std::to_string(a.left) + ", right " + std::to_string(a.right) +
                   ") at every input size: " + why);
}

Status Importer::Build(const ChainModel& model, ModelSpec* spec) {
  BuildState s{model, spec, model.height > 0 && model.width > 0, {}, {}, {}, 0};
  s.tensors[model.input_name] =
      Tensor{model.height, model.width, model.channels, model.input_name, -1, {}, nullptr};
  for (const ChainLayer& l : model.layers) {
    for (size_t k = 0; k < l.inbound.size(); ++k) {
      if (std::find(l.inbound.begin(), l.inbound.begin() + k, l.inbound[k]) ==
          l.inbound.begin() + k) {
        s.readers[l.inbound[k]].push_back(&l);
      }
    }
  }
  for (const ChainLayer& l : model.layers) {
    if (Status st = CheckInbound(s, l); !st.ok()) return st;
    const LayerBuilder build = BuilderOf(l.cls);
    if (build == nullptr) return UnknownLayer(l);
    const Tensor in = s.tensors.at(l.inbound[0]);  // a copy: adding a layer rehashes `tensors`
    LayerBuild b{s, l, in, in.h, in.w, in.c, in.pads, in.pad_layer};
    if (Status st = (this->*build)(b); !st.ok()) return st;
  }
  const Tensor& out = s.tensors.at(s.model.layers.back().name);
  if (out.pad_layer != nullptr) {
    return LayerFail(*out.pad_layer,
                     "ends the model; it must be followed by a Conv2D with "
                     "padding 'valid'");
  }
  if (s.convs == 0) return Fail("the model has no Conv2D layer between input and output");
  if (s.spec->layers.size() > static_cast<size_t>(model_limits::kMaxLayers)) {
    return Fail("the model gives " + std::to_string(s.spec->layers.size()) + " layers; at most " +
                std::to_string(model_limits::kMaxLayers) + " are supported");
  }
  if (out.index != static_cast<int>(s.spec->layers.size()) - 1) {
    return Fail("the model's output " + Quote(s.model.layers.back().name) +
                " is computed by layer " + Quote(out.layer) +
                ", which is not the last: the network's output must be its last layer");
  }
  ChooseCropRules(s);
  s.spec->input.channels = s.model.channels;
  // The default image order (four RGB images) only fits 12 channels; for any other count the file
  // does not say which images the channels hold, so the spec names none (as the loader accepts).
  if (s.spec->input.channels != 3 * static_cast<int>(s.spec->input.image_order.size())) {
    s.spec->input.image_order.clear();
  }
  s.spec->input.traced_height = s.model.height;
  s.spec->input.traced_width = s.model.width;
  SetOutputChannels(*s.spec, out.c);
  KeepInputNamesOfAGraph(*s.spec, s.model.input_name);
  return Status::Ok();
}

Status Importer::CheckAllWeightsUsed() {
  if (src_.nested) {
    if (src_.next != src_.nested_names.size()) {
      return Fail("group " + GroupLabel(src_.nested_group) + " lists " +
                  std::to_string(src_.nested_names.size()) +
                  " weights but the nested model's layers use " + std::to_string(src_.next));
    }
    return Status::Ok();
  }
  for (const std::string& name : layer_names_) {
    if (used_groups_.count(name) > 0) continue;
    const Result<bool> exists = PathExists(src_.root, name);
    if (!exists.ok()) return exists.status();
    if (!*exists) continue;
    H5Handle g(H5Gopen2(src_.root, name.c_str(), H5P_DEFAULT), H5Gclose);
    if (!g.valid()) continue;
    auto names = ReadKerasList(g.get(), "weight_names", "group " + GroupLabel(name));
    if (!names.ok()) return Fail(names.message());
    if (names->has_value() && !(*names)->empty()) {
      return Fail("weights group " + GroupLabel(name) + " holds " +
                  std::to_string((*names)->size()) +
                  " weights but no layer of that name lies between the model's input and "
                  "output (wrong architecture?)");
    }
  }
  return Status::Ok();
}

Result<KerasImportResult> Importer::Run() {
  SFRT_KERAS_RETURN_IF_ERROR(Open());
  if (backend_ == "theano") {
    return Fail(
        "saved with the Theano backend, whose stored kernels are flipped; load it in "
        "Keras with TensorFlow and save it again");
  }
  if (keras_version_.rfind("1.", 0) == 0) {
    return Fail("saved by Keras " + Printable(keras_version_) + "; only Keras 2 files are read");
  }
  SFRT_KERAS_RETURN_IF_ERROR(FindWeightsRoot());
  Result<json> arch = ReadArchitecture();
  if (!arch.ok()) return arch.status();
  const json top = std::move(arch).value();

  // A multi_gpu_model wrapper: one nested model among InputLayer/Lambda/Concatenate layers.
  json nested_model;
  const json* model_json = &top;
  const json* top_config = Find(top, "config");
  const json* top_layers = top_config ? Find(*top_config, "layers") : nullptr;
  const std::string top_class =
      top["class_name"].is_string() ? top["class_name"].get<std::string>() : std::string();
  std::string label = "model";
  if (const json* n = top_config ? Find(*top_config, "name") : nullptr; n && n->is_string()) {
    label = "model " + Quote(n->get<std::string>());
  }
  if ((top_class == "Model" || top_class == "Functional") && top_layers != nullptr &&
      top_layers->is_array()) {
    std::vector<ChainLayer> nested;
    bool wrapper_only = true;
    int lambdas = 0;
    for (const json& entry : *top_layers) {
      Result<ChainLayer> l = ReadLayerEntry(entry, path_ + ": " + label);
      if (!l.ok()) return l.status();
      if (IsNestedModelClass(l->cls)) {
        nested.push_back(*l);
      } else if (l->cls == "Lambda") {
        ++lambdas;
      } else if (l->cls != "InputLayer" && l->cls != "Concatenate") {
        wrapper_only = false;
      }
    }
    if (nested.size() == 1 && wrapper_only) {
      const ChainLayer& inner = nested[0];
      nested_model = json{{"class_name", inner.cls}, {"config", *inner.config}};
      model_json = &nested_model;
      label = "nested model " + Quote(inner.name);
      src_.nested = true;
      src_.nested_group = inner.name;
      const Result<bool> exists = PathExists(src_.root, inner.name);
      if (!exists.ok()) return exists.status();
      if (!*exists) {
        return LayerFail(inner, "weights group " + GroupLabel(inner.name) + " is missing");
      }
      H5Handle g(H5Gopen2(src_.root, inner.name.c_str(), H5P_DEFAULT), H5Gclose);
      if (!g.valid()) return LayerFail(inner, "cannot open its weights group" + Hdf5Error());
      auto names = ReadKerasList(g.get(), "weight_names", "group " + GroupLabel(inner.name));
      if (!names.ok()) return LayerFail(inner, names.message());
      if (!names->has_value()) {
        return LayerFail(
            inner, "weights group " + GroupLabel(inner.name) + " has no attribute 'weight_names'");
      }
      src_.nested_names = std::move(**names);
      notes_.push_back(
          (lambdas > 0 ? std::string("multi_gpu_model checkpoint: ") : std::string()) +
          "exported the nested model " + Quote(inner.name) + " (" + Printable(inner.cls) +
          ") with the weights of group " + GroupLabel(inner.name) + "; the outer " +
          std::to_string(top_layers->size() - 1) +
          " layers (input, Lambda batch slices, Concatenate merge) only split and merge the "
          "batch across devices");
    }
  }

  Result<ChainModel> chain = ParseModel(*model_json, label);
  if (!chain.ok()) return chain.status();
  KerasImportResult result;
  SFRT_KERAS_RETURN_IF_ERROR(Build(*chain, &result.spec));
  SFRT_KERAS_RETURN_IF_ERROR(CheckAllWeightsUsed());
  if (chain->height == 0) {
    notes_.push_back("the model's input height/width are None: no built size is recorded");
  }
  result.spec.producer.source_format = "keras-h5";
  result.spec.producer.source_file = std::filesystem::path(path_).filename().string();
  if (in_memory_) {
    Sha256 hash;
    hash.Update(image_.data(), image_.size());
    result.spec.producer.source_sha256 = hash.FinishHex();
  } else {
    Result<std::string> sha = Sha256OfFile(path_);
    if (!sha.ok()) return sha.status();
    result.spec.producer.source_sha256 = std::move(sha).value();
  }
  result.notes = std::move(notes_);
  return result;
}

}  // namespace

namespace {

// make() returns the Importer (constructed inside the try: construction may throw too).
template <typename MakeImporter>
Result<KerasImportResult> RunImporter(const std::string& label, const MakeImporter& make) {
  Result<KerasImportResult> result = Status::Error("unset");
  try {
    Importer importer = make();
    result = importer.Run();
  } catch (const std::exception& e) {  // nlohmann::json or allocation failures: never escape
    result = Status::Error(label + ": " + e.what());
  }
  if (result.ok()) return result;
  return Status::Error(Printable(result.message()));  // one line, whatever the file contained
}

}  // namespace

Result<KerasImportResult> ImportKerasH5(const std::string& path,
                                        const KerasImportOptions& options) {
  return RunImporter(path, [&] { return Importer(path, options); });
}

Result<KerasImportResult> ImportKerasH5FromMemory(std::string_view image, const std::string& label,
                                                  const KerasImportOptions& options) {
  return RunImporter(label, [&] { return Importer(image, label, options); });
}

}  // namespace sfrt::exporter
