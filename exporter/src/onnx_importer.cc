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

#include "sfrt/exporter/sha256.h"
#include "sfrt/model_limits.h"
#include "sfrt/shapes.h"

namespace sfrt::exporter {
namespace {

using namespace onnx_import;
using Shape4 = std::array<int64_t, 4>;  // N, C, H, W

constexpr int64_t kMinOpset = 11;
constexpr int64_t kMaxOpset = 17;
// Unsupported nodes named in one message; the rest are counted (a screenful at most).
constexpr size_t kMaxListedNodes = 20;

std::string PadsText(const Pads& p) {
  return "(top " + std::to_string(p.top) + ", left " + std::to_string(p.left) + ", bottom " +
         std::to_string(p.bottom) + ", right " + std::to_string(p.right) + ")";
}

std::string ShapeText(const Shape4& s) {
  return "(" + std::to_string(s[0]) + ", " + std::to_string(s[1]) + ", " + std::to_string(s[2]) +
         ", " + std::to_string(s[3]) + ")";
}

// ------------------------------------------------------------------------- resize semantics

// Whether ONNX nearest Resize with these modes computes in[floor(y / f)] for output row y, for
// every y and every input length n, at integer factor f (output length f*n). ONNX maps y to
// x = T(y) and rounds x with nearest_mode (then clamps to [0, n-1]).
// - asymmetric, half_pixel, pytorch_half_pixel, tf_half_pixel_for_nn: for y = f*k + r,
//   x = k + g(r) with g independent of k and n, so the result is floor(y / f) everywhere exactly
//   when round(k + g(r)) == k for every r in [0, f). That is checked below in exact rationals
//   (denominator 2f). Outcome: asymmetric + floor (any f); asymmetric + round_prefer_floor
//   (f <= 2); half_pixel/pytorch_half_pixel + round_prefer_floor/round_prefer_ceil (any f, the
//   fraction stays inside (-1/2, 1/2)); tf_half_pixel_for_nn + floor (any f).
// - align_corners: x = y (n-1) / (f n - 1). At f = 1, x = y. At f = 2, y = 2k + r gives
//   x = k + (r (n-1) - k) / (2n - 1), whose fraction lies strictly inside (-1/2, 1/2) for
//   0 <= k <= n-1, so round_prefer_floor/ceil give k; floor/ceil do not. At f >= 3, r = f-1,
//   k = 0 gives a fraction (f-1)(n-1)/(fn-1) > 1/2 once n > 3: not exact.
// - tf_crop_and_resize depends on roi: never accepted (it stays a Resize).
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

// TensorFlow 'same' / ONNX SAME_UPPER amounts for one axis.
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

// ONNX SAME_UPPER or SAME_LOWER amounts: the same totals, SAME_LOWER's larger half first.
Pads SamePads(PaddingRule rule, int64_t in_h, int64_t in_w, int kh, int kw, int sh, int sw) {
  const Pads upper = SameUpperPads(in_h, in_w, kh, kw, sh, sw);
  if (rule != PaddingRule::kSameLower) return upper;
  return Pads{upper.bottom, upper.right, upper.top, upper.left};
}

// ------------------------------------------------------------------------- the importer

// A node whose data input is a runtime tensor.
struct GraphOp {
  enum class Kind {
    kConv,
    kPad,
    kBatchNorm,
    kAffine,  // Add, Sub, Mul or Div by a per-channel constant (in batch_norm)
    kActivation,
    kUpsample,
    kSlice,
    kIdentity,
    kConcat,
    kAdd,
    kConvTranspose,
    kPool,
    kResize
  };
  Kind kind = Kind::kIdentity;
  int node_index = 0;
  std::vector<std::string> inputs;  // the runtime tensors it reads; one but for Concat and Add
  std::string output;
  Shape4 in_shape{};
  Shape4 out_shape{};
  ConvSpec conv;             // kConv; pads = the Conv's own amounts at the traced size
  ConvTransposeSpec deconv;  // kConvTranspose
  PoolSpec pool;             // kPool
  ResizeParams resize;       // kResize (a resize that is not nearest upsampling by integers)
  Pads pads;                 // kPad: amounts added; kSlice: amounts removed
  Activation activation = Activation::kNone;
  float slope = 0.0f;
  float elu_alpha = 1.0f;  // kElu
  float clip_min = 0.0f;   // kClip
  float clip_max = 0.0f;
  int factor_h = 1;
  int factor_w = 1;
  ChannelAffine batch_norm;  // kBatchNorm and kAffine (batch_norm_fold.h)
};

class Importer {
 public:
  // `bytes` must outlive the importer; `path` labels messages and names the source file.
  Importer(std::string_view bytes, const std::string& path, const OnnxImportOptions& options)
      : bytes_(bytes), path_(path), options_(options), budget_(bytes.size()) {}

  Result<ModelSpec> Run();

 private:
  const onnx::GraphProto& graph() const { return model_.graph(); }

  Status FileError(const std::string& message) const {
    return Status::Error(path_ + ": " + message);
  }
  std::string NodeLabel(int idx) const {
    const onnx::NodeProto& n = graph().node(idx);
    std::string label =
        n.name().empty() ? "node #" + std::to_string(idx) : "node " + Quote(n.name());
    return label + " (op " + Printable(n.op_type()) + ")";
  }
  Status NodeError(int idx, const std::string& message) const {
    return FileError(NodeLabel(idx) + ": " + message);
  }
  Status Unsupported(int idx, const std::string& note) const {
    return NodeError(idx, "unsupported; supported ops: " + SupportedOpsText() + note);
  }

  // How a node that reads a tensor depending on the network input becomes a GraphOp: one rule per
  // op type, found by name (FindRuntimeOp), as the constant folders are (onnx/folders.h).
  enum class Merge {
    kNever,                    // reads one such tensor; its other inputs are constants
    kAlways,                   // Concat: reads several (ProcessMergeNode)
    kWithSeveralRuntimeInputs  // Add: a merge when it reads several, a scale and shift otherwise
  };
  struct RuntimeOp {
    std::string_view type;
    GraphOp::Kind kind;
    Status (Importer::*process)(int idx, GraphOp& op);  // null: nothing to read (Identity)
    Activation activation = Activation::kNone;          // kActivation: which
    Merge merge = Merge::kNever;
  };
  static std::span<const RuntimeOp> RuntimeOps();
  static const RuntimeOp* FindRuntimeOp(std::string_view type);
  // "Conv, Pad, ... (constant subgraphs may also use Constant, Shape, ...)".
  static std::string SupportedOpsText();

  Status Load();
  Status ReadOpset();
  Status ReadInitializers();
  Status ReadInput();
  Status ChooseOutput();
  std::vector<bool> LiveNodes() const;
  // Live nodes whose op type (or domain) the importer does not know at all.
  std::vector<int> UnknownOpNodes(const std::vector<bool>& live) const;
  // One message listing `nodes` (at most kMaxListedNodes, then a count).
  Status UnsupportedNodesError(const std::vector<int>& nodes) const;
  Status ProcessNode(int idx);
  Status ProcessConstant(int idx);
  Status FoldNode(int idx);
  // A node whose input `slot` is a runtime tensor and whose other inputs are constants.
  Status ProcessRuntimeNode(int idx, int slot);
  Status ProcessClip(int idx, GraphOp& op);
  // Relu, LeakyRelu, Elu, Sigmoid, Tanh (op.activation set by the op's rule).
  Status ProcessActivation(int idx, GraphOp& op);
  Status CheckIntegerGraph(const std::vector<bool>& needed) const;
  // Add, Sub, Mul or Div of the runtime tensor it reads (op.inputs[0]) and a per-channel constant.
  Status ProcessElementwise(int idx, GraphOp& op);
  Status ProcessConv(int idx, GraphOp& op);
  Status ProcessConvTranspose(int idx, GraphOp& op);
  Status ProcessPool(int idx, GraphOp& op);
  Status ProcessPad(int idx, GraphOp& op);
  Status ProcessBatchNorm(int idx, GraphOp& op);
  Status ProcessResize(int idx, GraphOp& op);
  Status ResizeRegionOfInterest(int idx, float extrapolation_value, ResizeParams& r);
  Status ResizeScales(int idx, const GraphOp& op, const std::vector<double>& scales,
                      const std::vector<int64_t>& sizes, int64_t num[2], int64_t den[2]);
  Status ProcessSlice(int idx, GraphOp& op);
  // Concat and Add of runtime tensors.
  Status ProcessMergeNode(int idx);
  Result<ModelSpec> Assemble();

  // What Assemble keeps over the needed ops.
  struct ConvTrace {
    size_t layer = 0;
    int node_index = 0;
    int64_t in_h = 0;  // before any folded Pad
    int64_t in_w = 0;
  };
  struct CropTrace {
    size_t layer = 0;
    std::string output;  // the runtime tensor it ends in (consecutive Slices merge)
    int64_t out_h = 0;
    int64_t out_w = 0;
  };
  // What each runtime tensor is in the spec: the layer that computes it (or the input), and for a
  // Pad's output the amounts waiting for the Conv that reads it.
  struct Source {
    std::string layer;     // a layer's name, or input_name_
    int layer_index = -1;  // into spec.layers; -1 for the input
    bool padded = false;   // a Pad's output: only a Conv (or another Pad) may read it
    Pads pads;             // accumulated amounts when padded
    std::vector<int> pad_nodes;
    Shape4 pre_pad_shape{};
  };
  struct Assembly {
    ModelSpec spec;
    // The needed ops that read each runtime tensor.
    std::unordered_map<std::string, std::vector<size_t>> readers;
    std::set<std::string> used_names;  // layer names taken
    std::unordered_map<std::string, Source> source;
    std::vector<ConvTrace> convs;
    std::vector<CropTrace> crops;
    struct {
      int convs = 0, ups = 0, crops = 0, cats = 0, adds = 0, deconvs = 0, pools = 0, affines = 0;
    } count;  // the layers of each prefix named so far
  };
  using Lowering = Status (Importer::*)(Assembly& a, const GraphOp& op);
  static Lowering LoweringOf(GraphOp::Kind kind);
  Status LowerIdentity(Assembly& a, const GraphOp& op);
  Status LowerPad(Assembly& a, const GraphOp& op);
  Status LowerConv(Assembly& a, const GraphOp& op);
  Status LowerPool(Assembly& a, const GraphOp& op);
  Status LowerConvTranspose(Assembly& a, const GraphOp& op);
  Status LowerScaleOrActivation(Assembly& a, const GraphOp& op);
  Status LowerResize(Assembly& a, const GraphOp& op);
  Status LowerUpsample(Assembly& a, const GraphOp& op);
  Status LowerSlice(Assembly& a, const GraphOp& op);
  Status LowerConcat(Assembly& a, const GraphOp& op);
  Status LowerAdd(Assembly& a, const GraphOp& op);
  std::vector<bool> NeededOps(const std::string& out_name) const;
  std::string UniqueName(Assembly& a, const std::string& wanted, const std::string& prefix,
                         int counter);
  void AddLayer(Assembly& a, LayerSpec layer, const std::string& output);
  std::vector<std::string> InputNames(const Assembly& a, const GraphOp& op) const;
  // The layer that computes `tensor` when this op alone reads it, so that a BatchNormalization,
  // an activation or another Slice may fold into it.
  static bool SoleReader(Assembly& a, const std::string& tensor) {
    return a.readers[tensor].size() == 1;
  }
  Status CheckPadReader(const Assembly& a, const GraphOp& op) const;
  Status CheckAssembledOutput(const Assembly& a, const std::string& out_name) const;
  Status ChoosePaddingRules(Assembly& a) const;
  void ChooseCropRules(Assembly& a) const;
  // The pads of Conv node `idx` (its own plus those of the Pad nodes `pad_nodes` folded into it)
  // against the loader's limit, kernel - 1 per side.
  Status CheckConvPads(int idx, const ConvSpec& conv, const std::vector<int>& pad_nodes) const;

