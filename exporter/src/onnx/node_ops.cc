// The ONNX nodes that read the network input, each turned into a GraphOp (Importer::RuntimeOps
// names the member for each op type): convolutions, poolings, Pad, Resize, Slice,
// BatchNormalization, Clip, Add/Sub/Mul/Div by a constant, and the merges (Concat, Add).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <set>
#include <string>
#include <vector>

#include "crop_rule.h"
#include "onnx/importer.h"

namespace sfrt::exporter::onnx_import {

namespace {

// Weights of shape (outputs, inputs, kh, kw) (ONNX Conv's OIHW, `outputs_first`) or (inputs,
// outputs, kh, kw) (ConvTranspose's IOHW) as HWIO (kh, kw, inputs, outputs).
std::vector<float> ToHwio(const std::vector<float>& w, int64_t inputs, int64_t outputs, int64_t kh,
                          int64_t kw, bool outputs_first) {
  std::vector<float> hwio(w.size());
  for (int64_t i = 0; i < inputs; ++i) {
    for (int64_t o = 0; o < outputs; ++o) {
      const int64_t plane = outputs_first ? o * inputs + i : i * outputs + o;
      for (int64_t ky = 0; ky < kh; ++ky) {
        for (int64_t kx = 0; kx < kw; ++kx) {
          hwio[static_cast<size_t>(((ky * kw + kx) * inputs + i) * outputs + o)] =
              w[static_cast<size_t>((plane * kh + ky) * kw + kx)];
        }
      }
    }
  }
  return hwio;
}

}  // namespace

// A ConvTranspose's pads (top, left, bottom, right) from its auto_pad, pads and output_shape
// attributes; where the asked-for size needs it, more output padding in `output_padding`. Each
// pad removes output rows or columns the kernel wrote, so each is below its kernel side.
Status Importer::ConvTransposePads(int idx, const GraphOp& op, std::array<int64_t, 2> kernel,
                                   const std::vector<int64_t>& dilations,
                                   const std::vector<int64_t>& strides,
                                   const std::vector<int64_t>& output_shape,
                                   std::vector<int64_t>* output_padding,
                                   std::vector<int64_t>* pads_out) {
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::string auto_pad, StringAttr(idx, "auto_pad", "NOTSET"));
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> pads, IntsAttr(idx, "pads"));
  std::vector<int64_t>& out_pad = *output_padding;
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
      const int64_t extent = (kernel[a] - 1) * dilations[a] + 1;
      const int64_t target = same ? in * strides[a] : output_shape[output_shape.size() - 2 + a];
      const int64_t total = (in - 1) * strides[a] + out_pad[a] + extent - target;
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
  const int64_t extent_h = (kernel[0] - 1) * dilations[0] + 1;
  const int64_t extent_w = (kernel[1] - 1) * dilations[1] + 1;
  const int64_t limits[4] = {extent_h, extent_w, extent_h, extent_w};
  for (size_t k = 0; k < 4; ++k) {
    if (pads[k] < 0 || pads[k] >= limits[k]) {
      return NodeError(idx, "attribute 'pads' = " + JoinInts(pads) +
                                " is not supported (each at least 0 and below its kernel side)");
    }
  }
  *pads_out = pads;
  return Status::Ok();
}

// A convolution's 'kernel_shape', when given, matches its weight's kernel sides.
Status Importer::CheckKernelShape(int idx, const Dims& wdims) {
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<int64_t> kernel_shape,
                             IntsAttr(idx, "kernel_shape"));
  if (!kernel_shape.empty() && kernel_shape != std::vector<int64_t>{wdims[2], wdims[3]}) {
    return NodeError(idx, "attribute 'kernel_shape' = " + JoinInts(kernel_shape) +
                              " does not match the weight shape " + JoinInts(wdims));
  }
  return Status::Ok();
}

// A convolution's bias: its third input, of shape [out_ch], or zeros when it has none.
Status Importer::ReadBias(int idx, int64_t out_ch, std::vector<float>* bias) {
  const onnx::NodeProto& n = graph().node(idx);
  bias->assign(static_cast<size_t>(out_ch), 0.0f);
  if (n.input_size() <= 2 || n.input(2).empty()) return Status::Ok();
  Dims bdims;
  SFRT_ONNX_ASSIGN_OR_RETURN(*bias, GetFloats(idx, 2, &bdims));
  if (bdims != Dims{out_ch}) {
    return NodeError(idx, "bias " + Quote(n.input(2)) + " has shape " + JoinInts(bdims) +
                              ", expected [" + std::to_string(out_ch) + "]");
  }
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
  if (Status s = CheckKernelShape(idx, wdims); !s.ok()) return s;
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> strides, IntsAttr(idx, "strides"));
  if (strides.empty()) strides = {1, 1};
  if (strides.size() != 2 || strides[0] < 1 || strides[1] < 1) {
    return NodeError(idx, "attribute 'strides' = " + JoinInts(strides) + " is not supported");
  }
  SFRT_ONNX_RETURN_IF_ERROR(CheckConvSizes(idx, op, wdims, group, strides));
  const int64_t in_h = op.in_shape[2];
  const int64_t in_w = op.in_shape[3];
  const int64_t extent_h = (kh - 1) * dilations[0] + 1;  // the window's rows
  const int64_t extent_w = (kw - 1) * dilations[1] + 1;
  Pads p;
  PaddingRule rule = PaddingRule::kExplicit;
  SFRT_ONNX_RETURN_IF_ERROR(ConvPads(idx, op, extent_h, extent_w, strides, &p, &rule));
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
  // OIHW with I the inputs per group -> HWIO with the same I: the output index stays global.
  c.weights_hwio = ToHwio(w, group_in, out_ch, kh, kw, /*outputs_first=*/true);
  return ReadBias(idx, out_ch, &c.bias);
}

