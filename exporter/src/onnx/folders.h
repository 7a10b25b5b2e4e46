// The ONNX ops the importer evaluates when every input of a node is a constant (shape arithmetic,
// the constant subgraphs exporters write), registered by op type name in one table, as the
// runtime's layer kinds are (runtime/src/ops/registry.cc): one folder per op, no chain of name
// comparisons. Errors are bare details; the importer names the node.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "onnx/const_tensors.h"

namespace sfrt::exporter::onnx_import {

// One node being folded: its inputs (an absent optional input is empty) and, for Shape and Size,
// the static shape of input 0, which a tensor that depends on the network input has too.
struct FoldCall {
  const onnx::NodeProto& node;
  int64_t opset;
  ConstantBudget& budget;
  std::vector<std::optional<Const>> in;
  Dims shape;

  const Const* input(size_t k) const { return k < in.size() && in[k] ? &*in[k] : nullptr; }
  // Input k itself, moved out (call need() first): for ops whose result keeps its input's values,
  // so that they cost no copy.
  Const take(size_t k) { return std::move(*in[k]); }
  // Inputs 0..count-1 are present.
  Status need(size_t count) const;
  // Input k as a 1-D integer list (`what` names it in the error).
  Result<std::vector<int64_t>> int_list(size_t k, const char* what) const;
};

// Attributes of a node; errors are bare ("attribute 'axis' is not an integer").
const onnx::AttributeProto* FindAttribute(const onnx::NodeProto& node, std::string_view name);
Result<int64_t> IntAttribute(const onnx::NodeProto& node, std::string_view name, int64_t fallback);
Result<std::vector<int64_t>> IntsAttribute(const onnx::NodeProto& node, std::string_view name);

struct ConstantFolder {
  std::string_view op;
  // Null for Constant, which the importer reads itself.
  Result<Const> (*fold)(FoldCall& call);
  // Shape and Size: reads only input 0's static shape (FoldCall::shape), not its values.
  bool reads_shape_only = false;
};

// The folder of `op`; null when the importer cannot evaluate it.
const ConstantFolder* FindFolder(std::string_view op);
// Every folder, in the order `sfrt export` lists them.
std::span<const ConstantFolder> ConstantFolders();

}  // namespace sfrt::exporter::onnx_import