  bool IsConst(const std::string& name) const {
    return consts_.count(name) > 0 || initializers_.count(name) > 0;
  }
  // The constant input `slot` of node `idx` (a copy, charged to budget_). Errors name the node
  // and its input slot.
  Result<Const> GetConst(int idx, int slot);
  // The optional constant input `slot` of node `idx`: absent (empty name or beyond the inputs)
  // gives an empty optional.
  Result<std::optional<Const>> GetOptionalConst(int idx, int slot);
  // The FLOAT constant input `slot` of node `idx` as float32 values (charged to budget_), and
  // its shape in `dims`.
  Result<std::vector<float>> GetFloats(int idx, int slot, Dims* dims);

  // Attribute access; errors name the node and the attribute.
  const onnx::AttributeProto* FindAttr(int idx, std::string_view name) const;
  Result<int64_t> IntAttr(int idx, std::string_view name, int64_t fallback) const;
  Result<std::vector<int64_t>> IntsAttr(int idx, std::string_view name) const;
  // A 2-D dilations attribute: {1, 1} when absent; each value in 1..kMaxDilation.
  Result<std::vector<int64_t>> DilationsAttr(int idx, std::string_view name) const;
  Result<float> FloatAttr(int idx, std::string_view name, float fallback) const;
  Result<std::string> StringAttr(int idx, std::string_view name, const std::string& fallback) const;

  std::string_view bytes_;
  std::string path_;
  OnnxImportOptions options_;
  ConstantBudget budget_;
  int output_index_ = 0;  // the graph output the model computes (ChooseOutput)
  onnx::ModelProto model_;
  int64_t opset_ = 0;
  std::unordered_map<std::string, const TensorProto*> initializers_;
  std::unordered_map<std::string, Const> consts_;
  std::unordered_map<std::string, Shape4> runtime_;      // runtime tensor -> static shape
  std::unordered_map<std::string, size_t> producer_op_;  // runtime tensor -> index in ops_
  std::vector<GraphOp> ops_;
  std::string input_name_;
  Shape4 input_shape_{};
  // The graph input's element type when it is an 8- or 16-bit integer; 0 for FLOAT.
  int integer_io_type_ = 0;
};

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

Status Importer::ProcessConv(int idx, GraphOp& op) {
  const onnx::NodeProto& n = graph().node(idx);
  if (n.input_size() < 2) return NodeError(idx, "needs a weight input");
  Dims wdims;
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<float> w, GetFloats(idx, 1, &wdims));
  if (wdims.size() != 4) {
    return NodeError(idx, "weight " + Quote(n.input(1)) + " has shape " + JoinInts(wdims) +
                              "; only 2-D convolutions (OIHW weights) are supported");
  }
  // The weight's second dimension is the inputs per group.
  const int64_t out_ch = wdims[0], group_in = wdims[1], kh = wdims[2], kw = wdims[3];
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t group, IntAttr(idx, "group", 1));
  if (group < 1 || group > model_limits::kMaxChannels || out_ch % group != 0) {
    return NodeError(idx, "attribute 'group' = " + std::to_string(group) +
                              " must be positive and divide the weight's " +
                              std::to_string(out_ch) + " output channels");
  }
  const int64_t in_ch = group_in * group;
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<int64_t> dilations, DilationsAttr(idx, "dilations"));
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<int64_t> kernel_shape,
                             IntsAttr(idx, "kernel_shape"));
  if (!kernel_shape.empty() && kernel_shape != std::vector<int64_t>{kh, kw}) {
    return NodeError(idx, "attribute 'kernel_shape' = " + JoinInts(kernel_shape) +
                              " does not match the weight shape " + JoinInts(wdims));
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> strides, IntsAttr(idx, "strides"));
  if (strides.empty()) strides = {1, 1};
  if (strides.size() != 2 || strides[0] < 1 || strides[1] < 1) {
    return NodeError(idx, "attribute 'strides' = " + JoinInts(strides) + " is not supported");
  }
  if (in_ch != op.in_shape[1]) {
    return NodeError(idx, "weight " + Quote(n.input(1)) + " with group " + std::to_string(group) +
                              " expects " + std::to_string(in_ch) +
                              " input channels, the input tensor " + Quote(op.inputs[0]) + " has " +
                              std::to_string(op.in_shape[1]));
  }
  if (out_ch < 1 || kh < 1 || kw < 1) {
    return NodeError(idx, "weight " + Quote(n.input(1)) + " has an empty shape " + JoinInts(wdims));
  }
  if (kh > model_limits::kMaxKernel || kw > model_limits::kMaxKernel) {
    return NodeError(idx, "attribute 'kernel_shape' = " + JoinInts({kh, kw}) +
                              " exceeds the largest kernel side " +
                              std::to_string(model_limits::kMaxKernel));
  }
  if (strides[0] > model_limits::kMaxStride || strides[1] > model_limits::kMaxStride) {
    return NodeError(idx, "attribute 'strides' = " + JoinInts(strides) +
                              " exceeds the largest stride " +
                              std::to_string(model_limits::kMaxStride));
  }
  if (out_ch > model_limits::kMaxChannels) {
    return NodeError(idx, "weight " + Quote(n.input(1)) + " has " + std::to_string(out_ch) +
                              " output channels; at most " +
                              std::to_string(model_limits::kMaxChannels) + " are supported");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::string auto_pad, StringAttr(idx, "auto_pad", "NOTSET"));
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> pads, IntsAttr(idx, "pads"));
  const int64_t in_h = op.in_shape[2];
  const int64_t in_w = op.in_shape[3];
  const int64_t extent_h = (kh - 1) * dilations[0] + 1;  // the window's rows
  const int64_t extent_w = (kw - 1) * dilations[1] + 1;
  Pads p;
  PaddingRule rule = PaddingRule::kExplicit;
  if (auto_pad == "NOTSET") {
    if (pads.empty()) pads = {0, 0, 0, 0};
    if (pads.size() != 4) {
      return NodeError(idx, "attribute 'pads' = " + JoinInts(pads) + " must have 4 values");
    }
    for (int64_t v : pads) {
      if (v < 0 || v > std::numeric_limits<int32_t>::max()) {
        return NodeError(idx, "attribute 'pads' = " + JoinInts(pads) + " is not supported");
      }
    }
    p = Pads{static_cast<int>(pads[0]), static_cast<int>(pads[1]), static_cast<int>(pads[2]),
             static_cast<int>(pads[3])};
  } else if (auto_pad == "VALID") {
    p = Pads{};
  } else if (auto_pad == "SAME_UPPER" || auto_pad == "SAME_LOWER") {
    // SAME_UPPER is found again from the pads with the rest of the network's convolutions;
    // SAME_LOWER keeps its own rule.
    if (auto_pad == "SAME_LOWER") rule = PaddingRule::kSameLower;
    p = SamePads(rule, in_h, in_w, static_cast<int>(extent_h), static_cast<int>(extent_w),
                 static_cast<int>(strides[0]), static_cast<int>(strides[1]));
  } else {
    return NodeError(idx, "attribute 'auto_pad' = " + Quote(auto_pad) +
                              " is not supported (NOTSET, SAME_UPPER, SAME_LOWER, VALID)");
  }
  const int64_t padded_h = in_h + p.top + p.bottom;
  const int64_t padded_w = in_w + p.left + p.right;
  if (padded_h < extent_h || padded_w < extent_w) {
    return NodeError(
        idx, "kernel " + std::to_string(kh) + "x" + std::to_string(kw) +
                 (extent_h != kh || extent_w != kw ? " (dilated to " + std::to_string(extent_h) +
                                                         "x" + std::to_string(extent_w) + ")"
                                                   : std::string()) +
                 " is larger than the padded input " + std::to_string(padded_h) + "x" +
                 std::to_string(padded_w));
  }
  op.out_shape = {1, out_ch, (padded_h - extent_h) / strides[0] + 1,
                  (padded_w - extent_w) / strides[1] + 1};

  ConvSpec& c = op.conv;
  c.name = n.name();
  c.in_channels = static_cast<int>(in_ch);
  c.out_channels = static_cast<int>(out_ch);
  c.kernel_h = static_cast<int>(kh);
  c.kernel_w = static_cast<int>(kw);
  c.stride_h = static_cast<int>(strides[0]);
  c.stride_w = static_cast<int>(strides[1]);
  c.dilation_h = static_cast<int>(dilations[0]);
  c.dilation_w = static_cast<int>(dilations[1]);
  c.groups = static_cast<int>(group);
  c.pads = p;
  c.padding_rule = rule;
  c.weights_hwio.resize(w.size());
  // OIHW with I the inputs per group -> HWIO with the same I: the output index stays global.
  for (int64_t co = 0; co < out_ch; ++co) {
    for (int64_t ci = 0; ci < group_in; ++ci) {
      for (int64_t ky = 0; ky < kh; ++ky) {
        for (int64_t kx = 0; kx < kw; ++kx) {
          c.weights_hwio[((ky * kw + kx) * group_in + ci) * out_ch + co] =
              w[((co * group_in + ci) * kh + ky) * kw + kx];
        }
      }
    }
  }
  c.bias.assign(static_cast<size_t>(out_ch), 0.0f);
  if (n.input_size() > 2 && !n.input(2).empty()) {
    Dims bdims;
    SFRT_ONNX_ASSIGN_OR_RETURN(c.bias, GetFloats(idx, 2, &bdims));
    if (bdims != Dims{out_ch}) {
      return NodeError(idx, "bias " + Quote(n.input(2)) + " has shape " + JoinInts(bdims) +
                                ", expected [" + std::to_string(out_ch) + "]");
    }
  }
  return Status::Ok();
}