// A Conv's channels against its input, and its kernel, stride and channels within
// model_limits.
Status Importer::CheckConvSizes(int idx, const GraphOp& op, const Dims& wdims, int64_t group,
                                const std::vector<int64_t>& strides) {
  const onnx::NodeProto& n = graph().node(idx);
  const int64_t out_ch = wdims[0], kh = wdims[2], kw = wdims[3];
  const int64_t in_ch = wdims[1] * group;
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
  return Status::Ok();
}

// A Conv's padding: 'pads' as given (auto_pad NOTSET), none (VALID), or SAME_UPPER/SAME_LOWER's
// for a window of extent_h x extent_w.
Status Importer::ConvPads(int idx, const GraphOp& op, int64_t extent_h, int64_t extent_w,
                          const std::vector<int64_t>& strides, Pads* out, PaddingRule* rule) {
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::string auto_pad, StringAttr(idx, "auto_pad", "NOTSET"));
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> pads, IntsAttr(idx, "pads"));
  Pads& p = *out;
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
    if (auto_pad == "SAME_LOWER") *rule = PaddingRule::kSameLower;
    p = SamePads(*rule, op.in_shape[2], op.in_shape[3], static_cast<int>(extent_h),
                 static_cast<int>(extent_w), static_cast<int>(strides[0]),
                 static_cast<int>(strides[1]));
  } else {
    return NodeError(idx, "attribute 'auto_pad' = " + Quote(auto_pad) +
                              " is not supported (NOTSET, SAME_UPPER, SAME_LOWER, VALID)");
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
  if (Status s = CheckKernelShape(idx, wdims); !s.ok()) return s;
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
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> output_shape, IntsAttr(idx, "output_shape"));
  std::vector<int64_t> pads;
  if (Status s =
          ConvTransposePads(idx, op, {kh, kw}, dilations, strides, output_shape, &out_pad, &pads);
      !s.ok()) {
    return s;
  }
  const int64_t extent_h = (kh - 1) * dilations[0] + 1;
  const int64_t extent_w = (kw - 1) * dilations[1] + 1;
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
  d.weights_hwio = ToHwio(w, in_ch, out_ch, kh, kw, /*outputs_first=*/false);
  return ReadBias(idx, out_ch, &d.bias);
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
  const bool is_resize = graph().node(idx).op_type() == "Resize";
  SFRT_ONNX_ASSIGN_OR_RETURN(const ResizeAttrs attrs, ReadResizeAttrs(idx, is_resize));
  std::vector<double> scales;
  std::vector<int64_t> sizes;
  SFRT_ONNX_RETURN_IF_ERROR(ReadResizeInputs(idx, is_resize, &scales, &sizes));
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
  if (attrs.mode == "nearest" && den[0] == 1 && den[1] == 1 &&
      NearestIsFloorOfQuotient(attrs.ctm, attrs.nearest_mode, num[0]) &&
      NearestIsFloorOfQuotient(attrs.ctm, attrs.nearest_mode, num[1])) {
    op.kind = GraphOp::Kind::kUpsample;
    op.factor_h = static_cast<int>(num[0]);
    op.factor_w = static_cast<int>(num[1]);
    return Status::Ok();
  }
  op.kind = GraphOp::Kind::kResize;
  SFRT_ONNX_RETURN_IF_ERROR(ResizeParamsOf(idx, attrs, op.resize));
  ResizeParams& r = op.resize;
  r.scale_num_h = num[0];
  r.scale_den_h = den[0];
  r.scale_num_w = num[1];
  r.scale_den_w = den[1];
  return Status::Ok();
}

