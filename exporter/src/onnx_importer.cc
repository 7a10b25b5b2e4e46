// ONNX -> ModelSpec. Method, in order:
//  1. Parse the ModelProto; check the default-domain opset (11..17) and the single graph input
//     (static (1, C, H, W) float32).
//  2. Mark the nodes the graph output depends on (anything else is dead code and ignored).
//  3. Walk the live nodes in file order (ONNX requires topological order). Every tensor is either
//     a constant (initialiser, Constant node, or the result of evaluating a supported op whose
//     inputs are all constants; Shape/Size of any tensor with a static shape is a constant) or a
//     runtime tensor with a static NCHW shape. Runtime tensors may only flow through Conv (any
//     group and dilation), ConvTranspose, MaxPool, AveragePool, Pad, BatchNormalization
//     (inference), Relu, LeakyRelu, Elu, Sigmoid, Tanh, Clip, Add/Sub/Mul/Div by a per-channel
//     constant, Resize, Upsample, Slice, Identity, and Concat (channels) and Add, which read
//     several of them. A Resize that is nearest upsampling by integer factors equal to
//     in[floor(y / f)] becomes an Upsample; any other (linear, cubic, other scales or roundings)
//     a Resize layer (schema 1.7) with its scales as exact fractions.
//  4. The layers are the ops the output depends on through runtime tensors, in file order: a
//     graph (schema 1.5) whose layers name the layers they read, or, when each reads the one
//     before it, a chain that names none. Pads fold into the Conv that reads them, a
//     BatchNormalization folds into the Conv before it (its weights and bias scaled per output
//     channel), as does an Add/Sub/Mul/Div by a constant; ReLU and LeakyReLU fuse into the Conv,
//     ConvTranspose or Add before them, and any activation into a ChannelAffine, where that
//     layer's output has no other reader (otherwise each becomes a ChannelAffine); consecutive
//     Slices merge into one crop. Padding and crop rules are decided from the amounts at the
//     traced size (a crop whose only reader is a Concat with a tensor of the crop's size becomes
//     a crop to that tensor's size: a U-Net's skip).
#include "sfrt/exporter/onnx_importer.h"

#include "batch_norm_fold.h"
#include "crop_rule.h"
#include "message_text.h"
#include "onnx/const_tensors.h"
#include "onnx/folders.h"
#include "onnx/importer.h"

// onnx_pb.h defines ONNX_API and then includes onnx-ml.pb.h (ONNX_ML=1); including
// onnx-ml.pb.h directly does not compile with Debian's headers.
#include <onnx/onnx_pb.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <numeric>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <unordered_map>
#include <utility>
#include <vector>

#include "sfrt/model_limits.h"
#include "sfrt/sha256.h"
#include "sfrt/shapes.h"

