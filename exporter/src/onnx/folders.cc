#include "onnx/folders.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace sfrt::exporter::onnx_import {

Status FoldCall::need(size_t count) const {
  for (size_t k = 0; k < count; ++k) {
    if (input(k) == nullptr) {
      return Status::Error("needs input " + std::to_string(k) + ", which is missing");
    }
  }
  return Status::Ok();
}

Result<std::vector<int64_t>> FoldCall::int_list(size_t k, const char* what) const {
  const Const* c = input(k);
  if (c == nullptr || c->is_real() || c->dims.size() > 1) {
    return Status::Error(std::string("input '") + what + "' must be a 1-D integer tensor");
  }
  return c->ints;
}

const onnx::AttributeProto* FindAttribute(const onnx::NodeProto& node, std::string_view name) {
  for (const auto& a : node.attribute()) {
    if (a.name() == name) return &a;
  }
  return nullptr;
}

Result<int64_t> IntAttribute(const onnx::NodeProto& node, std::string_view name, int64_t fallback) {
  const auto* a = FindAttribute(node, name);
  if (a == nullptr) return fallback;
  if (a->type() != onnx::AttributeProto::INT) {
    return Status::Error("attribute '" + std::string(name) + "' is not an integer");
  }
  return a->i();
}

Result<std::vector<int64_t>> IntsAttribute(const onnx::NodeProto& node, std::string_view name) {
  const auto* a = FindAttribute(node, name);
  if (a == nullptr) return std::vector<int64_t>{};
  if (a->type() != onnx::AttributeProto::INTS) {
    return Status::Error("attribute '" + std::string(name) + "' is not a list of integers");
  }
  return std::vector<int64_t>(a->ints().begin(), a->ints().end());
}

namespace {

// ----------------------------------------------------------------- the shapes of the folders

template <typename RealFn, typename IntFn>
Result<Const> Binary(FoldCall& c, RealFn real_fn, IntFn int_fn) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(2));
  return Elementwise(c.budget, *c.input(0), *c.input(1),
                     PromoteTypes(c.input(0)->type, c.input(1)->type), real_fn, int_fn);
}

// A logical comparison: true where fn holds (values compared as doubles).
template <typename Fn>
Result<Const> Logical(FoldCall& c, Fn fn) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(2));
  return Elementwise(
      c.budget, *c.input(0), *c.input(1), TensorProto::BOOL,
      [&](double x, double y) { return fn(x, y) ? 1.0 : 0.0; },
      [&](int64_t x, int64_t y) -> Result<int64_t> {
        return fn(static_cast<double>(x), static_cast<double>(y)) ? 1 : 0;
      });
}

// A comparison, exact for int64 values.
template <typename Fn>
Result<Const> Compare(FoldCall& c, Fn fn) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(2));
  return Elementwise(
      c.budget, *c.input(0), *c.input(1), TensorProto::BOOL,
      [&](double x, double y) { return fn(x, y) ? 1.0 : 0.0; },
      [&](int64_t x, int64_t y) -> Result<int64_t> { return fn(x, y) ? 1 : 0; });
}

template <typename RealFn, typename IntFn>
Result<Const> Unary(FoldCall& c, RealFn real_fn, IntFn int_fn) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(1));
  Const out = c.take(0);
  for (size_t i = 0; i < out.size(); ++i) {
    if (out.is_real()) {
      out.Set(i, real_fn(out.reals[i]));
    } else {
      out.SetInt(i, int_fn(out.ints[i]));
    }
  }
  return out;
}

// ----------------------------------------------------------------- shapes and data movement

Result<Const> FoldShape(FoldCall& c) {
  const Dims& shape = c.shape;
  Const out;
  out.type = TensorProto::INT64;
  if (c.node.op_type() == "Size") {
    int64_t count = 1;
    for (int64_t d : shape) count *= d;
    out.ints = {count};
    return out;
  }
  const auto rank = static_cast<int64_t>(shape.size());
  SFRT_ONNX_ASSIGN_OR_RETURN(int64_t start, IntAttribute(c.node, "start", 0));
  SFRT_ONNX_ASSIGN_OR_RETURN(int64_t end, IntAttribute(c.node, "end", rank));
  if (start < 0) start += rank;
  if (end < 0) end += rank;
  start = std::clamp<int64_t>(start, 0, rank);
  end = std::clamp<int64_t>(end, start, rank);
  out.ints.assign(shape.begin() + start, shape.begin() + end);
  out.dims = {end - start};
  return out;
}

Result<Const> FoldIdentity(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(1));
  return c.take(0);
}

