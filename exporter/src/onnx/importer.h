// The ONNX importer's inside (onnx_importer.cc reads and walks the graph, onnx/node_ops.cc turns
// the nodes that read the network input into GraphOps, onnx/assemble.cc lowers those to the
// spec): the GraphOp, the Importer class, and the helpers they share. Not an API.
#pragma once

// onnx_pb.h defines ONNX_API and then includes onnx-ml.pb.h (ONNX_ML=1).
#include <onnx/onnx_pb.h>

#include <array>
#include <cstdint>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "batch_norm_fold.h"
#include "message_text.h"
#include "onnx/const_tensors.h"
#include "onnx/folders.h"
#include "sfrt/exporter/onnx_importer.h"
#include "sfrt/model_limits.h"
#include "sfrt/shapes.h"

namespace sfrt::exporter::onnx_import {

using Shape4 = std::array<int64_t, 4>;  // N, C, H, W

constexpr int64_t kMinOpset = 11;

constexpr int64_t kMaxOpset = 17;

// Unsupported nodes named in one message; the rest are counted (a screenful at most).
constexpr size_t kMaxListedNodes = 20;

std::string PadsText(const Pads& p);

std::string ShapeText(const Shape4& s);

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
bool NearestIsFloorOfQuotient(const std::string& ctm, const std::string& nearest_mode, int64_t f);

// TensorFlow 'same' / ONNX SAME_UPPER amounts for one axis.
std::pair<int, int> SameUpperAxis(int64_t in, int64_t stride, int64_t kernel);

Pads SameUpperPads(int64_t in_h, int64_t in_w, int kh, int kw, int sh, int sw);

// ONNX SAME_UPPER or SAME_LOWER amounts: the same totals, SAME_LOWER's larger half first.
Pads SamePads(PaddingRule rule, int64_t in_h, int64_t in_w, int kh, int kw, int sh, int sw);

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
  Status CheckConvSizes(int idx, const GraphOp& op, const Dims& wdims, int64_t group,
                        const std::vector<int64_t>& strides);
  Status ConvPads(int idx, const GraphOp& op, int64_t extent_h, int64_t extent_w,
                  const std::vector<int64_t>& strides, Pads* out, PaddingRule* rule);
  Status ProcessConvTranspose(int idx, GraphOp& op);
  Status ConvTransposePads(int idx, const GraphOp& op, std::array<int64_t, 2> kernel,
                           const std::vector<int64_t>& dilations,
                           const std::vector<int64_t>& strides,
                           const std::vector<int64_t>& output_shape,
                           std::vector<int64_t>* output_padding, std::vector<int64_t>* pads);
  Status CheckKernelShape(int idx, const Dims& wdims);
  Status ReadBias(int idx, int64_t out_ch, std::vector<float>* bias);
  Status ProcessPool(int idx, GraphOp& op);
  Status ProcessPad(int idx, GraphOp& op);
  Status ProcessBatchNorm(int idx, GraphOp& op);
  Status ProcessResize(int idx, GraphOp& op);
  // Resize's (Upsample's) attributes as given.
  struct ResizeAttrs {
    std::string mode;
    std::string ctm = "asymmetric";
    std::string nearest_mode = "floor";  // Upsample: in[floor(y / scale)]
    float cubic_a = -0.75f;
    int64_t exclude_outside = 0;
    float extrapolation_value = 0.0f;
  };
  Result<ResizeAttrs> ReadResizeAttrs(int idx, bool is_resize);
  Status ReadResizeInputs(int idx, bool is_resize, std::vector<double>* scales,
                          std::vector<int64_t>* sizes);
  Status ResizeParamsOf(int idx, const ResizeAttrs& a, ResizeParams& r);
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

}  // namespace sfrt::exporter::onnx_import