namespace sfrt::exporter::onnx_import {

std::string PadsText(const Pads& p) {
  return "(top " + std::to_string(p.top) + ", left " + std::to_string(p.left) + ", bottom " +
         std::to_string(p.bottom) + ", right " + std::to_string(p.right) + ")";
}

std::string ShapeText(const Shape4& s) {
  return "(" + std::to_string(s[0]) + ", " + std::to_string(s[1]) + ", " + std::to_string(s[2]) +
         ", " + std::to_string(s[3]) + ")";
}

bool NearestIsFloorOfQuotient(const std::string& ctm, const std::string& nearest_mode, int64_t f) {
  const bool round_mode =
      nearest_mode == "round_prefer_floor" || nearest_mode == "round_prefer_ceil";
  const bool known_mode = round_mode || nearest_mode == "floor" || nearest_mode == "ceil";
  if (ctm == "align_corners") return known_mode && (f == 1 || (f == 2 && round_mode));
  constexpr int64_t k = 3;  // any block index with x > 0
  const int64_t den = 2 * f;
  for (int64_t r = 0; r < f; ++r) {
    const int64_t y = f * k + r;
    int64_t num = 0;
    if (ctm == "asymmetric") {
      num = 2 * y;
    } else if (ctm == "half_pixel" || ctm == "pytorch_half_pixel") {
      num = 2 * y + 1 - f;
    } else if (ctm == "tf_half_pixel_for_nn") {
      num = 2 * y + 1;
    } else {
      return false;
    }
    const int64_t fl = FloorDiv(num, den);
    const int64_t rem = num - fl * den;  // in [0, den)
    int64_t rounded = 0;
    if (nearest_mode == "floor") {
      rounded = fl;
    } else if (nearest_mode == "ceil") {
      rounded = rem == 0 ? fl : fl + 1;
    } else if (nearest_mode == "round_prefer_floor") {
      rounded = 2 * rem <= den ? fl : fl + 1;
    } else if (nearest_mode == "round_prefer_ceil") {
      rounded = 2 * rem < den ? fl : fl + 1;
    } else {
      return false;
    }
    if (rounded != k) return false;
  }
  return true;
}

std::pair<int, int> SameUpperAxis(int64_t in, int64_t stride, int64_t kernel) {
  const int64_t out = (in + stride - 1) / stride;
  const int64_t total = std::max<int64_t>((out - 1) * stride + kernel - in, 0);
  return {static_cast<int>(total / 2), static_cast<int>(total - total / 2)};
}

Pads SameUpperPads(int64_t in_h, int64_t in_w, int kh, int kw, int sh, int sw) {
  const auto [top, bottom] = SameUpperAxis(in_h, sh, kh);
  const auto [left, right] = SameUpperAxis(in_w, sw, kw);
  return Pads{top, left, bottom, right};
}

Pads SamePads(PaddingRule rule, int64_t in_h, int64_t in_w, int kh, int kw, int sh, int sw) {
  const Pads upper = SameUpperPads(in_h, in_w, kh, kw, sh, sw);
  if (rule != PaddingRule::kSameLower) return upper;
  return Pads{upper.bottom, upper.right, upper.top, upper.left};
}

const onnx::AttributeProto* Importer::FindAttr(int idx, std::string_view name) const {
  return FindAttribute(graph().node(idx), name);
}

Result<int64_t> Importer::IntAttr(int idx, std::string_view name, int64_t fallback) const {
  Result<int64_t> value = IntAttribute(graph().node(idx), name, fallback);
  if (!value.ok()) return NodeError(idx, value.message());
  return value;
}

Result<std::vector<int64_t>> Importer::DilationsAttr(int idx, std::string_view name) const {
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> dilations, IntsAttr(idx, name));
  if (dilations.empty()) dilations = {1, 1};
  if (dilations.size() != 2 || dilations[0] < 1 || dilations[1] < 1 ||
      dilations[0] > model_limits::kMaxDilation || dilations[1] > model_limits::kMaxDilation) {
    return NodeError(idx, "attribute '" + std::string(name) + "' = " + JoinInts(dilations) +
                              " is not supported (two values, each 1.." +
                              std::to_string(model_limits::kMaxDilation) + ")");
  }
  return dilations;
}

Result<std::vector<int64_t>> Importer::IntsAttr(int idx, std::string_view name) const {
  Result<std::vector<int64_t>> values = IntsAttribute(graph().node(idx), name);
  if (!values.ok()) return NodeError(idx, values.message());
  return values;
}

Result<float> Importer::FloatAttr(int idx, std::string_view name, float fallback) const {
  const auto* a = FindAttr(idx, name);
  if (a == nullptr) return fallback;
  if (a->type() != onnx::AttributeProto::FLOAT) {
    return NodeError(idx, "attribute '" + std::string(name) + "' is not a float");
  }
  return a->f();
}

Result<std::string> Importer::StringAttr(int idx, std::string_view name,
                                         const std::string& fallback) const {
  const auto* a = FindAttr(idx, name);
  if (a == nullptr) return fallback;
  if (a->type() != onnx::AttributeProto::STRING) {
    return NodeError(idx, "attribute '" + std::string(name) + "' is not a string");
  }
  return a->s();
}

Result<Const> Importer::GetConst(int idx, int slot) {
  const std::string& name = graph().node(idx).input(slot);
  if (auto it = consts_.find(name); it != consts_.end()) {
    const Const& c = it->second;
    if (Status s = budget_.Take(
            c.size(), kConstValueBytes,
            "input " + std::to_string(slot) + " " + Quote(name) + " of shape " + JoinInts(c.dims));
        !s.ok()) {
      return NodeError(idx, s.message());
    }
    return c;
  }
  if (auto it = initializers_.find(name); it != initializers_.end()) {
    auto decoded = DecodeTensor(*it->second, "initializer " + Quote(name), budget_);
    if (!decoded.ok()) return FileError(decoded.message());
    return decoded;
  }
  return NodeError(idx, "input " + std::to_string(slot) + " " + Quote(name) +
                            " must be a constant (an initializer, a Constant node or a constant "
                            "subgraph), but it depends on the network input");
}

Result<std::optional<Const>> Importer::GetOptionalConst(int idx, int slot) {
  const onnx::NodeProto& n = graph().node(idx);
  if (slot >= n.input_size() || n.input(slot).empty()) return std::optional<Const>();
  SFRT_ONNX_ASSIGN_OR_RETURN(Const c, GetConst(idx, slot));
  return std::optional<Const>(std::move(c));
}