Result<Const> FoldCast(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(1));
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t to, IntAttribute(c.node, "to", -1));
  return Cast(c.budget, *c.input(0), static_cast<int>(to));
}

Result<Const> FoldCastLike(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(2));
  return Cast(c.budget, *c.input(0), c.input(1)->type);
}

Result<Const> FoldConcat(FoldCall& c) {
  std::vector<const Const*> parts;
  for (size_t k = 0; k < c.in.size(); ++k) {
    if (c.input(k) != nullptr) parts.push_back(c.input(k));
  }
  if (FindAttribute(c.node, "axis") == nullptr) {
    return Status::Error("attribute 'axis' is missing");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t axis, IntAttribute(c.node, "axis", 0));
  return Concat(c.budget, parts, axis);
}

Result<Const> FoldGather(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(2));
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t axis, IntAttribute(c.node, "axis", 0));
  return Gather(c.budget, *c.input(0), *c.input(1), axis);
}

// Unsqueeze and Squeeze: their axes are an input from opset 13, an attribute before.
Result<Const> FoldSqueezing(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(1));
  std::vector<int64_t> axes;
  bool have_axes = false;
  if (c.opset >= 13) {
    if (c.input(1) != nullptr) {
      SFRT_ONNX_ASSIGN_OR_RETURN(axes, c.int_list(1, "axes"));
      have_axes = true;
    }
  } else {
    SFRT_ONNX_ASSIGN_OR_RETURN(axes, IntsAttribute(c.node, "axes"));
    have_axes = FindAttribute(c.node, "axes") != nullptr;
  }
  if (c.node.op_type() == "Squeeze") return Squeeze(c.take(0), axes, have_axes);
  if (!have_axes) return Status::Error("axes are missing");
  return Unsqueeze(c.take(0), axes);
}

Result<Const> FoldReshape(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(2));
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t allow_zero, IntAttribute(c.node, "allowzero", 0));
  return Reshape(c.take(0), *c.input(1), allow_zero != 0);
}

Result<Const> FoldExpand(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(2));
  return Expand(c.budget, *c.input(0), *c.input(1));
}

Result<Const> FoldTile(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(2));
  return Tile(c.budget, *c.input(0), *c.input(1));
}

Result<Const> FoldTranspose(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(1));
  SFRT_ONNX_ASSIGN_OR_RETURN(std::vector<int64_t> perm, IntsAttribute(c.node, "perm"));
  return Transpose(c.budget, *c.input(0), std::move(perm));
}

Result<Const> FoldSlice(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(3));
  SFRT_ONNX_ASSIGN_OR_RETURN(const SliceArgs args,
                             ReadSliceArgs(c.input(1), c.input(2), c.input(3), c.input(4),
                                           static_cast<int64_t>(c.input(0)->dims.size())));
  return SliceConst(c.budget, *c.input(0), args);
}

Result<Const> FoldRange(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(3));
  return Range(c.budget, *c.input(0), *c.input(1), *c.input(2));
}

Result<Const> FoldConstantOfShape(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(1));
  SFRT_ONNX_ASSIGN_OR_RETURN(const std::vector<int64_t> shape, c.int_list(0, "input"));
  Const value;
  value.type = TensorProto::FLOAT;
  value.reals = {0.0};
  if (const auto* a = FindAttribute(c.node, "value"); a != nullptr) {
    if (a->type() != onnx::AttributeProto::TENSOR) {
      return Status::Error("attribute 'value' is not a tensor");
    }
    SFRT_ONNX_ASSIGN_OR_RETURN(value, DecodeTensor(a->t(), "attribute 'value'", c.budget));
    if (value.size() != 1) return Status::Error("attribute 'value' must hold one element");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(Const made, MakeConst(c.budget, value.type, shape));
  for (size_t i = 0; i < made.size(); ++i) CopyElement(value, 0, made, i);
  return made;
}

Result<Const> FoldWhere(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(3));
  const Const& cond = *c.input(0);
  const Const& x = *c.input(1);
  const Const& y = *c.input(2);
  SFRT_ONNX_ASSIGN_OR_RETURN(const Dims dims, BroadcastDims({&cond.dims, &x.dims, &y.dims}));
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(c.budget, PromoteTypes(x.type, y.type), dims));
  for (size_t i = 0; i < out.size(); ++i) {
    const bool pick_x = cond.Real(SourceIndex(i, dims, cond.dims)) != 0.0;
    const Const& src = pick_x ? x : y;
    CopyElement(src, SourceIndex(i, dims, src.dims), out, i);
  }
  return out;
}