// ONNX ConvTranspose (opsets 1-17): weights (C_in, C_out, kH, kW), each input pixel scattered
// through the kernel at stride `strides`, `pads` removed from the full output's borders and
// `output_padding` added at its end: exactly sfrt's ConvTranspose2D with HWIO weights.
Status Importer::ProcessConvTranspose(int idx, GraphOp& op) {
  const onnx::NodeProto& n = graph().node(idx);
  if (n.input_size() < 2) return NodeError(idx, "needs a weight input");
  Dims wdims;
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<float> w, GetFloats(idx, 1, &wdims));
  if (wdims.size() != 4) {
    return NodeError(idx, "weight " + Quote(n.input(1)) + " has shape " + JoinInts(wdims) +
                              "; only 2-D transposed convolutions (IOHW weights) are supported");
  }
  const int64_t in_ch = wdims[0], out_ch = wdims[1], kh = wdims[2], kw = wdims[3];
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t group, IntAttr(idx, "group", 1));
  if (group != 1) {
    return NodeError(
        idx, "attribute 'group' = " + std::to_string(group) + " is not supported (only group 1)");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<int64_t> dilations, DilationsAttr(idx, "dilations"));
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<int64_t> kernel_shape,
                             IntsAttr(idx, "kernel_shape"));
  if (!kernel_shape.empty() && kernel_shape != std::vector<int64_t>{kh, kw}) {
    return NodeError(idx, "attribute 'kernel_shape' = " + JoinInts(kernel_shape) +
                              " does not match the weight shape " + JoinInts(wdims));
  }
  if (in_ch != op.in_shape[1]) {
    return NodeError(idx, "weight " + Quote(n.input(1)) + " expects " + std::to_string(in_ch) +
                              " input channels, the input tensor " + Quote(op.inputs[0]) + " has " +
                              std::to_string(op.in_shape[1]));
  }
  if (out_ch < 1 || kh < 1 || kw < 1 || kh > model_limits::kMaxKernel ||
      kw > model_limits::kMaxKernel || out_ch > model_limits::kMaxChannels) {
    return NodeError(
        idx, "weight " + Quote(n.input(1)) + " has shape " + JoinInts(wdims) +
                 "; kernel sides must be in 1.." + std::to_string(model_limits::kMaxKernel) +
                 " and output channels in 1.." + std::to_string(model_limits::kMaxChannels));
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> strides, IntsAttr(idx, "strides"));
  if (strides.empty()) strides = {1, 1};
  if (strides.size() != 2 || strides[0] < 1 || strides[1] < 1 ||
      strides[0] > model_limits::kMaxStride || strides[1] > model_limits::kMaxStride) {
    return NodeError(idx, "attribute 'strides' = " + JoinInts(strides) + " is not supported (1.." +
                              std::to_string(model_limits::kMaxStride) + " per axis)");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> out_pad, IntsAttr(idx, "output_padding"));
  if (out_pad.empty()) out_pad = {0, 0};
  if (out_pad.size() != 2 || out_pad[0] < 0 || out_pad[1] < 0 || out_pad[0] >= strides[0] ||
      out_pad[1] >= strides[1]) {
    return NodeError(idx, "attribute 'output_padding' = " + JoinInts(out_pad) +
                              " is not supported (two values, each below its stride)");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::string auto_pad, StringAttr(idx, "auto_pad", "NOTSET"));
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> pads, IntsAttr(idx, "pads"));
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<int64_t> output_shape,
                             IntsAttr(idx, "output_shape"));
  if (auto_pad != "NOTSET" && auto_pad != "VALID" && auto_pad != "SAME_UPPER" &&
      auto_pad != "SAME_LOWER") {
    return NodeError(idx, "attribute 'auto_pad' = " + Quote(auto_pad) +
                              " is not supported (NOTSET, SAME_UPPER, SAME_LOWER, VALID)");
  }
  if (!output_shape.empty() && output_shape.size() < 2) {
    return NodeError(idx, "attribute 'output_shape' = " + JoinInts(output_shape) +
                              " needs the output height and width");
  }
  const bool same = auto_pad == "SAME_UPPER" || auto_pad == "SAME_LOWER";
  if (same || (!output_shape.empty() && auto_pad == "NOTSET" && pads.empty())) {
    // ONNX: the pads (and, where they would be negative, extra output padding) that give the
    // asked-for size: in * stride for SAME_*, else output_shape; the odd pixel goes to the end
    // for SAME_UPPER, to the start otherwise.
    pads = {0, 0, 0, 0};
    for (int a = 0; a < 2; ++a) {
      const int64_t in = op.in_shape[2 + a];
      const int64_t kernel = ((a == 0 ? kh : kw) - 1) * dilations[a] + 1;
      const int64_t target = same ? in * strides[a] : output_shape[output_shape.size() - 2 + a];
      const int64_t total = (in - 1) * strides[a] + out_pad[a] + kernel - target;
      if (total < 0) {
        out_pad[a] -= total;
        continue;
      }
      const int64_t larger = total - total / 2;
      pads[a] = auto_pad == "SAME_UPPER" ? total / 2 : larger;
      pads[a + 2] = total - pads[a];
    }
    if (out_pad[0] >= strides[0] || out_pad[1] >= strides[1]) {
      return NodeError(idx, "its output size needs output padding " + JoinInts(out_pad) +
                                ", not below its strides " + JoinInts(strides));
    }
  }
  if (auto_pad == "VALID" || (auto_pad == "NOTSET" && pads.empty())) pads = {0, 0, 0, 0};
  if (pads.size() != 4) {
    return NodeError(idx, "attribute 'pads' = " + JoinInts(pads) + " must have 4 values");
  }
  // pads are (top, left, bottom, right); each removes output rows or columns the kernel wrote.
  const int64_t extent_h = (kh - 1) * dilations[0] + 1;
  const int64_t extent_w = (kw - 1) * dilations[1] + 1;
  const int64_t limits[4] = {extent_h, extent_w, extent_h, extent_w};
  for (size_t k = 0; k < 4; ++k) {
    if (pads[k] < 0 || pads[k] >= limits[k]) {
      return NodeError(idx, "attribute 'pads' = " + JoinInts(pads) +
                                " is not supported (each at least 0 and below its kernel side)");
    }
  }
  const int64_t in_h = op.in_shape[2];
  const int64_t in_w = op.in_shape[3];
  const int64_t out_h = (in_h - 1) * strides[0] - pads[0] - pads[2] + extent_h + out_pad[0];
  const int64_t out_w = (in_w - 1) * strides[1] - pads[1] - pads[3] + extent_w + out_pad[1];
  if (!output_shape.empty() &&
      (output_shape[output_shape.size() - 2] != out_h || output_shape.back() != out_w)) {
    return NodeError(idx, "attribute 'output_shape' = " + JoinInts(output_shape) +
                              " differs from the size its pads give (" + std::to_string(out_h) +
                              "x" + std::to_string(out_w) +
                              "); give pads and output_padding instead");
  }
  if (out_h < 1 || out_w < 1) {
    return NodeError(idx, "its pads leave an empty output (" + std::to_string(out_h) + "x" +
                              std::to_string(out_w) + ")");
  }
  op.out_shape = {1, out_ch, out_h, out_w};

  ConvTransposeSpec& d = op.deconv;
  d.name = n.name();
  d.in_channels = static_cast<int>(in_ch);
  d.out_channels = static_cast<int>(out_ch);
  d.kernel_h = static_cast<int>(kh);
  d.kernel_w = static_cast<int>(kw);
  d.stride_h = static_cast<int>(strides[0]);
  d.stride_w = static_cast<int>(strides[1]);
  d.dilation_h = static_cast<int>(dilations[0]);
  d.dilation_w = static_cast<int>(dilations[1]);
  d.pads = Pads{static_cast<int>(pads[0]), static_cast<int>(pads[1]), static_cast<int>(pads[2]),
                static_cast<int>(pads[3])};
  d.output_padding_h = static_cast<int>(out_pad[0]);
  d.output_padding_w = static_cast<int>(out_pad[1]);
  d.weights_hwio.resize(w.size());
  for (int64_t ci = 0; ci < in_ch; ++ci) {
    for (int64_t co = 0; co < out_ch; ++co) {
      for (int64_t ky = 0; ky < kh; ++ky) {
        for (int64_t kx = 0; kx < kw; ++kx) {
          d.weights_hwio[((ky * kw + kx) * in_ch + ci) * out_ch + co] =
              w[((ci * out_ch + co) * kh + ky) * kw + kx];
        }
      }
    }
  }
  d.bias.assign(static_cast<size_t>(out_ch), 0.0f);
  if (n.input_size() > 2 && !n.input(2).empty()) {
    Dims bdims;
    SFRT_ONNX_ASSIGN_OR_RETURN(d.bias, GetFloats(idx, 2, &bdims));
    if (bdims != Dims{out_ch}) {
      return NodeError(idx, "bias " + Quote(n.input(2)) + " has shape " + JoinInts(bdims) +
                                ", expected [" + std::to_string(out_ch) + "]");
    }
  }
  return Status::Ok();
}