Result<std::vector<float>> Importer::GetFloats(int idx, int slot, Dims* dims) {
  const std::string& name = graph().node(idx).input(slot);
  const std::string what = "input " + std::to_string(slot) + " " + Quote(name);
  // Fast path for float32 initialisers (the weights): no detour through doubles.
  if (auto it = initializers_.find(name); it != initializers_.end() && consts_.count(name) == 0) {
    const TensorProto& t = *it->second;
    if (t.data_type() == TensorProto::FLOAT && t.data_location() != TensorProto::EXTERNAL) {
      dims->assign(t.dims().begin(), t.dims().end());
      auto count = NumElements(*dims);
      if (!count.ok()) return NodeError(idx, what + ": " + count.message());
      const auto n = static_cast<size_t>(*count);
      // The declared shape against the bytes the file holds, before the vector is sized from it
      // (a 257-byte file declared [1, 536870890]: 2 GB).
      if (t.has_raw_data() && t.raw_data().size() != 4 * n) {
        return NodeError(idx, what + " holds " + std::to_string(t.raw_data().size()) +
                                  " bytes, its shape " + JoinInts(*dims) + " needs " +
                                  std::to_string(4 * n));
      }
      if (!t.has_raw_data() && static_cast<size_t>(t.float_data_size()) != n) {
        return NodeError(idx, what + " holds " + std::to_string(t.float_data_size()) +
                                  " floats, its shape " + JoinInts(*dims) + " needs " +
                                  std::to_string(n));
      }
      if (Status s = budget_.Take(n, sizeof(float), what + " of shape " + JoinInts(*dims));
          !s.ok()) {
        return NodeError(idx, s.message());
      }
      std::vector<float> values(n);
      if (t.has_raw_data()) {
        for (size_t i = 0; i < n; ++i)
          values[i] = LoadLittleEndian<float>(t.raw_data().data() + 4 * i);
      } else {
        std::copy(t.float_data().begin(), t.float_data().end(), values.begin());
      }
      return values;
    }
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(const Const c, GetConst(idx, slot));
  if (c.type != TensorProto::FLOAT) {
    return NodeError(idx, what + " has element type " + TypeName(c.type) + ", expected FLOAT");
  }
  *dims = c.dims;
  if (Status s = budget_.Take(c.size(), sizeof(float), what + " of shape " + JoinInts(c.dims));
      !s.ok()) {
    return NodeError(idx, s.message());
  }
  return std::vector<float>(c.reals.begin(), c.reals.end());
}

Status Importer::Load() {
  if (!model_.ParseFromArray(bytes_.data(), static_cast<int>(bytes_.size()))) {
    return FileError("not a valid ONNX file: the protobuf ModelProto does not parse (" +
                     std::to_string(bytes_.size()) + " bytes)");
  }
  if (model_.ir_version() <= 0 || !model_.has_graph()) {
    return FileError("not a valid ONNX file: no ir_version or no graph (" +
                     std::to_string(bytes_.size()) + " bytes)");
  }
  return Status::Ok();
}

// Reads the whole file at `path`; errors name it.
Result<std::string> ReadOnnxFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return Status::Error(path + ": cannot open ONNX file: no such file");
  }
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Status::Error(path + ": cannot open ONNX file: not a regular file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return Status::Error(path + ": cannot open ONNX file: " + std::strerror(errno));
  }
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) {
    return Status::Error(path + ": cannot read ONNX file: " + std::strerror(errno));
  }
  return bytes;
}

Status Importer::ReadOpset() {
  bool found = false;
  for (const auto& op : model_.opset_import()) {
    if (op.domain().empty() || op.domain() == "ai.onnx") {
      opset_ = op.version();
      found = true;
    }
  }
  if (!found) return FileError("opset_import has no entry for the default ONNX domain");
  if (opset_ < kMinOpset || opset_ > kMaxOpset) {
    return FileError("opset " + std::to_string(opset_) +
                     " is not supported (supported: " + std::to_string(kMinOpset) + " to " +
                     std::to_string(kMaxOpset) + "); re-export with opset_version in that range");
  }
  return Status::Ok();
}

Status Importer::ReadInitializers() {
  for (const auto& t : graph().initializer()) initializers_[t.name()] = &t;
  if (graph().sparse_initializer_size() > 0) {
    return FileError("sparse initializers are not supported");
  }
  return Status::Ok();
}