// ----------------------------------------------------------------- arithmetic

Result<Const> FoldAdd(FoldCall& c) {
  return Binary(
      c, [](double x, double y) { return x + y; },
      [](int64_t x, int64_t y) { return IntOk(WrapAdd(x, y)); });
}

Result<Const> FoldSub(FoldCall& c) {
  return Binary(
      c, [](double x, double y) { return x - y; },
      [](int64_t x, int64_t y) { return IntOk(WrapSub(x, y)); });
}

Result<Const> FoldMul(FoldCall& c) {
  return Binary(
      c, [](double x, double y) { return x * y; },
      [](int64_t x, int64_t y) { return IntOk(WrapMul(x, y)); });
}

Result<Const> FoldDiv(FoldCall& c) {
  return Binary(
      c, [](double x, double y) { return x / y; },
      [](int64_t x, int64_t y) -> Result<int64_t> {
        if (y == 0) return Status::Error("integer division by zero");
        if (y == -1) return WrapSub(0, x);
        return x / y;  // truncates, as ONNX runtimes do
      });
}

Result<Const> FoldMod(FoldCall& c) {
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t fmod, IntAttribute(c.node, "fmod", 0));
  return Binary(
      c,
      [fmod](double x, double y) {
        const double r = std::fmod(x, y);
        return (fmod == 0 && r != 0.0 && ((r < 0) != (y < 0))) ? r + y : r;
      },
      [fmod](int64_t x, int64_t y) -> Result<int64_t> {
        if (y == 0) return Status::Error("integer modulo by zero");
        const int64_t r = y == -1 ? 0 : x % y;
        return (fmod == 0 && r != 0 && ((r < 0) != (y < 0))) ? r + y : r;
      });
}

Result<Const> FoldPow(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(2));
  return Elementwise(
      c.budget, *c.input(0), *c.input(1), c.input(0)->type,
      [](double x, double y) { return std::pow(x, y); },
      [](int64_t x, int64_t y) -> Result<int64_t> {
        return ToInt64(std::round(std::pow(static_cast<double>(x), static_cast<double>(y))));
      });
}

// Min and Max: of any number of inputs, broadcast.
Result<Const> FoldMinMax(FoldCall& c) {
  const bool is_min = c.node.op_type() == "Min";
  std::optional<Const> acc;
  for (size_t k = 0; k < c.in.size(); ++k) {
    if (c.input(k) == nullptr) continue;
    if (!acc.has_value()) {
      acc = c.take(k);
      continue;
    }
    SFRT_ONNX_ASSIGN_OR_RETURN(
        acc, Elementwise(
                 c.budget, *acc, *c.input(k), PromoteTypes(acc->type, c.input(k)->type),
                 [is_min](double x, double y) { return is_min ? std::min(x, y) : std::max(x, y); },
                 [is_min](int64_t x, int64_t y) {
                   return IntOk(is_min ? std::min(x, y) : std::max(x, y));
                 }));
  }
  if (!acc.has_value()) return Status::Error("has no inputs");
  return std::move(*acc);
}

Result<Const> FoldClip(FoldCall& c) {
  SFRT_ONNX_RETURN_IF_ERROR(c.need(1));
  const Const* lo = c.input(1);
  const Const* hi = c.input(2);
  if ((lo != nullptr && lo->size() != 1) || (hi != nullptr && hi->size() != 1)) {
    return Status::Error("inputs 'min' and 'max' must be scalars");
  }
  Const out = c.take(0);
  for (size_t i = 0; i < out.size(); ++i) {
    if (out.is_real()) {
      double v = out.reals[i];
      if (lo != nullptr) v = std::max(v, lo->Real(0));
      if (hi != nullptr) v = std::min(v, hi->Real(0));
      out.Set(i, v);
    } else {
      int64_t v = out.ints[i];
      if (lo != nullptr) v = std::max(v, lo->Int(0));
      if (hi != nullptr) v = std::min(v, hi->Int(0));
      out.SetInt(i, v);
    }
  }
  return out;
}