// ONNX MaxPool and AveragePool (opsets 1-17), 2-D: explicit pads, VALID or SAME_UPPER,
// ceil_mode, count_include_pad. A MaxPool's optional Indices output becomes a second op, an
// argmax pool (ProcessRuntimeNode).
Status Importer::ProcessPool(int idx, GraphOp& op) {
  const onnx::NodeProto& n = graph().node(idx);
  const bool max = n.op_type() == "MaxPool";
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<int64_t> kernel, IntsAttr(idx, "kernel_shape"));
  if (kernel.size() != 2 || kernel[0] < 1 || kernel[1] < 1 ||
      kernel[0] > model_limits::kMaxKernel || kernel[1] > model_limits::kMaxKernel) {
    return NodeError(idx, "attribute 'kernel_shape' = " + JoinInts(kernel) +
                              " is not supported (two sides, each 1.." +
                              std::to_string(model_limits::kMaxKernel) + ")");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<int64_t> dilations, DilationsAttr(idx, "dilations"));
  // How the Indices output numbers the input: row-major (0) or column-major (1).
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t storage_order, IntAttr(idx, "storage_order", 0));
  if (storage_order != 0 && storage_order != 1) {
    return NodeError(idx, "attribute 'storage_order' = " + std::to_string(storage_order) +
                              " is not supported (0 or 1)");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> strides, IntsAttr(idx, "strides"));
  if (strides.empty()) strides = {1, 1};
  if (strides.size() != 2 || strides[0] < 1 || strides[1] < 1 ||
      strides[0] > model_limits::kMaxStride || strides[1] > model_limits::kMaxStride) {
    return NodeError(idx, "attribute 'strides' = " + JoinInts(strides) + " is not supported (1.." +
                              std::to_string(model_limits::kMaxStride) + " per axis)");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t ceil_mode, IntAttr(idx, "ceil_mode", 0));
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t count_include_pad, IntAttr(idx, "count_include_pad", 0));
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::string auto_pad, StringAttr(idx, "auto_pad", "NOTSET"));
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> pads, IntsAttr(idx, "pads"));
  PoolSpec& p = op.pool;
  p.name = n.name();
  p.kind = max ? PoolKind::kMax : PoolKind::kAverage;
  p.kernel_h = static_cast<int>(kernel[0]);
  p.kernel_w = static_cast<int>(kernel[1]);
  p.stride_h = static_cast<int>(strides[0]);
  p.stride_w = static_cast<int>(strides[1]);
  p.dilation_h = static_cast<int>(dilations[0]);
  p.dilation_w = static_cast<int>(dilations[1]);
  const int extent_h = DilatedExtent(p.kernel_h, p.dilation_h);
  const int extent_w = DilatedExtent(p.kernel_w, p.dilation_w);
  p.ceil_mode = ceil_mode != 0;
  p.indices_column_major = storage_order == 1;  // used by the Indices output only
  p.count_include_pad = !max && count_include_pad != 0;
  const int64_t in_h = op.in_shape[2];
  const int64_t in_w = op.in_shape[3];
  if (auto_pad == "SAME_UPPER" || auto_pad == "SAME_LOWER") {
    p.padding_rule = auto_pad == "SAME_UPPER" ? PaddingRule::kSameUpper : PaddingRule::kSameLower;
    p.pads = SamePads(p.padding_rule, in_h, in_w, extent_h, extent_w, p.stride_h, p.stride_w);
  } else if (auto_pad == "NOTSET" || auto_pad == "VALID") {
    if (auto_pad == "VALID" || pads.empty()) pads = {0, 0, 0, 0};
    if (pads.size() != 4) {
      return NodeError(idx, "attribute 'pads' = " + JoinInts(pads) + " must have 4 values");
    }
    const int64_t limits[4] = {extent_h, extent_w, extent_h, extent_w};
    for (size_t k = 0; k < 4; ++k) {
      if (pads[k] < 0 || pads[k] >= limits[k]) {
        return NodeError(idx, "attribute 'pads' = " + JoinInts(pads) +
                                  " is not supported (each at least 0 and below its window's "
                                  "dilated side)");
      }
    }
    p.pads = Pads{static_cast<int>(pads[0]), static_cast<int>(pads[1]), static_cast<int>(pads[2]),
                  static_cast<int>(pads[3])};
  } else {
    return NodeError(idx, "attribute 'auto_pad' = " + Quote(auto_pad) +
                              " is not supported (NOTSET, SAME_UPPER, SAME_LOWER, VALID)");
  }
  int before = 0, after = 0;
  const int out_h = PoolOutputSize(static_cast<int>(in_h), extent_h, p.stride_h, p.padding_rule,
                                   p.pads.top, p.pads.bottom, p.ceil_mode, &before, &after);
  const int out_w = PoolOutputSize(static_cast<int>(in_w), extent_w, p.stride_w, p.padding_rule,
                                   p.pads.left, p.pads.right, p.ceil_mode, &before, &after);
  if (out_h < 1 || out_w < 1) {
    return NodeError(idx, "its " + JoinInts(kernel) + " window does not fit the " +
                              std::to_string(in_h) + "x" + std::to_string(in_w) +
                              " input with its pads");
  }
  op.out_shape = {1, op.in_shape[1], out_h, out_w};
  return Status::Ok();
}

Status Importer::ProcessPad(int idx, GraphOp& op) {
  const onnx::NodeProto& n = graph().node(idx);
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::string mode, StringAttr(idx, "mode", "constant"));
  if (mode != "constant") {
    return NodeError(idx, "attribute 'mode' = " + Quote(mode) +
                              " is not supported (only constant zero padding)");
  }
  if (n.input_size() < 2 || n.input(1).empty()) return NodeError(idx, "input 'pads' is missing");
  if (n.input_size() > 3 && !n.input(3).empty()) {
    return NodeError(idx, "input 'axes' is not supported");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(const Const pads_c, GetConst(idx, 1));
  if (pads_c.is_real() || pads_c.size() != 8) {
    return NodeError(idx, "input 'pads' must hold 8 integers (NCHW begins, then ends)");
  }
  const std::vector<int64_t>& pv = pads_c.ints;
  if (pv[0] != 0 || pv[1] != 0 || pv[4] != 0 || pv[5] != 0) {
    return NodeError(idx, "input 'pads' = " + JoinInts(pv) +
                              " pads the batch or channel axis; only H and W can be padded");
  }
  for (int64_t v : pv) {
    if (v < 0 || v > std::numeric_limits<int32_t>::max() / 4) {
      return NodeError(
          idx, "input 'pads' = " + JoinInts(pv) + " is not supported (negative or huge amounts)");
    }
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::optional<Const> value, GetOptionalConst(idx, 2));
  if (value.has_value()) {
    if (value->size() > 1) return NodeError(idx, "input 'constant_value' must be a scalar");
    if (value->size() == 1 && value->Real(0) != 0.0) {
      return NodeError(idx, "input 'constant_value' = " + FormatDouble(value->Real(0)) +
                                " is not supported (only zero padding)");
    }
  }
  op.pads = Pads{static_cast<int>(pv[2]), static_cast<int>(pv[3]), static_cast<int>(pv[6]),
                 static_cast<int>(pv[7])};
  op.out_shape = {op.in_shape[0], op.in_shape[1], op.in_shape[2] + pv[2] + pv[6],
                  op.in_shape[3] + pv[3] + pv[7]};
  return Status::Ok();
}

// Scales (from 'scales', or 'sizes' over the traced input) as exact fractions: a float scale is a
// binary fraction, a size ratio is sizes / input. Only H and W may be scaled.
Status Importer::ResizeScales(int idx, const GraphOp& op, const std::vector<double>& scales,
                              const std::vector<int64_t>& sizes, int64_t num[2], int64_t den[2]) {
  const std::string what = scales.empty() ? "input 'sizes' = " + JoinInts(sizes)
                                          : "input 'scales' = " + JoinReals(scales);
  if ((scales.empty() ? sizes.size() : scales.size()) != 4) {
    return NodeError(idx, what + " must have 4 values (NCHW)");
  }
  for (int k = 0; k < 4; ++k) {
    int64_t n = 1;
    int64_t d = 1;
    if (!scales.empty()) {
      const double s = scales[k];
      if (!std::isfinite(s) || s <= 0 || s > model_limits::kMaxUpsample) {
        return NodeError(idx, what + ": value " + FormatDouble(s) + " on axis " +
                                  std::to_string(k) + " is not in (0, " +
                                  std::to_string(model_limits::kMaxUpsample) + "]");
      }
      // s * 2^e is an integer for some e <= 32 when s came from a float.
      int e = 0;
      while (e < 32 && std::ldexp(s, e) != std::floor(std::ldexp(s, e))) ++e;
      if (std::ldexp(s, e) != std::floor(std::ldexp(s, e))) {
        return NodeError(idx, what + ": value " + FormatDouble(s) + " on axis " +
                                  std::to_string(k) + " is not a float32 number");
      }
      n = static_cast<int64_t>(std::ldexp(s, e));
      d = int64_t{1} << e;
    } else {
      if (sizes[k] < 1 || sizes[k] > op.in_shape[k] * model_limits::kMaxUpsample) {
        return NodeError(idx, what + " for an input of shape " + ShapeText(op.in_shape) +
                                  ": axis " + std::to_string(k) + " is not in 1.." +
                                  std::to_string(model_limits::kMaxUpsample) + " times the input");
      }
      n = sizes[k];
      d = op.in_shape[k];
    }
    const int64_t g = std::gcd(n, d);
    n /= g;
    d /= g;
    if (k < 2 && (n != 1 || d != 1)) {
      return NodeError(idx, what + " scales the batch or channel axis; only H and W");
    }
    if (k >= 2) {
      num[k - 2] = n;
      den[k - 2] = d;
    }
  }
  return Status::Ok();
}