Status Importer::ReadInput() {
  const onnx::ValueInfoProto* input = nullptr;
  for (const auto& vi : graph().input()) {
    if (initializers_.count(vi.name()) > 0) continue;
    if (input != nullptr) {
      return FileError("graph has more than one non-initializer input (" + Quote(input->name()) +
                       " and " + Quote(vi.name()) + "); the network takes one (1, C, H, W) tensor");
    }
    input = &vi;
  }
  if (input == nullptr) return FileError("graph has no input (every input is an initializer)");
  input_name_ = input->name();
  const std::string what = "graph input " + Quote(input_name_);
  if (!input->type().has_tensor_type()) return FileError(what + " is not a tensor");
  const auto& tt = input->type().tensor_type();
  if (IsSmallInteger(tt.elem_type())) {
    integer_io_type_ = tt.elem_type();  // Assemble checks that float32 computes it exactly
  } else if (tt.elem_type() != TensorProto::FLOAT) {
    return FileError(what + " has element type " + TypeName(tt.elem_type()) +
                     ", expected FLOAT (or INT8, UINT8, INT16, UINT16 into selection operators)");
  }
  if (!tt.has_shape() || tt.shape().dim_size() != 4) {
    return FileError(what + " must have a static 4-D shape (1, C, H, W)" +
                     (tt.has_shape() ? ", it has rank " + std::to_string(tt.shape().dim_size())
                                     : std::string(", it has no shape")));
  }
  static constexpr const char* kAxisNames[] = {"N", "C", "H", "W"};
  for (int k = 0; k < 4; ++k) {
    const auto& d = tt.shape().dim(k);
    if (!d.has_dim_value() || d.dim_value() <= 0) {
      return FileError(what + " dimension " + std::to_string(k) + " (" + kAxisNames[k] + ") is " +
                       (d.has_dim_param() ? "symbolic " + Quote(d.dim_param()) : "unknown") +
                       "; export with a static shape (1, C, H, W)");
    }
    if (d.dim_value() > std::numeric_limits<int32_t>::max()) {
      return FileError(what + " dimension " + std::to_string(k) + " is too large");
    }
    input_shape_[k] = d.dim_value();
  }
  if (input_shape_[0] != 1) {
    return FileError(what + " has batch size " + std::to_string(input_shape_[0]) +
                     ", expected 1 (shape (1, C, H, W))");
  }
  if (input_shape_[1] > model_limits::kMaxChannels) {
    return FileError(what + " has " + std::to_string(input_shape_[1]) + " channels; at most " +
                     std::to_string(model_limits::kMaxChannels) + " are supported");
  }
  runtime_[input_name_] = input_shape_;
  return Status::Ok();
}

// The graph output the model computes: OnnxImportOptions::output, or the only one.
Status Importer::ChooseOutput() {
  std::string names;
  for (int k = 0; k < graph().output_size(); ++k) {
    if (!options_.output.empty() && graph().output(k).name() == options_.output) {
      output_index_ = k;
      return Status::Ok();
    }
    names += (k == 0 ? "" : ", ") + Quote(graph().output(k).name());
  }
  if (!options_.output.empty()) {
    return FileError("graph has no output " + Quote(options_.output) + "; its outputs: " + names);
  }
  if (graph().output_size() == 1) return Status::Ok();
  if (graph().output_size() == 0) return FileError("graph has no output");
  return FileError("graph has " + std::to_string(graph().output_size()) + " outputs (" + names +
                   "); an sfrt model computes one: choose it (sfrt export --onnx-output NAME)");
}

std::vector<bool> Importer::LiveNodes() const {
  std::unordered_map<std::string, int> producer;
  for (int i = 0; i < graph().node_size(); ++i) {
    for (const auto& out : graph().node(i).output()) {
      if (!out.empty()) producer[out] = i;
    }
  }
  std::vector<bool> live(graph().node_size(), false);
  std::vector<std::string> stack{graph().output(output_index_).name()};
  while (!stack.empty()) {
    const std::string name = std::move(stack.back());
    stack.pop_back();
    auto it = producer.find(name);
    if (it == producer.end() || live[it->second]) continue;
    live[it->second] = true;
    for (const auto& in : graph().node(it->second).input()) {
      if (!in.empty()) stack.push_back(in);
    }
  }
  return live;
}

std::vector<int> Importer::UnknownOpNodes(const std::vector<bool>& live) const {
  std::vector<int> unknown;
  for (int i = 0; i < graph().node_size(); ++i) {
    if (!live[i]) continue;
    const onnx::NodeProto& n = graph().node(i);
    const bool default_domain = n.domain().empty() || n.domain() == "ai.onnx";
    if (!default_domain ||
        (FindRuntimeOp(n.op_type()) == nullptr && FindFolder(n.op_type()) == nullptr)) {
      unknown.push_back(i);
    }
  }
  return unknown;
}

