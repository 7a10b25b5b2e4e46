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
#include "keras/importer.h"
#include "message_text.h"
#include "sfrt/model_limits.h"
#include "sfrt/sha256.h"

namespace sfrt::exporter::keras_import {

std::string DimsText(const std::vector<uint64_t>& dims) {
  std::string s = "(";
  for (size_t i = 0; i < dims.size(); ++i) {
    if (i > 0) s += ", ";
    s += std::to_string(dims[i]);
  }
  return s + (dims.size() == 1 ? ",)" : ")");
}

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

}  // namespace sfrt::exporter::keras_import

namespace sfrt::exporter {

using keras_import::Importer;

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