Status Importer::ProcessResize(int idx, GraphOp& op) {
  const onnx::NodeProto& n = graph().node(idx);
  const bool is_resize = n.op_type() == "Resize";
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::string mode, StringAttr(idx, "mode", "nearest"));
  if (mode != "nearest" && mode != "linear" && mode != "cubic") {
    return NodeError(
        idx, "attribute 'mode' = " + Quote(mode) + " is not supported (nearest, linear, cubic)");
  }
  std::string ctm = "asymmetric";
  std::string nearest_mode = "floor";  // Upsample: in[floor(y / scale)]
  float cubic_a = -0.75f;
  int64_t exclude_outside = 0;
  float extrapolation_value = 0.0f;
  if (is_resize) {
    SFRT_ONNX_ASSIGN_OR_RETURN(ctm,
                               StringAttr(idx, "coordinate_transformation_mode", "half_pixel"));
    SFRT_ONNX_ASSIGN_OR_RETURN(nearest_mode, StringAttr(idx, "nearest_mode", "round_prefer_floor"));
    SFRT_ONNX_ASSIGN_OR_RETURN(cubic_a, FloatAttr(idx, "cubic_coeff_a", -0.75f));
    SFRT_ONNX_ASSIGN_OR_RETURN(exclude_outside, IntAttr(idx, "exclude_outside", 0));
    SFRT_ONNX_ASSIGN_OR_RETURN(extrapolation_value, FloatAttr(idx, "extrapolation_value", 0.0f));
  } else if (mode == "cubic") {
    return NodeError(idx, "attribute 'mode' = 'cubic' is not an Upsample mode (nearest, linear)");
  }
  // Scales or sizes.
  std::vector<double> scales;
  std::vector<int64_t> sizes;
  if (is_resize) {
    SFRT_ONNX_ASSIGN_OR_RETURN(const std::optional<Const> s, GetOptionalConst(idx, 2));
    SFRT_ONNX_ASSIGN_OR_RETURN(const std::optional<Const> z, GetOptionalConst(idx, 3));
    if (s.has_value() && s->size() > 0) {
      for (size_t i = 0; i < s->size(); ++i) scales.push_back(s->Real(i));
    }
    if (z.has_value() && z->size() > 0) {
      if (z->is_real()) return NodeError(idx, "input 'sizes' must be integers");
      sizes = z->ints;
    }
    if (scales.empty() == sizes.empty()) {
      return NodeError(idx, "exactly one of the inputs 'scales' and 'sizes' must be given");
    }
  } else if (n.input_size() > 1 && !n.input(1).empty()) {
    SFRT_ONNX_ASSIGN_OR_RETURN(const Const s, GetConst(idx, 1));
    for (size_t i = 0; i < s.size(); ++i) scales.push_back(s.Real(i));
  } else if (const auto* a = FindAttr(idx, "scales"); a != nullptr) {
    scales.assign(a->floats().begin(), a->floats().end());
  } else {
    return NodeError(idx, "no scales given");
  }
  int64_t num[2] = {1, 1};
  int64_t den[2] = {1, 1};
  SFRT_ONNX_RETURN_IF_ERROR(ResizeScales(idx, op, scales, sizes, num, den));
  op.out_shape = {op.in_shape[0], op.in_shape[1], op.in_shape[2] * num[0] / den[0],
                  op.in_shape[3] * num[1] / den[1]};
  if (op.out_shape[2] < 1 || op.out_shape[3] < 1) {
    return NodeError(
        idx, "resizes " + ShapeText(op.in_shape) + " to an empty " + ShapeText(op.out_shape));
  }

  // Nearest upsampling by integer factors that is in[floor(y / f)] stays an Upsample, which the
  // runtime fuses into the convolution after it.
  if (mode == "nearest" && den[0] == 1 && den[1] == 1 &&
      NearestIsFloorOfQuotient(ctm, nearest_mode, num[0]) &&
      NearestIsFloorOfQuotient(ctm, nearest_mode, num[1])) {
    op.kind = GraphOp::Kind::kUpsample;
    op.factor_h = static_cast<int>(num[0]);
    op.factor_w = static_cast<int>(num[1]);
    return Status::Ok();
  }

  ResizeParams& r = op.resize;
  op.kind = GraphOp::Kind::kResize;
  r.mode = mode == "nearest"  ? ResizeMode::kNearest
           : mode == "linear" ? ResizeMode::kLinear
                              : ResizeMode::kCubic;
  static const std::pair<const char*, ResizeCoordinates> kCoordinates[] = {
      {"half_pixel", ResizeCoordinates::kHalfPixel},
      {"pytorch_half_pixel", ResizeCoordinates::kPytorchHalfPixel},
      {"align_corners", ResizeCoordinates::kAlignCorners},
      {"asymmetric", ResizeCoordinates::kAsymmetric},
      {"tf_half_pixel_for_nn", ResizeCoordinates::kTfHalfPixelForNn},
      {"tf_crop_and_resize", ResizeCoordinates::kTfCropAndResize}};
  bool known = false;
  for (const auto& [name, value] : kCoordinates) {
    if (ctm == name) {
      r.coordinates = value;
      known = true;
    }
  }
  if (!known) {
    return NodeError(idx, "attribute 'coordinate_transformation_mode' = " + Quote(ctm) +
                              " is not supported (half_pixel, pytorch_half_pixel, align_corners, "
                              "asymmetric, tf_half_pixel_for_nn, tf_crop_and_resize)");
  }
  if (r.coordinates == ResizeCoordinates::kTfCropAndResize) {
    SFRT_ONNX_RETURN_IF_ERROR(ResizeRegionOfInterest(idx, extrapolation_value, r));
  }
  static const std::pair<const char*, NearestRounding> kRounding[] = {
      {"round_prefer_floor", NearestRounding::kRoundPreferFloor},
      {"round_prefer_ceil", NearestRounding::kRoundPreferCeil},
      {"floor", NearestRounding::kFloor},
      {"ceil", NearestRounding::kCeil}};
  known = false;
  for (const auto& [name, value] : kRounding) {
    if (nearest_mode == name) {
      r.nearest = value;
      known = true;
    }
  }
  if (!known) {
    return NodeError(idx, "attribute 'nearest_mode' = " + Quote(nearest_mode) +
                              " is not supported (round_prefer_floor, round_prefer_ceil, floor, "
                              "ceil)");
  }
  if (!std::isfinite(cubic_a)) {
    return NodeError(idx,
                     "attribute 'cubic_coeff_a' = " + FormatDouble(cubic_a) + " is not finite");
  }
  r.scale_num_h = num[0];
  r.scale_den_h = den[0];
  r.scale_num_w = num[1];
  r.scale_den_w = den[1];
  r.cubic_coeff_a = cubic_a;
  r.exclude_outside = exclude_outside != 0;
  return Status::Ok();
}

// tf_crop_and_resize's region of interest, input 1 (ONNX: starts then ends of every axis, as
// fractions of the input's sides): only H and W may be cut; batch and channels span 0..1.
Status Importer::ResizeRegionOfInterest(int idx, float extrapolation_value, ResizeParams& r) {
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::optional<Const> roi, GetOptionalConst(idx, 1));
  if (!roi.has_value() || roi->size() == 0) {
    return NodeError(idx,
                     "coordinate_transformation_mode 'tf_crop_and_resize' needs the input "
                     "'roi' (8 values: starts then ends of N, C, H, W)");
  }
  std::vector<double> v;
  for (size_t i = 0; i < roi->size(); ++i) v.push_back(roi->Real(i));
  auto text = [&v] {
    std::string t;
    for (double x : v) t += (t.empty() ? "" : ", ") + FormatDouble(x);
    return "[" + t + "]";
  };
  if (v.size() != 8) {
    return NodeError(idx, "input 'roi' has " + std::to_string(v.size()) +
                              " values; a 4-D Resize needs 8 (starts then ends of N, C, H, W)");
  }
  if (v[0] != 0 || v[1] != 0 || v[4] != 1 || v[5] != 1) {
    return NodeError(idx, "input 'roi' = " + text() +
                              " cuts the batch or channel axis; only H and W (starts 2, 3, ends "
                              "6, 7) can be cut");
  }
  for (int i : {2, 3, 6, 7}) {
    if (!(std::fabs(v[static_cast<size_t>(i)]) <= model_limits::kMaxResizeRoi)) {
      return NodeError(idx, "input 'roi' = " + text() +
                                ": every value must be finite and within -" +
                                FormatDouble(model_limits::kMaxResizeRoi) + ".." +
                                FormatDouble(model_limits::kMaxResizeRoi));
    }
  }
  if (!std::isfinite(extrapolation_value)) {
    return NodeError(idx, "attribute 'extrapolation_value' = " + FormatDouble(extrapolation_value) +
                              " is not finite");
  }
  r.roi_start_h = static_cast<float>(v[2]);
  r.roi_start_w = static_cast<float>(v[3]);
  r.roi_end_h = static_cast<float>(v[6]);
  r.roi_end_w = static_cast<float>(v[7]);
  r.extrapolation_value = extrapolation_value;
  return Status::Ok();
}

Status Importer::ProcessSlice(int idx, GraphOp& op) {
  const onnx::NodeProto& n = graph().node(idx);
  if (n.input_size() < 3) return NodeError(idx, "needs inputs 'starts' and 'ends'");
  SFRT_ONNX_ASSIGN_OR_RETURN(const Const starts, GetConst(idx, 1));
  SFRT_ONNX_ASSIGN_OR_RETURN(const Const ends, GetConst(idx, 2));
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::optional<Const> axes, GetOptionalConst(idx, 3));
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::optional<Const> steps, GetOptionalConst(idx, 4));
  auto args = ReadSliceArgs(&starts, &ends, axes ? &*axes : nullptr, steps ? &*steps : nullptr, 4);
  if (!args.ok()) return NodeError(idx, args.message());
  op.out_shape = op.in_shape;
  Pads removed;
  for (size_t i = 0; i < args->axes.size(); ++i) {
    const int64_t axis = args->axes[i];
    if (args->steps[i] != 1) {
      return NodeError(
          idx, "input 'steps' = " + JoinInts(args->steps) + " is not supported (only step 1)");
    }
    const int64_t dim = op.in_shape[axis];
    const SliceAxis s = ClampSlice(args->starts[i], args->ends[i], 1, dim);
    const int64_t before = s.start;
    const int64_t after = dim - s.start - s.count;
    if (s.count < 1) {
      return NodeError(idx, "slice of axis " + std::to_string(axis) + " with starts " +
                                JoinInts(args->starts) + " and ends " + JoinInts(args->ends) +
                                " is empty");
    }
    if (axis < 2) {
      if (before != 0 || after != 0) {
        return NodeError(idx, "slices axis " + std::to_string(axis) +
                                  (axis == 0 ? " (batch)" : " (channels)") + " with starts " +
                                  JoinInts(args->starts) + " and ends " + JoinInts(args->ends) +
                                  "; only H and W (axes 2, 3) can be cropped");
      }
      continue;
    }
    if (axis == 2) {
      removed.top = static_cast<int>(before);
      removed.bottom = static_cast<int>(after);
    } else {
      removed.left = static_cast<int>(before);
      removed.right = static_cast<int>(after);
    }
    op.out_shape[axis] = s.count;
  }
  op.pads = removed;
  return Status::Ok();
}