// Resize's attributes (Upsample has only 'mode', and the rest as it behaves: asymmetric
// coordinates, in[floor(y / scale)]).
Result<Importer::ResizeAttrs> Importer::ReadResizeAttrs(int idx, bool is_resize) {
  ResizeAttrs a;
  SFRT_ONNX_ASSIGN_OR_RETURN(a.mode, StringAttr(idx, "mode", "nearest"));
  if (a.mode != "nearest" && a.mode != "linear" && a.mode != "cubic") {
    return NodeError(
        idx, "attribute 'mode' = " + Quote(a.mode) + " is not supported (nearest, linear, cubic)");
  }
  if (!is_resize) {
    if (a.mode == "cubic") {
      return NodeError(idx, "attribute 'mode' = 'cubic' is not an Upsample mode (nearest, linear)");
    }
    return a;
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(a.ctm,
                             StringAttr(idx, "coordinate_transformation_mode", "half_pixel"));
  SFRT_ONNX_ASSIGN_OR_RETURN(a.nearest_mode, StringAttr(idx, "nearest_mode", "round_prefer_floor"));
  SFRT_ONNX_ASSIGN_OR_RETURN(a.cubic_a, FloatAttr(idx, "cubic_coeff_a", -0.75f));
  SFRT_ONNX_ASSIGN_OR_RETURN(a.exclude_outside, IntAttr(idx, "exclude_outside", 0));
  SFRT_ONNX_ASSIGN_OR_RETURN(a.extrapolation_value, FloatAttr(idx, "extrapolation_value", 0.0f));
  return a;
}

// The scales or the sizes: Resize's inputs 2 and 3 (exactly one given); Upsample's input 1 or,
// before opset 9, its attribute 'scales'.
Status Importer::ReadResizeInputs(int idx, bool is_resize, std::vector<double>* scales,
                                  std::vector<int64_t>* sizes) {
  const onnx::NodeProto& n = graph().node(idx);
  if (is_resize) {
    SFRT_ONNX_ASSIGN_OR_RETURN(const std::optional<Const> s, GetOptionalConst(idx, 2));
    SFRT_ONNX_ASSIGN_OR_RETURN(const std::optional<Const> z, GetOptionalConst(idx, 3));
    if (s.has_value() && s->size() > 0) {
      for (size_t i = 0; i < s->size(); ++i) scales->push_back(s->Real(i));
    }
    if (z.has_value() && z->size() > 0) {
      if (z->is_real()) return NodeError(idx, "input 'sizes' must be integers");
      *sizes = z->ints;
    }
    if (scales->empty() == sizes->empty()) {
      return NodeError(idx, "exactly one of the inputs 'scales' and 'sizes' must be given");
    }
  } else if (n.input_size() > 1 && !n.input(1).empty()) {
    SFRT_ONNX_ASSIGN_OR_RETURN(const Const s, GetConst(idx, 1));
    for (size_t i = 0; i < s.size(); ++i) scales->push_back(s.Real(i));
  } else if (const auto* a = FindAttr(idx, "scales"); a != nullptr) {
    scales->assign(a->floats().begin(), a->floats().end());
  } else {
    return NodeError(idx, "no scales given");
  }
  return Status::Ok();
}

// A general resize's mode, coordinates, rounding and cubic parameters (not its scales).
Status Importer::ResizeParamsOf(int idx, const ResizeAttrs& a, ResizeParams& r) {
  r.mode = a.mode == "nearest"  ? ResizeMode::kNearest
           : a.mode == "linear" ? ResizeMode::kLinear
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
    if (a.ctm == name) {
      r.coordinates = value;
      known = true;
    }
  }
  if (!known) {
    return NodeError(idx, "attribute 'coordinate_transformation_mode' = " + Quote(a.ctm) +
                              " is not supported (half_pixel, pytorch_half_pixel, align_corners, "
                              "asymmetric, tf_half_pixel_for_nn, tf_crop_and_resize)");
  }
  if (r.coordinates == ResizeCoordinates::kTfCropAndResize) {
    SFRT_ONNX_RETURN_IF_ERROR(ResizeRegionOfInterest(idx, a.extrapolation_value, r));
  }
  static const std::pair<const char*, NearestRounding> kRounding[] = {
      {"round_prefer_floor", NearestRounding::kRoundPreferFloor},
      {"round_prefer_ceil", NearestRounding::kRoundPreferCeil},
      {"floor", NearestRounding::kFloor},
      {"ceil", NearestRounding::kCeil}};
  known = false;
  for (const auto& [name, value] : kRounding) {
    if (a.nearest_mode == name) {
      r.nearest = value;
      known = true;
    }
  }
  if (!known) {
    return NodeError(idx, "attribute 'nearest_mode' = " + Quote(a.nearest_mode) +
                              " is not supported (round_prefer_floor, round_prefer_ceil, floor, "
                              "ceil)");
  }
  if (!std::isfinite(a.cubic_a)) {
    return NodeError(idx,
                     "attribute 'cubic_coeff_a' = " + FormatDouble(a.cubic_a) + " is not finite");
  }
  r.cubic_coeff_a = a.cubic_a;
  r.exclude_outside = a.exclude_outside != 0;
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

}  // namespace sfrt::exporter::onnx_import