Status Importer::UnsupportedNodesError(const std::vector<int>& nodes) const {
  const onnx::NodeProto& first = graph().node(nodes[0]);
  if (nodes.size() == 1) {
    const bool default_domain = first.domain().empty() || first.domain() == "ai.onnx";
    return Unsupported(nodes[0], default_domain ? std::string()
                                                : "; domain " + Quote(first.domain()) +
                                                      " is not the default ONNX domain");
  }
  std::string list;
  const size_t listed = std::min(nodes.size(), kMaxListedNodes);
  for (size_t k = 0; k < listed; ++k) list += (k > 0 ? ", " : "") + NodeLabel(nodes[k]);
  if (nodes.size() > listed) list += " and " + std::to_string(nodes.size() - listed) + " more";
  return FileError(std::to_string(nodes.size()) + " nodes are unsupported: " + list +
                   "; supported ops (default ONNX domain): " + SupportedOpsText());
}

Status Importer::ProcessConstant(int idx) {
  const onnx::NodeProto& n = graph().node(idx);
  if (n.attribute_size() != 1) {
    return NodeError(
        idx, "expected exactly one value attribute, found " + std::to_string(n.attribute_size()));
  }
  const onnx::AttributeProto& a = n.attribute(0);
  Const c;
  if (a.name() == "value" && a.type() == onnx::AttributeProto::TENSOR) {
    auto decoded = DecodeTensor(a.t(), "attribute 'value'", budget_);
    if (!decoded.ok()) return NodeError(idx, decoded.message());
    c = std::move(decoded).value();
  } else if (a.name() == "value_float" && a.type() == onnx::AttributeProto::FLOAT) {
    c.type = TensorProto::FLOAT;
    c.reals = {a.f()};
  } else if (a.name() == "value_floats" && a.type() == onnx::AttributeProto::FLOATS) {
    if (Status s = budget_.Take(
            static_cast<size_t>(a.floats_size()), kConstValueBytes,
            "attribute 'value_floats' of " + std::to_string(a.floats_size()) + " values");
        !s.ok()) {
      return NodeError(idx, s.message());
    }
    c.type = TensorProto::FLOAT;
    c.dims = {a.floats_size()};
    c.reals.assign(a.floats().begin(), a.floats().end());
  } else if (a.name() == "value_int" && a.type() == onnx::AttributeProto::INT) {
    c.type = TensorProto::INT64;
    c.ints = {a.i()};
  } else if (a.name() == "value_ints" && a.type() == onnx::AttributeProto::INTS) {
    if (Status s =
            budget_.Take(static_cast<size_t>(a.ints_size()), kConstValueBytes,
                         "attribute 'value_ints' of " + std::to_string(a.ints_size()) + " values");
        !s.ok()) {
      return NodeError(idx, s.message());
    }
    c.type = TensorProto::INT64;
    c.dims = {a.ints_size()};
    c.ints.assign(a.ints().begin(), a.ints().end());
  } else {
    return NodeError(idx, "attribute " + Quote(a.name()) +
                              " is not supported (value, value_float(s), value_int(s))");
  }
  if (n.output_size() != 1) return NodeError(idx, "expected one output");
  consts_[n.output(0)] = std::move(c);
  return Status::Ok();
}

// clang-format off
std::span<const Importer::RuntimeOp> Importer::RuntimeOps() {
  using K = GraphOp::Kind;
  static constexpr std::array kOps = {
      RuntimeOp{"Conv", K::kConv, &Importer::ProcessConv},
      RuntimeOp{"Pad", K::kPad, &Importer::ProcessPad},
      RuntimeOp{"BatchNormalization", K::kBatchNorm, &Importer::ProcessBatchNorm},
      RuntimeOp{"LeakyRelu", K::kActivation, &Importer::ProcessActivation, Activation::kLeakyRelu},
      RuntimeOp{"Relu", K::kActivation, &Importer::ProcessActivation, Activation::kRelu},
      RuntimeOp{"Elu", K::kActivation, &Importer::ProcessActivation, Activation::kElu},
      RuntimeOp{"Sigmoid", K::kActivation, &Importer::ProcessActivation, Activation::kSigmoid},
      RuntimeOp{"Tanh", K::kActivation, &Importer::ProcessActivation, Activation::kTanh},
      RuntimeOp{"Clip", K::kActivation, &Importer::ProcessClip},
      RuntimeOp{"Resize", K::kUpsample, &Importer::ProcessResize},
      RuntimeOp{"Upsample", K::kUpsample, &Importer::ProcessResize},
      RuntimeOp{"Slice", K::kSlice, &Importer::ProcessSlice},
      RuntimeOp{"Identity", K::kIdentity, nullptr},
      RuntimeOp{"Concat", K::kConcat, nullptr, Activation::kNone, Merge::kAlways},
      RuntimeOp{"Add", K::kAffine, &Importer::ProcessElementwise, Activation::kNone,
                Merge::kWithSeveralRuntimeInputs},
      RuntimeOp{"Sub", K::kAffine, &Importer::ProcessElementwise},
      RuntimeOp{"Mul", K::kAffine, &Importer::ProcessElementwise},
      RuntimeOp{"Div", K::kAffine, &Importer::ProcessElementwise},
      RuntimeOp{"ConvTranspose", K::kConvTranspose, &Importer::ProcessConvTranspose},
      RuntimeOp{"MaxPool", K::kPool, &Importer::ProcessPool},
      RuntimeOp{"AveragePool", K::kPool, &Importer::ProcessPool},
  };
  return kOps;
}
// clang-format on