Status Importer::ProcessBatchNorm(int idx, GraphOp& op) {
  const onnx::NodeProto& n = graph().node(idx);
  // Training mode normalises by the batch's own statistics: nothing to fold.
  const auto* mode = FindAttr(idx, "training_mode");
  if ((mode != nullptr && mode->i() != 0) || n.output_size() > 1) {
    return NodeError(idx, std::string("is a training-mode BatchNormalization") +
                              (mode != nullptr && mode->i() != 0 ? " (training_mode = 1)"
                                                                 : " (it outputs the running "
                                                                   "mean and variance)") +
                              ", which normalises by each batch's statistics; an eval-mode "
                              "export (model.eval() before torch.onnx.export) uses the running "
                              "statistics, which sfrt folds into the preceding Conv");
  }
  if (n.input_size() != 5) {
    return NodeError(
        idx, "expected 5 inputs (X, scale, B, mean, var), found " + std::to_string(n.input_size()));
  }
  float epsilon = 1e-5f;
  SFRT_ONNX_ASSIGN_OR_RETURN(epsilon, FloatAttr(idx, "epsilon", 1e-5f));
  const int64_t channels = op.in_shape[1];
  std::vector<float> v[4];  // scale, B, mean, var
  static const char* const kNames[4] = {"scale", "B", "mean", "var"};
  for (int k = 0; k < 4; ++k) {
    Dims dims;
    SFRT_ONNX_ASSIGN_OR_RETURN(v[k], GetFloats(idx, k + 1, &dims));
    if (static_cast<int64_t>(v[k].size()) != channels) {
      return NodeError(idx, std::string("input '") + kNames[k] + "' has " +
                                std::to_string(v[k].size()) + " values for " +
                                std::to_string(channels) + " channels");
    }
  }
  const long bad = BatchNormAffine(v[0], v[1], v[2], v[3], epsilon, &op.batch_norm);
  if (bad >= 0) {
    return NodeError(
        idx, "channel " + std::to_string(bad) + ": var + epsilon = " +
                 std::to_string(static_cast<double>(v[3][static_cast<size_t>(bad)]) + epsilon) +
                 " is not a positive number");
  }
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

// ONNX Clip (opsets 11-17): min and max as optional constant inputs 1 and 2, absent meaning
// unbounded. Clip(0, unbounded) is a ReLU (which fuses into the producing convolution).
Status Importer::ProcessClip(int idx, GraphOp& op) {
  const onnx::NodeProto& n = graph().node(idx);
  float bounds[2] = {-std::numeric_limits<float>::infinity(),
                     std::numeric_limits<float>::infinity()};
  for (int k = 1; k <= 2; ++k) {
    if (n.input_size() <= k || n.input(k).empty()) continue;
    Dims dims;
    std::vector<float> v;
    if (integer_io_type_ != 0) {  // the bounds have the integer graph's type
      SFRT_ONNX_ASSIGN_OR_RETURN(const Const c, GetConst(idx, k));
      if (c.type != integer_io_type_) {
        return NodeError(idx, "input " + std::to_string(k) + " " + Quote(n.input(k)) +
                                  " has element type " + TypeName(c.type) + ", expected " +
                                  TypeName(integer_io_type_) + " as the graph's input");
      }
      dims = c.dims;
      for (int64_t value : c.ints) v.push_back(static_cast<float>(value));
    } else {
      SFRT_ONNX_ASSIGN_OR_RETURN(v, GetFloats(idx, k, &dims));
    }
    if (v.size() != 1 || std::isnan(v[0])) {
      return NodeError(idx, std::string(k == 1 ? "min " : "max ") + Quote(n.input(k)) +
                                " must be one number; has shape " + JoinInts(dims));
    }
    bounds[k - 1] = v[0];
  }
  if (bounds[0] > bounds[1]) {
    return NodeError(idx,
                     "min " + FormatFloat(bounds[0]) + " is above max " + FormatFloat(bounds[1]));
  }
  if (bounds[0] == 0.0f && std::isinf(bounds[1])) {
    op.activation = Activation::kRelu;
    return Status::Ok();
  }
  op.activation = Activation::kClip;
  op.clip_min = bounds[0];
  op.clip_max = bounds[1];
  return Status::Ok();
}

// x + c, x - c, c - x, x * c and x / c for a constant c that varies at most along the channels
// (shapes that broadcast to [1, C, 1, 1]): out = x * scale[ch] + shift[ch]. x / c becomes
// x * (1 / c), within a rounding of the division.
Status Importer::ProcessElementwise(int idx, GraphOp& op) {
  const onnx::NodeProto& n = graph().node(idx);
  const std::string& type = n.op_type();
  const int slot = n.input(0) == op.inputs[0] ? 0 : 1;  // which input depends on the network's
  const int other = 1 - slot;
  Dims dims;
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<float> c, GetFloats(idx, other, &dims));
  const int64_t channels = op.in_shape[1];
  // Right-aligned against (N, C, H, W): every axis but C of size 1, C of size 1 or `channels`.
  bool per_channel = dims.size() <= 4;
  for (size_t k = 0; per_channel && k < dims.size(); ++k) {
    const size_t axis = 4 - dims.size() + k;
    per_channel = dims[k] == 1 || (axis == 1 && dims[k] == channels);
  }
  if (!per_channel || c.empty()) {
    return Unsupported(idx, "; the constant " + Quote(n.input(other)) + " has shape " +
                                JoinInts(dims) + ", which varies along more than the " +
                                std::to_string(channels) +
                                " channels (only per-channel constants are supported)");
  }
  if (type == "Div" && slot == 1) {
    return Unsupported(idx,
                       "; a constant divided by a tensor that depends on the network input "
                       "is not supported (only the tensor divided by a constant)");
  }
  ChannelAffine& a = op.batch_norm;
  a.scale.assign(static_cast<size_t>(channels), 1.0f);
  a.shift.assign(static_cast<size_t>(channels), 0.0f);
  for (size_t ch = 0; ch < a.scale.size(); ++ch) {
    const float v = c.size() == 1 ? c[0] : c[ch];
    if (type == "Mul") {
      a.scale[ch] = v;
    } else if (type == "Add") {
      a.shift[ch] = v;
    } else if (type == "Sub") {
      a.scale[ch] = slot == 0 ? 1.0f : -1.0f;
      a.shift[ch] = slot == 0 ? -v : v;
    } else {  // Div
      if (v == 0.0f || !std::isfinite(1.0f / v)) {
        return NodeError(idx, "divides by " + FormatFloat(v) + " (channel " + std::to_string(ch) +
                                  " of " + Quote(n.input(other)) + ")");
      }
      a.scale[ch] = 1.0f / v;
    }
    if (!std::isfinite(v)) {
      return NodeError(idx, "the constant " + Quote(n.input(other)) + " holds " + FormatFloat(v) +
                                " (channel " + std::to_string(ch) + ")");
    }
  }
  return Status::Ok();
}

Status Importer::ProcessMergeNode(int idx) {
  const onnx::NodeProto& n = graph().node(idx);
  const std::string& type = n.op_type();
  if (n.output_size() < 1 || n.output(0).empty()) return NodeError(idx, "has no output");
  GraphOp op;
  op.node_index = idx;
  op.output = n.output(0);
  for (int k = 0; k < n.input_size(); ++k) {
    const std::string& name = n.input(k);
    if (runtime_.count(name) == 0) {
      return Unsupported(
          idx, "; " + type + " of a tensor that depends on the network input and " +
                   (name.empty() ? std::string("an absent input") : "the constant " + Quote(name)) +
                   " is not supported (" + type +
                   " is only evaluated when all its inputs are constants, or "
                   "runs on tensors that all depend on the network input)");
    }
    op.inputs.push_back(name);
  }
  const Shape4& first = runtime_.at(op.inputs[0]);
  op.in_shape = first;
  op.out_shape = first;
  if (type == "Add") {
    op.kind = GraphOp::Kind::kAdd;
    if (op.inputs.size() != 2) {
      return NodeError(idx, "has " + std::to_string(op.inputs.size()) + " inputs; Add has 2");
    }
    const Shape4& second = runtime_.at(op.inputs[1]);
    if (second != first) {
      return NodeError(idx, "adds " + Quote(op.inputs[0]) + " of shape " + ShapeText(first) +
                                " and " + Quote(op.inputs[1]) + " of shape " + ShapeText(second) +
                                "; only tensors of the same shape are added (no broadcasting)");
    }
  } else {
    op.kind = GraphOp::Kind::kConcat;
    constexpr int64_t kNoAxis = std::numeric_limits<int64_t>::min();
    SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t axis_attr, IntAttr(idx, "axis", kNoAxis));
    if (axis_attr == kNoAxis) return NodeError(idx, "attribute 'axis' is missing");
    auto axis = NormalizeAxis(axis_attr, 4, "attribute 'axis'");
    if (!axis.ok()) return NodeError(idx, axis.message());
    if (*axis != 1) {
      return NodeError(idx, "concatenates along axis " + std::to_string(axis_attr) +
                                "; only the channel axis (1) is supported");
    }
    if (op.inputs.size() < 2) return NodeError(idx, "has fewer than 2 inputs");
    op.out_shape[1] = 0;
    for (const std::string& name : op.inputs) {
      const Shape4& s = runtime_.at(name);
      if (s[0] != first[0] || s[2] != first[2] || s[3] != first[3]) {
        return NodeError(idx, "concatenates " + Quote(op.inputs[0]) + " of shape " +
                                  ShapeText(first) + " and " + Quote(name) + " of shape " +
                                  ShapeText(s) + "; all must have the same height and width");
      }
      op.out_shape[1] += s[1];
    }
  }
  if (op.out_shape[1] > std::numeric_limits<int32_t>::max()) {
    return NodeError(idx, "output shape " + ShapeText(op.out_shape) + " is too large");
  }
  runtime_[op.output] = op.out_shape;
  producer_op_[op.output] = ops_.size();
  ops_.push_back(std::move(op));
  return Status::Ok();
}

Status Importer::CheckConvPads(int idx, const ConvSpec& conv,
                               const std::vector<int>& pad_nodes) const {
  const Pads& p = conv.pads;
  const int extent_h = DilatedExtent(conv.kernel_h, conv.dilation_h);
  const int extent_w = DilatedExtent(conv.kernel_w, conv.dilation_w);
  const int max_h = model_limits::MaxPad(extent_h);
  const int max_w = model_limits::MaxPad(extent_w);
  if (p.top <= max_h && p.bottom <= max_h && p.left <= max_w && p.right <= max_w) {
    return Status::Ok();
  }
  std::string folded;
  for (int pad : pad_nodes) folded += (folded.empty() ? "" : ", ") + NodeLabel(pad);
  return NodeError(idx, "attribute 'pads' = " + JoinInts({p.top, p.left, p.bottom, p.right}) +
                            (folded.empty() ? "" : " (with " + folded + " folded in)") +
                            " exceed the kernel's extent - 1 (at most " + std::to_string(max_h) +
                            " top/bottom, " + std::to_string(max_w) + " left/right for the " +
                            std::to_string(extent_h) + "x" + std::to_string(extent_w) + " kernel)");
}

// The needed ops: those the output depends on through runtime tensors (an op whose output only
// Shape or Size nodes read is not one).
std::vector<bool> Importer::NeededOps(const std::string& out_name) const {
  std::vector<bool> needed(ops_.size(), false);
  for (std::vector<std::string> stack{out_name}; !stack.empty();) {
    const std::string name = std::move(stack.back());
    stack.pop_back();
    if (name == input_name_) continue;
    const size_t i = producer_op_.at(name);
    if (needed[i]) continue;
    needed[i] = true;
    for (const std::string& in : ops_[i].inputs) stack.push_back(in);
  }
  return needed;
}