// The folders the table names are made from these shapes; each entry says which and with what.
// clang-format off
constexpr std::array kFolders = {
    ConstantFolder{"Constant", nullptr},
    ConstantFolder{"Shape", FoldShape, true},
    ConstantFolder{"Size", FoldShape, true},
    ConstantFolder{"Gather", FoldGather},
    ConstantFolder{"Cast", FoldCast},
    ConstantFolder{"CastLike", FoldCastLike},
    ConstantFolder{"Concat", FoldConcat},
    ConstantFolder{"Unsqueeze", FoldSqueezing},
    ConstantFolder{"Squeeze", FoldSqueezing},
    ConstantFolder{"Slice", FoldSlice},
    ConstantFolder{"Reshape", FoldReshape},
    ConstantFolder{"Expand", FoldExpand},
    ConstantFolder{"Transpose", FoldTranspose},
    ConstantFolder{"Tile", FoldTile},
    ConstantFolder{"Range", FoldRange},
    ConstantFolder{"ConstantOfShape", FoldConstantOfShape},
    ConstantFolder{"Identity", FoldIdentity},
    ConstantFolder{"Add", FoldAdd},
    ConstantFolder{"Sub", FoldSub},
    ConstantFolder{"Mul", FoldMul},
    ConstantFolder{"Div", FoldDiv},
    ConstantFolder{"Mod", FoldMod},
    ConstantFolder{"Pow", FoldPow},
    ConstantFolder{"Neg", [](FoldCall& c) {
      return Unary(c, [](double x) { return -x; }, [](int64_t x) { return WrapSub(0, x); }); }},
    ConstantFolder{"Abs", [](FoldCall& c) {
      return Unary(c, [](double x) { return std::fabs(x); },
                   [](int64_t x) { return x < 0 ? WrapSub(0, x) : x; }); }},
    ConstantFolder{"Floor", [](FoldCall& c) {
      return Unary(c, [](double x) { return std::floor(x); }, [](int64_t x) { return x; }); }},
    ConstantFolder{"Ceil", [](FoldCall& c) {
      return Unary(c, [](double x) { return std::ceil(x); }, [](int64_t x) { return x; }); }},
    ConstantFolder{"Round", [](FoldCall& c) {  // half to even
      return Unary(c, [](double x) { return std::nearbyint(x); }, [](int64_t x) { return x; }); }},
    ConstantFolder{"Sqrt", [](FoldCall& c) {
      return Unary(c, [](double x) { return std::sqrt(x); },
                   [](int64_t x) { return ToInt64(std::sqrt(static_cast<double>(x))); }); }},
    ConstantFolder{"Reciprocal", [](FoldCall& c) {
      return Unary(c, [](double x) { return 1.0 / x; },
                   [](int64_t x) -> int64_t { return x == 0 ? 0 : 1 / x; }); }},
    ConstantFolder{"Sign", [](FoldCall& c) {
      return Unary(c, [](double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); },
                   [](int64_t x) -> int64_t { return x > 0 ? 1 : (x < 0 ? -1 : 0); }); }},
    ConstantFolder{"Min", FoldMinMax},
    ConstantFolder{"Max", FoldMinMax},
    ConstantFolder{"Clip", FoldClip},
    ConstantFolder{"Equal", [](FoldCall& c) {
      return Compare(c, [](auto x, auto y) { return x == y; }); }},
    ConstantFolder{"Less", [](FoldCall& c) {
      return Compare(c, [](auto x, auto y) { return x < y; }); }},
    ConstantFolder{"Greater", [](FoldCall& c) {
      return Compare(c, [](auto x, auto y) { return x > y; }); }},
    ConstantFolder{"LessOrEqual", [](FoldCall& c) {
      return Compare(c, [](auto x, auto y) { return x <= y; }); }},
    ConstantFolder{"GreaterOrEqual", [](FoldCall& c) {
      return Compare(c, [](auto x, auto y) { return x >= y; }); }},
    ConstantFolder{"And", [](FoldCall& c) {
      return Logical(c, [](double x, double y) { return x != 0 && y != 0; }); }},
    ConstantFolder{"Or", [](FoldCall& c) {
      return Logical(c, [](double x, double y) { return x != 0 || y != 0; }); }},
    ConstantFolder{"Xor", [](FoldCall& c) {
      return Logical(c, [](double x, double y) { return (x != 0) != (y != 0); }); }},
    ConstantFolder{"Not", [](FoldCall& c) {
      return Unary(c, [](double x) { return x == 0 ? 1.0 : 0.0; },
                   [](int64_t x) -> int64_t { return x == 0 ? 1 : 0; }); }},
    ConstantFolder{"Where", FoldWhere},
};
// clang-format on

}  // namespace

const ConstantFolder* FindFolder(std::string_view op) {
  for (const ConstantFolder& f : kFolders) {
    if (f.op == op) return &f;
  }
  return nullptr;
}

std::span<const ConstantFolder> ConstantFolders() { return kFolders; }

}  // namespace sfrt::exporter::onnx_import