const Importer::RuntimeOp* Importer::FindRuntimeOp(std::string_view type) {
  for (const RuntimeOp& op : RuntimeOps()) {
    if (op.type == type) return &op;
  }
  return nullptr;
}

std::string Importer::SupportedOpsText() {
  std::string text;
  for (const RuntimeOp& op : RuntimeOps()) {
    if (!text.empty()) text += ", ";
    text += op.type;
  }
  text += " (constant subgraphs may also use";
  bool first = true;
  for (const ConstantFolder& folder : ConstantFolders()) {
    if (FindRuntimeOp(folder.op) != nullptr) continue;  // already listed
    text += first ? " " : ", ";
    text += folder.op;
    first = false;
  }
  text += ")";
  return text;
}

// Relu takes no attribute; LeakyRelu and Elu their alpha.
Status Importer::ProcessActivation(int idx, GraphOp& op) {
  if (op.activation == Activation::kLeakyRelu) {
    SFRT_ONNX_ASSIGN_OR_RETURN(op.slope, FloatAttr(idx, "alpha", 0.01f));
  } else if (op.activation == Activation::kElu) {
    SFRT_ONNX_ASSIGN_OR_RETURN(op.elu_alpha, FloatAttr(idx, "alpha", 1.0f));
  }
  return Status::Ok();
}

Status Importer::FoldNode(int idx) {
  const onnx::NodeProto& n = graph().node(idx);
  if (n.output_size() < 1 || n.output(0).empty()) return NodeError(idx, "has no output");
  const ConstantFolder* folder = FindFolder(n.op_type());
  if (folder == nullptr || folder->fold == nullptr) return Unsupported(idx, "");
  FoldCall call{n, opset_, budget_, {}, {}};
  if (folder->reads_shape_only) {
    // Shape and Size only need the input's static shape, which runtime tensors have too.
    if (n.input_size() != 1) return NodeError(idx, "expected one input");
    if (auto it = runtime_.find(n.input(0)); it != runtime_.end()) {
      call.shape.assign(it->second.begin(), it->second.end());
    } else {
      SFRT_ONNX_ASSIGN_OR_RETURN(const Const in, GetConst(idx, 0));
      call.shape = in.dims;
    }
  } else {
    call.in.resize(static_cast<size_t>(n.input_size()));
    for (int k = 0; k < n.input_size(); ++k) {
      SFRT_ONNX_ASSIGN_OR_RETURN(call.in[static_cast<size_t>(k)], GetOptionalConst(idx, k));
    }
  }
  Result<Const> result = folder->fold(call);
  if (!result.ok()) {
    // Folders' errors are bare details; those of GetConst already carry the file name.
    if (result.message().rfind(path_ + ": ", 0) == 0) return result.status();
    return NodeError(idx, result.message());
  }
  consts_[n.output(0)] = std::move(result).value();
  return Status::Ok();
}