// torch.onnx.export names nodes by module path and op ("/conv0/Conv"): keep the module path,
// which is what the author called the layer ("conv0"); `prefix` and `counter` name a node without
// a name; a name taken gets a suffix.
std::string Importer::UniqueName(Assembly& a, const std::string& wanted, const std::string& prefix,
                                 int counter) {
  std::string readable = wanted;
  if (readable.size() > 1 && readable[0] == '/') {
    readable.erase(0, 1);
    const size_t last_slash = readable.rfind('/');
    if (last_slash != std::string::npos && last_slash > 0) readable.erase(last_slash);
  }
  std::string base = readable.empty() ? prefix + std::to_string(counter) : readable;
  std::string name = base;
  for (int k = 2; a.used_names.count(name) > 0; ++k) name = base + "_" + std::to_string(k);
  a.used_names.insert(name);
  return name;
}

void Importer::AddLayer(Assembly& a, LayerSpec layer, const std::string& output) {
  const std::string name = std::visit([](const auto& l) { return l.name; }, layer);
  a.source[output] = Source{name, static_cast<int>(a.spec.layers.size()), false, {}, {}, {}};
  a.spec.layers.push_back(std::move(layer));
}

std::vector<std::string> Importer::InputNames(const Assembly& a, const GraphOp& op) const {
  std::vector<std::string> names;
  for (const std::string& in : op.inputs) names.push_back(a.source.at(in).layer);
  return names;
}

// A Pad's output is folded into the Conv (or AveragePool, as torch.onnx.export writes an
// AvgPool2d that counts its pads) that reads it; nothing else may read it.
Status Importer::CheckPadReader(const Assembly& a, const GraphOp& op) const {
  // A Pad's output is folded into the Conv (or AveragePool, as torch.onnx.export writes an
  // AvgPool2d that counts its pads) that reads it; nothing else may read it.
  for (const std::string& in : op.inputs) {
    const Source& src = a.source.at(in);
    const bool average = op.kind == GraphOp::Kind::kPool && op.pool.kind == PoolKind::kAverage;
    if (src.padded && op.kind != GraphOp::Kind::kConv && op.kind != GraphOp::Kind::kPad &&
        !average) {
      return FileError(NodeLabel(src.pad_nodes.back()) +
                       ": a Pad must be followed by a Conv or an AveragePool (it is folded "
                       "into its padding), but it is followed by " +
                       NodeLabel(op.node_index));
    }
  }
  return Status::Ok();
}

// Identity: the tensor it reads.
Status Importer::LowerIdentity(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  a.source[op.output] = a.source.at(in0);
  return Status::Ok();
}

// Pad: amounts waiting for the Conv (or counting AveragePool) that reads its output.
Status Importer::LowerPad(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  Source padded = a.source.at(in0);
  if (!padded.padded) padded.pre_pad_shape = op.in_shape;
  padded.padded = true;
  padded.pads.top += op.pads.top;
  padded.pads.left += op.pads.left;
  padded.pads.bottom += op.pads.bottom;
  padded.pads.right += op.pads.right;
  padded.pad_nodes.push_back(op.node_index);
  a.source[op.output] = std::move(padded);
  return Status::Ok();
}

// Conv, with the Pads before it folded into its padding.
Status Importer::LowerConv(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  const Source& src = a.source.at(in0);
  ConvSpec conv = op.conv;
  const Shape4 traced_in = src.padded ? src.pre_pad_shape : op.in_shape;
  conv.pads.top += src.pads.top;
  conv.pads.left += src.pads.left;
  conv.pads.bottom += src.pads.bottom;
  conv.pads.right += src.pads.right;
  // A folded Pad's amounts are fixed: the sum holds at the traced size only.
  if (src.padded) conv.padding_rule = PaddingRule::kExplicit;
  SFRT_ONNX_RETURN_IF_ERROR(CheckConvPads(op.node_index, conv, src.pad_nodes));
  conv.name = UniqueName(a, conv.name, "conv", a.count.convs++);
  conv.inputs = {src.layer};
  a.convs.push_back({a.spec.layers.size(), op.node_index, traced_in[2], traced_in[3]});
  AddLayer(a, std::move(conv), op.output);
  return Status::Ok();
}

// MaxPool and AveragePool; an AveragePool counts the zeros of a Pad before it.
Status Importer::LowerPool(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  PoolSpec pool = op.pool;
  const Source& src = a.source.at(in0);
  if (src.padded) {
    // Zeros padded before an average: the pool's own pads, counted in the divisor. Its
    // size at the traced input must stay what the file computes after the Pad.
    if (pool.padding_rule != PaddingRule::kExplicit ||
        (pool.pads != Pads{} && !pool.count_include_pad)) {
      return FileError(NodeLabel(src.pad_nodes.back()) + ": a Pad before " +
                       NodeLabel(op.node_index) +
                       " folds into its pads only when it pads explicitly and counts them");
    }
    pool.pads.top += src.pads.top;
    pool.pads.left += src.pads.left;
    pool.pads.bottom += src.pads.bottom;
    pool.pads.right += src.pads.right;
    pool.count_include_pad = true;
    int before = 0, after = 0;
    const Shape4& pre = src.pre_pad_shape;
    const int extent_h = DilatedExtent(pool.kernel_h, pool.dilation_h);
    const int extent_w = DilatedExtent(pool.kernel_w, pool.dilation_w);
    const int oh =
        PoolOutputSize(static_cast<int>(pre[2]), extent_h, pool.stride_h, pool.padding_rule,
                       pool.pads.top, pool.pads.bottom, pool.ceil_mode, &before, &after);
    const int ow =
        PoolOutputSize(static_cast<int>(pre[3]), extent_w, pool.stride_w, pool.padding_rule,
                       pool.pads.left, pool.pads.right, pool.ceil_mode, &before, &after);
    const bool in_range = pool.pads.top < extent_h && pool.pads.bottom < extent_h &&
                          pool.pads.left < extent_w && pool.pads.right < extent_w;
    if (!in_range || oh != op.out_shape[2] || ow != op.out_shape[3]) {
      return FileError(NodeLabel(src.pad_nodes.back()) + ": the Pad before " +
                       NodeLabel(op.node_index) +
                       " cannot become the pool's own padding (pads below the window, the "
                       "same output size)");
    }
  }
  pool.name = UniqueName(a, pool.name, "pool", a.count.pools++);
  pool.inputs = {a.source.at(in0).layer};
  AddLayer(a, std::move(pool), op.output);
  return Status::Ok();
}

// ConvTranspose.
Status Importer::LowerConvTranspose(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  ConvTransposeSpec deconv = op.deconv;
  deconv.name = UniqueName(a, deconv.name, "deconv", a.count.deconvs++);
  deconv.inputs = {a.source.at(in0).layer};
  AddLayer(a, std::move(deconv), op.output);
  return Status::Ok();
}

// A scale and shift (BatchNormalization, Add/Sub/Mul/Div by a constant) folds into the Conv or
// ConvTranspose before it, or joins a ChannelAffine before it; an activation fuses into a Conv,
// ConvTranspose or Add (ReLU and LeakyReLU) or a ChannelAffine (any). The layer before must have
// no activation yet and be read by this node only (its output is then this node's). Otherwise the
// node becomes a ChannelAffine of its own (schema 1.7).
Status Importer::LowerScaleOrActivation(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  const bool scales = op.kind != GraphOp::Kind::kActivation;
  const Source& src = a.source.at(in0);
  const bool last_and_sole = src.layer_index >= 0 &&
                             src.layer_index == static_cast<int>(a.spec.layers.size()) - 1 &&
                             SoleReader(a, in0);
  LayerSpec* layer = last_and_sole ? &a.spec.layers[src.layer_index] : nullptr;
  auto* conv = layer != nullptr ? std::get_if<ConvSpec>(layer) : nullptr;
  auto* deconv = layer != nullptr ? std::get_if<ConvTransposeSpec>(layer) : nullptr;
  auto* add = layer != nullptr ? std::get_if<AddSpec>(layer) : nullptr;
  auto* affine = layer != nullptr ? std::get_if<ChannelAffineSpec>(layer) : nullptr;
  if (conv != nullptr && conv->activation != Activation::kNone) conv = nullptr;
  if (deconv != nullptr && deconv->activation != Activation::kNone) deconv = nullptr;
  if (add != nullptr && add->activation != Activation::kNone) add = nullptr;
  if (affine != nullptr && affine->activation != Activation::kNone) affine = nullptr;
  const bool fusable_activation =
      op.activation == Activation::kRelu || op.activation == Activation::kLeakyRelu;
  const float slope = op.activation == Activation::kLeakyRelu ? op.slope : 0.0f;
  auto activate = [&](ChannelAffineSpec& target) {
    target.activation = op.activation;
    target.leaky_slope = slope;
    target.elu_alpha = op.elu_alpha;
    target.clip_min = op.clip_min;
    target.clip_max = op.clip_max;
  };
  if (scales && conv != nullptr) {
    FoldIntoConv(op.batch_norm, conv);
  } else if (scales && deconv != nullptr) {
    FoldIntoConv(op.batch_norm, deconv);
  } else if (scales && affine != nullptr) {  // a * (x * s + t) + b
    for (size_t ch = 0; ch < affine->scale.size(); ++ch) {
      affine->scale[ch] *= op.batch_norm.scale[ch];
      affine->shift[ch] = affine->shift[ch] * op.batch_norm.scale[ch] + op.batch_norm.shift[ch];
    }
  } else if (!scales && fusable_activation && conv != nullptr) {
    conv->activation = op.activation;
    conv->leaky_slope = slope;
  } else if (!scales && fusable_activation && deconv != nullptr) {
    deconv->activation = op.activation;
    deconv->leaky_slope = slope;
  } else if (!scales && fusable_activation && add != nullptr) {
    add->activation = op.activation;
    add->leaky_slope = slope;
  } else if (!scales && affine != nullptr) {
    activate(*affine);
  } else {
    ChannelAffineSpec own;
    own.name = UniqueName(a, graph().node(op.node_index).name(), "affine", a.count.affines++);
    own.inputs = {src.layer};
    const size_t channels = static_cast<size_t>(op.in_shape[1]);
    own.scale = scales ? op.batch_norm.scale : std::vector<float>(channels, 1.0f);
    own.shift = scales ? op.batch_norm.shift : std::vector<float>(channels, 0.0f);
    if (!scales) activate(own);
    AddLayer(a, std::move(own), op.output);
    return Status::Ok();
  }
  a.source[op.output] = a.source.at(in0);
  return Status::Ok();
}