Status Importer::ProcessRuntimeNode(int idx, int slot) {
  const onnx::NodeProto& n = graph().node(idx);
  const std::string& type = n.op_type();
  if (n.output_size() < 1 || n.output(0).empty()) return NodeError(idx, "has no output");
  // Only input `slot` carries activations; every other input must be a constant.
  for (int k = 0; k < n.input_size(); ++k) {
    if (k != slot && runtime_.count(n.input(k)) > 0) {
      return NodeError(idx, "input " + std::to_string(k) + " " + Quote(n.input(k)) +
                                " depends on the network input; only input " +
                                std::to_string(slot) + " may");
    }
  }
  const Shape4& in_shape = runtime_.at(n.input(slot));
  GraphOp op;
  op.node_index = idx;
  op.inputs = {n.input(slot)};
  op.output = n.output(0);
  op.in_shape = in_shape;
  op.out_shape = in_shape;
  const RuntimeOp* rule = FindRuntimeOp(type);
  if (rule == nullptr) return Unsupported(idx, "");  // ProcessNode only routes runtime ops here
  op.kind = rule->kind;
  op.activation = rule->activation;
  if (rule->process != nullptr) SFRT_ONNX_RETURN_IF_ERROR((this->*rule->process)(idx, op));
  for (int64_t d : op.out_shape) {
    if (d > std::numeric_limits<int32_t>::max()) {
      return NodeError(idx, "output shape " + ShapeText(op.out_shape) + " is too large");
    }
  }
  if (op.kind == GraphOp::Kind::kPool && op.pool.kind == PoolKind::kMax && n.output_size() > 1 &&
      !n.output(1).empty()) {
    // The Indices output: where each max is, as ONNX numbers the input's elements (batch 1):
    // c * H * W + y * W + x, or c * H * W + x * H + y with storage_order 1.
    GraphOp indices = op;
    indices.output = n.output(1);
    indices.pool.kind = PoolKind::kArgMax;
    op.pool.indices_column_major = false;  // the values' pool has no indices
    runtime_[indices.output] = indices.out_shape;
    producer_op_[indices.output] = ops_.size() + 1;
    runtime_[op.output] = op.out_shape;
    producer_op_[op.output] = ops_.size();
    ops_.push_back(std::move(op));
    ops_.push_back(std::move(indices));
    return Status::Ok();
  }
  runtime_[op.output] = op.out_shape;
  producer_op_[op.output] = ops_.size();
  ops_.push_back(std::move(op));
  return Status::Ok();
}

Status Importer::ProcessNode(int idx) {
  const onnx::NodeProto& n = graph().node(idx);
  if (!n.domain().empty() && n.domain() != "ai.onnx") {
    return Unsupported(idx, "; domain " + Quote(n.domain()) + " is not the default ONNX domain");
  }
  if (n.op_type() == "Constant") return ProcessConstant(idx);
  // Every input must be known by now (ONNX graphs are topologically sorted).
  int runtime_slot = -1;
  for (int k = 0; k < n.input_size(); ++k) {
    const std::string& name = n.input(k);
    if (name.empty()) continue;
    if (runtime_.count(name) > 0) {
      if (runtime_slot < 0) runtime_slot = k;
      continue;
    }
    if (!IsConst(name)) {
      return NodeError(idx, "input " + Quote(name) +
                                " is not produced by an earlier node, an initializer or the "
                                "graph input");
    }
  }
  const std::string& type = n.op_type();
  const ConstantFolder* folder = FindFolder(type);
  const RuntimeOp* rule = FindRuntimeOp(type);
  if (runtime_slot < 0 || (folder != nullptr && folder->reads_shape_only)) {
    if (folder != nullptr) return FoldNode(idx);
    if (rule != nullptr) {
      return Unsupported(idx, "; " + Printable(type) +
                                  " on constant data only (it does not depend on the network "
                                  "input) cannot be evaluated at import");
    }
    return Unsupported(idx, "");
  }
  if (rule == nullptr) {
    return Unsupported(idx, folder != nullptr
                                ? "; " + Printable(type) +
                                      " is only evaluated when all its inputs are constants, and "
                                      "input " +
                                      Quote(n.input(runtime_slot)) + " depends on the network input"
                                : "");
  }
  int runtime_inputs = 0;
  for (int k = 0; k < n.input_size(); ++k) runtime_inputs += runtime_.count(n.input(k)) > 0;
  if (rule->merge == Merge::kAlways ||
      (rule->merge == Merge::kWithSeveralRuntimeInputs && runtime_inputs > 1)) {
    return ProcessMergeNode(idx);
  }
  if (rule->kind == GraphOp::Kind::kAffine) {
    if (runtime_inputs > 1 || n.input_size() != 2) {
      return Unsupported(idx, "; " + Printable(type) +
                                  " runs on one tensor that depends on the network input and a "
                                  "per-channel constant (Add also on two such tensors)");
    }
    return ProcessRuntimeNode(idx, runtime_slot);
  }
  if (runtime_slot != 0) {
    return NodeError(idx, "input " + std::to_string(runtime_slot) + " " +
                              Quote(n.input(runtime_slot)) +
                              " depends on the network input; only input 0 may");
  }
  return ProcessRuntimeNode(idx, 0);
}

// A graph of 8- or 16-bit integers runs in float32, which holds every such value exactly, when
// each output value is one of the input values or an integer constant: MaxPool, ReLU, Clip,
// Concat, Slice, Pad, nearest resizing. Arithmetic (convolutions, averages, Add, which wraps
// around in ONNX's integer types) is refused, as is an output of another type.
Status Importer::CheckIntegerGraph(const std::vector<bool>& needed) const {
  if (integer_io_type_ == 0) return Status::Ok();
  const std::string type = TypeName(integer_io_type_);
  const auto& out = graph().output(output_index_);
  const int out_type = out.type().has_tensor_type() ? out.type().tensor_type().elem_type() : 0;
  if (out_type != integer_io_type_) {
    return FileError("graph output " + Quote(out.name()) + " has element type " +
                     TypeName(out_type) + ", but the input " + Quote(input_name_) + " is " + type +
                     "; an integer graph must keep its type");
  }
  for (size_t i = 0; i < ops_.size(); ++i) {
    if (!needed[i]) continue;
    const GraphOp& op = ops_[i];
    bool exact = false;
    switch (op.kind) {
      case GraphOp::Kind::kPool:
        exact = op.pool.kind == PoolKind::kMax;
        break;
      case GraphOp::Kind::kActivation:  // ProcessClip took the bounds from integer constants
        exact = op.activation == Activation::kRelu || op.activation == Activation::kClip;
        break;
      case GraphOp::Kind::kResize:
        exact = op.resize.mode == ResizeMode::kNearest &&
                op.resize.coordinates != ResizeCoordinates::kTfCropAndResize;
        break;
      case GraphOp::Kind::kUpsample:
      case GraphOp::Kind::kSlice:
      case GraphOp::Kind::kIdentity:
      case GraphOp::Kind::kConcat:
      case GraphOp::Kind::kPad:
        exact = true;
        break;
      default:
        break;
    }
    if (!exact) {
      return NodeError(op.node_index,
                       "computes on the " + type + " input " + Quote(input_name_) +
                           ", which sfrt runs in float32; that is exact only for MaxPool, Relu, "
                           "Clip to integer bounds, Concat, Slice, Pad and nearest Resize");
    }
  }
  return Status::Ok();
}

Result<ModelSpec> Importer::Run() {
  SFRT_ONNX_RETURN_IF_ERROR(Load());
  SFRT_ONNX_RETURN_IF_ERROR(ReadOpset());
  SFRT_ONNX_RETURN_IF_ERROR(ReadInitializers());
  SFRT_ONNX_RETURN_IF_ERROR(ReadInput());
  SFRT_ONNX_RETURN_IF_ERROR(ChooseOutput());
  const std::vector<bool> live = LiveNodes();
  if (const std::vector<int> unknown = UnknownOpNodes(live); !unknown.empty()) {
    return UnsupportedNodesError(unknown);
  }
  for (int i = 0; i < graph().node_size(); ++i) {
    if (live[i]) SFRT_ONNX_RETURN_IF_ERROR(ProcessNode(i));
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(ModelSpec spec, Assemble());
  spec.producer.source_format = "onnx";
  spec.producer.source_file = std::filesystem::path(path_).filename().string();
  Sha256 sha;
  sha.Update(bytes_.data(), bytes_.size());
  spec.producer.source_sha256 = sha.FinishHex();
  return spec;
}

}  // namespace sfrt::exporter::onnx_import

namespace sfrt::exporter {

using onnx_import::Importer;
using onnx_import::ReadOnnxFile;

Result<ModelSpec> ImportOnnxFromMemory(std::string_view bytes, const std::string& label,
                                       const OnnxImportOptions& options) {
  if (bytes.size() > static_cast<size_t>(std::numeric_limits<int>::max())) {
    return Status::Error(Printable(label) + ": ONNX file is " + std::to_string(bytes.size()) +
                         " bytes, above protobuf's 2 GiB limit");
  }
  Importer importer(bytes, label, options);
  Result<ModelSpec> result = importer.Run();
  if (result.ok()) return result;
  return Status::Error(Printable(result.message()));  // one line, whatever the file contained
}

Result<ModelSpec> ImportOnnx(const std::string& path, const OnnxImportOptions& options) {
  Result<std::string> bytes = ReadOnnxFile(path);
  if (!bytes.ok()) return Status::Error(Printable(bytes.message()));
  return ImportOnnxFromMemory(*bytes, path, options);
}

}  // namespace sfrt::exporter