// Resize that is not nearest upsampling by integers.
Status Importer::LowerResize(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  ResizeSpec resize;
  resize.name = UniqueName(a, graph().node(op.node_index).name(), "resize", a.count.ups++);
  resize.params = op.resize;
  resize.inputs = {a.source.at(in0).layer};
  AddLayer(a, std::move(resize), op.output);
  return Status::Ok();
}

// Nearest upsampling by integer factors.
Status Importer::LowerUpsample(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  UpsampleSpec up;
  up.name = UniqueName(a, graph().node(op.node_index).name(), "up", a.count.ups++);
  up.factor_h = op.factor_h;
  up.factor_w = op.factor_w;
  up.inputs = {a.source.at(in0).layer};
  AddLayer(a, std::move(up), op.output);
  return Status::Ok();
}

// Slice: a crop; consecutive Slices merge into one.
Status Importer::LowerSlice(Assembly& a, const GraphOp& op) {
  const std::string& in0 = op.inputs[0];
  const Source& src = a.source.at(in0);
  const bool merge = !a.crops.empty() && a.crops.back().output == in0 && SoleReader(a, in0);
  if (merge) {  // consecutive slices become one crop
    auto& crop = std::get<CropSpec>(a.spec.layers[a.crops.back().layer]);
    crop.amounts.top += op.pads.top;
    crop.amounts.left += op.pads.left;
    crop.amounts.bottom += op.pads.bottom;
    crop.amounts.right += op.pads.right;
    a.crops.back().output = op.output;
    a.crops.back().out_h = op.out_shape[2];
    a.crops.back().out_w = op.out_shape[3];
    a.source[op.output] = src;
  } else {
    CropSpec crop;
    crop.name = UniqueName(a, graph().node(op.node_index).name(), "crop", a.count.crops++);
    crop.amounts = op.pads;
    crop.inputs = {src.layer};
    a.crops.push_back({a.spec.layers.size(), op.output, op.out_shape[2], op.out_shape[3]});
    AddLayer(a, std::move(crop), op.output);
  }
  return Status::Ok();
}

// Concat of channels.
Status Importer::LowerConcat(Assembly& a, const GraphOp& op) {
  ConcatSpec cat;
  cat.name = UniqueName(a, graph().node(op.node_index).name(), "concat", a.count.cats++);
  cat.inputs = InputNames(a, op);
  AddLayer(a, std::move(cat), op.output);
  return Status::Ok();
}

// Add of two runtime tensors.
Status Importer::LowerAdd(Assembly& a, const GraphOp& op) {
  AddSpec add;
  add.name = UniqueName(a, graph().node(op.node_index).name(), "add", a.count.adds++);
  add.inputs = InputNames(a, op);
  AddLayer(a, std::move(add), op.output);
  return Status::Ok();
}

// Each GraphOp kind is lowered to the spec by one member, indexed by GraphOp::Kind.
Importer::Lowering Importer::LoweringOf(GraphOp::Kind kind) {
  using K = GraphOp::Kind;
  static constexpr std::array<std::pair<K, Lowering>, 13> kLowerings = {{
      {K::kIdentity, &Importer::LowerIdentity},
      {K::kPad, &Importer::LowerPad},
      {K::kConv, &Importer::LowerConv},
      {K::kPool, &Importer::LowerPool},
      {K::kConvTranspose, &Importer::LowerConvTranspose},
      {K::kBatchNorm, &Importer::LowerScaleOrActivation},
      {K::kAffine, &Importer::LowerScaleOrActivation},
      {K::kActivation, &Importer::LowerScaleOrActivation},
      {K::kResize, &Importer::LowerResize},
      {K::kUpsample, &Importer::LowerUpsample},
      {K::kSlice, &Importer::LowerSlice},
      {K::kConcat, &Importer::LowerConcat},
      {K::kAdd, &Importer::LowerAdd},
  }};
  for (const auto& [k, lowering] : kLowerings) {
    if (k == kind) return lowering;
  }
  return nullptr;
}

// The output is the last layer, and the layer count within the loader's limit.
Status Importer::CheckAssembledOutput(const Assembly& a, const std::string& out_name) const {
  if (const Source& out = a.source.at(out_name); out.padded) {
    return FileError(NodeLabel(out.pad_nodes.back()) +
                     ": a Pad must be followed by a Conv (it is folded into the Conv's "
                     "padding), but it ends the graph");
  }
  if (a.spec.layers.empty()) return FileError("graph has no layers between input and output");
  if (a.spec.layers.size() > static_cast<size_t>(model_limits::kMaxLayers)) {
    return FileError("graph gives " + std::to_string(a.spec.layers.size()) + " layers; at most " +
                     std::to_string(model_limits::kMaxLayers) + " are supported");
  }
  // The graph output may be a fused layer's tensor that an earlier layer computes (an Identity
  // or activation of it); the spec's output is its last layer.
  if (a.source.at(out_name).layer_index != static_cast<int>(a.spec.layers.size()) - 1) {
    return FileError("graph output " + Quote(out_name) + " is computed by layer " +
                     Quote(a.source.at(out_name).layer) +
                     ", which is not the last: the network's output must be its last layer");
  }
  return Status::Ok();
}

// Padding rule: SAME_UPPER for every Conv when each one's traced pads are its SAME_UPPER amounts
// (--padding auto), else explicit.
Status Importer::ChoosePaddingRules(Assembly& a) const {
  bool all_same_upper = true;
  for (const ConvTrace& t : a.convs) {
    auto& conv = std::get<ConvSpec>(a.spec.layers[t.layer]);
    const Pads same =
        SameUpperPads(t.in_h, t.in_w, DilatedExtent(conv.kernel_h, conv.dilation_h),
                      DilatedExtent(conv.kernel_w, conv.dilation_w), conv.stride_h, conv.stride_w);
    if (conv.pads == same) continue;
    // A SAME_LOWER conv keeps its rule (kAuto) whatever the others do.
    if (conv.padding_rule == PaddingRule::kSameLower &&
        options_.padding == PaddingDetection::kAuto) {
      continue;
    }
    all_same_upper = false;
    if (options_.padding == PaddingDetection::kSameUpper) {
      return FileError("conv " + Quote(conv.name) + ": traced pads " + PadsText(conv.pads) +
                       " at input " + std::to_string(t.in_h) + "x" + std::to_string(t.in_w) +
                       " differ from the SAME_UPPER pads " + PadsText(same) +
                       "; cannot force padding rule SameUpper");
    }
  }
  const bool same_upper = options_.padding == PaddingDetection::kSameUpper ||
                          (options_.padding == PaddingDetection::kAuto && all_same_upper);
  for (const ConvTrace& t : a.convs) {
    auto& conv = std::get<ConvSpec>(a.spec.layers[t.layer]);
    if (conv.padding_rule == PaddingRule::kSameLower &&
        options_.padding == PaddingDetection::kAuto) {
      continue;
    }
    conv.padding_rule = same_upper ? PaddingRule::kSameUpper : PaddingRule::kExplicit;
  }
  return Status::Ok();
}

void Importer::ChooseCropRules(Assembly& a) const {
  // Crop rules (crop_rule.h): the skip a crop's only reader, a Concat, also reads at the crop's
  // size decides a crop to that layer's size.
  for (const CropTrace& t : a.crops) {
    auto& crop = std::get<CropSpec>(a.spec.layers[t.layer]);
    TracedCrop traced{static_cast<int>(t.out_h), static_cast<int>(t.out_w), ""};
    const auto& crop_readers = a.readers[t.output];
    if (crop_readers.size() == 1 && ops_[crop_readers[0]].kind == GraphOp::Kind::kConcat) {
      for (const std::string& in : ops_[crop_readers[0]].inputs) {
        const Source& other = a.source.at(in);
        const Shape4& shape = runtime_.at(in);
        if (in == t.output || other.padded || other.layer_index >= static_cast<int>(t.layer) ||
            shape[2] != t.out_h || shape[3] != t.out_w) {
          continue;
        }
        traced.skip = other.layer;
        break;
      }
    }
    ChooseCropRule(crop, traced, static_cast<int>(input_shape_[2]),
                   static_cast<int>(input_shape_[3]));
  }
}

Result<ModelSpec> Importer::Assemble() {
  const std::string& out_name = graph().output(output_index_).name();
  if (runtime_.count(out_name) == 0) {
    return FileError("graph output " + Quote(out_name) +
                     (IsConst(out_name) ? " is a constant: it does not depend on the input"
                                        : " is not produced by any node"));
  }
  const std::vector<bool> needed = NeededOps(out_name);
  SFRT_ONNX_RETURN_IF_ERROR(CheckIntegerGraph(needed));
  Assembly a;
  // The needed ops that read each runtime tensor (a Concat reading it twice counts once).
  for (size_t i = 0; i < ops_.size(); ++i) {
    if (!needed[i]) continue;
    for (const std::string& in : ops_[i].inputs) {
      auto& list = a.readers[in];
      if (list.empty() || list.back() != i) list.push_back(i);
    }
  }
  // The input's name is one a layer may read: no layer may take it.
  a.used_names.insert(input_name_);
  a.source[input_name_] = Source{input_name_, -1, false, {}, {}, {}};
  // The layers, in file order, which ONNX makes topological.
  for (size_t i = 0; i < ops_.size(); ++i) {
    if (!needed[i]) continue;
    SFRT_ONNX_RETURN_IF_ERROR(CheckPadReader(a, ops_[i]));
    SFRT_ONNX_RETURN_IF_ERROR((this->*LoweringOf(ops_[i].kind))(a, ops_[i]));
  }
  SFRT_ONNX_RETURN_IF_ERROR(CheckAssembledOutput(a, out_name));
  SFRT_ONNX_RETURN_IF_ERROR(ChoosePaddingRules(a));
  ChooseCropRules(a);

  const Shape4& out_shape = runtime_.at(out_name);
  a.spec.input.channels = static_cast<int>(input_shape_[1]);
  // The default image order (four RGB images) only fits 12 channels; for any other count the file
  // does not say which images the channels hold, so the spec names none (as the loader accepts).
  if (a.spec.input.channels != 3 * static_cast<int>(a.spec.input.image_order.size())) {
    a.spec.input.image_order.clear();
  }
  a.spec.input.traced_height = static_cast<int>(input_shape_[2]);
  a.spec.input.traced_width = static_cast<int>(input_shape_[3]);
  SetOutputChannels(a.spec, static_cast<int>(out_shape[1]));
  KeepInputNamesOfAGraph(a.spec, input_name_);
  return std::move(a.spec);
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

}  // namespace

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
