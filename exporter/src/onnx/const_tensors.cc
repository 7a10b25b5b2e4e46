#include "onnx/const_tensors.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

namespace sfrt::exporter::onnx_import {

std::string FormatFloat(float v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", static_cast<double>(v));
  return buf;
}

std::string JoinInts(const std::vector<int64_t>& values) {
  std::string s = "[";
  for (size_t i = 0; i < values.size() && i < kMaxListedValues; ++i) {
    if (i > 0) s += ", ";
    s += std::to_string(values[i]);
  }
  if (values.size() > kMaxListedValues) s += ", ... (" + std::to_string(values.size()) + " values)";
  return s + "]";
}

std::string FormatDouble(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

std::string JoinReals(const std::vector<double>& values) {
  std::string s = "[";
  for (size_t i = 0; i < values.size() && i < kMaxListedValues; ++i) {
    if (i > 0) s += ", ";
    s += FormatDouble(values[i]);
  }
  if (values.size() > kMaxListedValues) s += ", ... (" + std::to_string(values.size()) + " values)";
  return s + "]";
}

bool IsReal(int type) { return type == TensorProto::FLOAT || type == TensorProto::DOUBLE; }

bool IsSmallInteger(int type) {
  return type == TensorProto::INT8 || type == TensorProto::UINT8 || type == TensorProto::INT16 ||
         type == TensorProto::UINT16;
}

bool IsSupportedType(int type) {
  return type == TensorProto::FLOAT || type == TensorProto::DOUBLE || type == TensorProto::INT64 ||
         type == TensorProto::INT32 || type == TensorProto::BOOL || IsSmallInteger(type);
}

std::string TypeName(int type) {
  if (TensorProto::DataType_IsValid(type)) {
    return TensorProto::DataType_Name(static_cast<TensorProto::DataType>(type));
  }
  return "data type " + std::to_string(type);
}

double RoundToType(int type, double v) {
  return type == TensorProto::FLOAT ? static_cast<double>(static_cast<float>(v)) : v;
}

int64_t ToInt64(double v) {
  if (std::isnan(v)) return 0;
  if (v >= 9223372036854775807.0) return std::numeric_limits<int64_t>::max();
  if (v <= -9223372036854775808.0) return std::numeric_limits<int64_t>::min();
  return static_cast<int64_t>(v);
}

int64_t WrapAdd(int64_t a, int64_t b) {
  return static_cast<int64_t>(static_cast<uint64_t>(a) + static_cast<uint64_t>(b));
}

int64_t WrapSub(int64_t a, int64_t b) {
  return static_cast<int64_t>(static_cast<uint64_t>(a) - static_cast<uint64_t>(b));
}

int64_t WrapMul(int64_t a, int64_t b) {
  return static_cast<int64_t>(static_cast<uint64_t>(a) * static_cast<uint64_t>(b));
}

int64_t WrapToType(int type, int64_t v) {
  if (type == TensorProto::INT32) return static_cast<int32_t>(v);
  if (type == TensorProto::BOOL) return v != 0 ? 1 : 0;
  return v;
}

Result<int64_t> NumElements(const Dims& dims) {
  int64_t n = 1;
  for (int64_t d : dims) {
    if (d < 0) return Status::Error("negative dimension " + std::to_string(d));
    if (d != 0 && n > kMaxFoldedElements * 64 / d) {
      return Status::Error("tensor of shape " + JoinInts(dims) + " is too large");
    }
    n *= d;
  }
  return n;
}

Result<Const> MakeConst(ConstantBudget& budget, int type, Dims dims) {
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t n, NumElements(dims));
  if (n > kMaxFoldedElements) {
    return Status::Error("a constant of shape " + JoinInts(dims) + " is too large to evaluate");
  }
  SFRT_ONNX_RETURN_IF_ERROR(budget.Take(static_cast<size_t>(n), kConstValueBytes,
                                        "a constant of shape " + JoinInts(dims)));
  Const c;
  c.type = type;
  c.dims = std::move(dims);
  if (c.is_real()) {
    c.reals.assign(static_cast<size_t>(n), 0.0);
  } else {
    c.ints.assign(static_cast<size_t>(n), 0);
  }
  return c;
}

void CopyElement(const Const& src, size_t si, Const& dst, size_t di) {
  if (src.is_real()) {
    dst.Set(di, src.reals[si]);
  } else {
    dst.SetInt(di, src.ints[si]);
  }
}

size_t RawWidth(int type) {
  switch (type) {
    case TensorProto::DOUBLE:
    case TensorProto::INT64:
      return 8;
    case TensorProto::FLOAT:
    case TensorProto::INT32:
      return 4;
    case TensorProto::INT16:
    case TensorProto::UINT16:
      return 2;
    default:  // INT8, UINT8, BOOL
      return 1;
  }
}

size_t HeldValues(const TensorProto& t) {
  if (t.has_raw_data()) return t.raw_data().size() / RawWidth(t.data_type());
  switch (t.data_type()) {
    case TensorProto::FLOAT:
      return static_cast<size_t>(t.float_data_size());
    case TensorProto::DOUBLE:
      return static_cast<size_t>(t.double_data_size());
    case TensorProto::INT64:
      return static_cast<size_t>(t.int64_data_size());
    default:
      return static_cast<size_t>(t.int32_data_size());
  }
}

Result<Const> DecodeTensor(const TensorProto& t, const std::string& what, ConstantBudget& budget) {
  if (t.data_location() == TensorProto::EXTERNAL) {
    return Status::Error(what +
                         " uses external data, which is not supported (re-export with the "
                         "weights inside the .onnx file)");
  }
  if (!IsSupportedType(t.data_type())) {
    return Status::Error(
        what + " has unsupported element type " + TypeName(t.data_type()) +
        " (supported: FLOAT, DOUBLE, INT64, INT32, INT16, UINT16, INT8, UINT8, BOOL)");
  }
  Dims dims(t.dims().begin(), t.dims().end());
  auto count = NumElements(dims);
  if (!count.ok()) return Status::Error(what + ": " + count.message());
  const auto n = static_cast<size_t>(*count);
  // The declared shape against the values the file holds, before anything is sized from it.
  const size_t width = RawWidth(t.data_type());
  if (const size_t held = HeldValues(t);
      held != n || (t.has_raw_data() && t.raw_data().size() != n * width)) {
    return Status::Error(what + " holds " + std::to_string(held) + " values of " +
                         TypeName(t.data_type()) + ", its shape " + JoinInts(dims) + " needs " +
                         std::to_string(n));
  }
  SFRT_ONNX_RETURN_IF_ERROR(budget.Take(n, kConstValueBytes, what + " of shape " + JoinInts(dims)));
  Const c;
  c.type = t.data_type();
  c.dims = std::move(dims);
  const char* raw = t.raw_data().data();
  if (c.is_real()) {
    c.reals.resize(n);
  } else {
    c.ints.resize(n);
  }
  switch (t.data_type()) {
    case TensorProto::FLOAT:
      for (size_t i = 0; i < n; ++i) {
        c.reals[i] = t.has_raw_data() ? LoadLittleEndian<float>(raw + 4 * i)
                                      : t.float_data(static_cast<int>(i));
      }
      break;
    case TensorProto::DOUBLE:
      for (size_t i = 0; i < n; ++i) {
        c.reals[i] = t.has_raw_data() ? LoadLittleEndian<double>(raw + 8 * i)
                                      : t.double_data(static_cast<int>(i));
      }
      break;
    case TensorProto::INT64:
      for (size_t i = 0; i < n; ++i) {
        c.ints[i] = t.has_raw_data() ? LoadLittleEndian<int64_t>(raw + 8 * i)
                                     : t.int64_data(static_cast<int>(i));
      }
      break;
    case TensorProto::INT32:
      for (size_t i = 0; i < n; ++i) {
        c.ints[i] = t.has_raw_data() ? LoadLittleEndian<int32_t>(raw + 4 * i)
                                     : t.int32_data(static_cast<int>(i));
      }
      break;
    case TensorProto::INT8:
    case TensorProto::UINT8:
    case TensorProto::INT16:
    case TensorProto::UINT16: {
      const bool is_signed =
          t.data_type() == TensorProto::INT8 || t.data_type() == TensorProto::INT16;
      const uint32_t sign_bit = width == 1 ? 0x80u : 0x8000u;
      for (size_t i = 0; i < n; ++i) {
        if (!t.has_raw_data()) {  // int32_data holds one value per element
          c.ints[i] = t.int32_data(static_cast<int>(i));
          continue;
        }
        uint32_t u = static_cast<unsigned char>(raw[width * i]);
        if (width == 2) u |= static_cast<uint32_t>(static_cast<unsigned char>(raw[2 * i + 1])) << 8;
        c.ints[i] = is_signed && (u & sign_bit) != 0 ? static_cast<int64_t>(u) - 2 * sign_bit
                                                     : static_cast<int64_t>(u);
      }
      break;
    }
    default:  // BOOL
      for (size_t i = 0; i < n; ++i) {
        const bool set = t.has_raw_data() ? raw[i] != 0 : t.int32_data(static_cast<int>(i)) != 0;
        c.ints[i] = set ? 1 : 0;
      }
      break;
  }
  return c;
}

Result<Dims> BroadcastDims(const std::vector<const Dims*>& shapes) {
  size_t rank = 0;
  for (const Dims* s : shapes) rank = std::max(rank, s->size());
  Dims out(rank, 1);
  for (const Dims* s : shapes) {
    const size_t offset = rank - s->size();
    for (size_t i = 0; i < s->size(); ++i) {
      const int64_t d = (*s)[i];
      int64_t& o = out[offset + i];
      if (d == o || d == 1) continue;
      if (o == 1) {
        o = d;
        continue;
      }
      std::string text;
      for (const Dims* t : shapes) text += (text.empty() ? "" : " and ") + JoinInts(*t);
      return Status::Error("shapes " + text + " do not broadcast");
    }
  }
  return out;
}

size_t SourceIndex(size_t flat, const Dims& out, const Dims& in) {
  size_t index = 0;
  size_t stride = 1;
  const size_t offset = out.size() - in.size();
  for (size_t k = out.size(); k-- > 0;) {
    const auto extent = static_cast<size_t>(out[k]);
    const size_t coord = extent == 0 ? 0 : flat % extent;
    flat = extent == 0 ? 0 : flat / extent;
    if (k >= offset) {
      const auto in_extent = static_cast<size_t>(in[k - offset]);
      if (in_extent != 1) index += coord * stride;
      stride *= in_extent;
    }
  }
  return index;
}

int PromoteTypes(int a, int b) {
  if (a == b) return a;
  if (a == TensorProto::DOUBLE || b == TensorProto::DOUBLE) return TensorProto::DOUBLE;
  if (a == TensorProto::FLOAT || b == TensorProto::FLOAT) return TensorProto::FLOAT;
  return TensorProto::INT64;
}

Result<int64_t> IntOk(int64_t v) { return v; }

int64_t FloorDiv(int64_t n, int64_t d) {
  int64_t q = n / d;
  if ((n % d != 0) && ((n < 0) != (d < 0))) --q;
  return q;
}

Result<Const> Cast(ConstantBudget& budget, const Const& in, int to) {
  if (!IsSupportedType(to)) {
    return Status::Error("attribute 'to' = " + TypeName(to) +
                         " is not supported (FLOAT, DOUBLE, INT64, INT32, BOOL)");
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(budget, to, in.dims));
  for (size_t i = 0; i < in.size(); ++i) {
    if (in.is_real() && !out.is_real()) {
      const double v = in.reals[i];
      if (to == TensorProto::BOOL) {
        out.ints[i] = v != 0.0 ? 1 : 0;
        continue;
      }
      if (!std::isfinite(v) || std::fabs(v) >= 9.2e18) {
        return Status::Error("cannot cast " + FormatDouble(v) + " to " + TypeName(to));
      }
      out.SetInt(i, static_cast<int64_t>(std::trunc(v)));
    } else {
      CopyElement(in, i, out, i);
    }
  }
  return out;
}

Result<int64_t> NormalizeAxis(int64_t axis, int64_t rank, const std::string& what) {
  if (axis < -rank || axis >= rank) {
    return Status::Error(what + " " + std::to_string(axis) + " is out of range for rank " +
                         std::to_string(rank));
  }
  return axis < 0 ? axis + rank : axis;
}

Dims Strides(const Dims& dims) {
  Dims strides(dims.size(), 1);
  for (size_t k = dims.size(); k-- > 1;) strides[k - 1] = strides[k] * dims[k];
  return strides;
}

Result<Const> Concat(ConstantBudget& budget, const std::vector<const Const*>& ins,
                     int64_t axis_attr) {
  if (ins.empty()) return Status::Error("no inputs");
  const Const& first = *ins[0];
  const auto rank = static_cast<int64_t>(first.dims.size());
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t axis, NormalizeAxis(axis_attr, rank, "axis"));
  Dims dims = first.dims;
  dims[axis] = 0;
  int type = first.type;
  for (const Const* in : ins) {
    if (static_cast<int64_t>(in->dims.size()) != rank) {
      return Status::Error("inputs have different ranks");
    }
    for (int64_t k = 0; k < rank; ++k) {
      if (k != axis && in->dims[k] != first.dims[k]) {
        return Status::Error("input shapes " + JoinInts(first.dims) + " and " + JoinInts(in->dims) +
                             " differ outside axis " + std::to_string(axis));
      }
    }
    dims[axis] += in->dims[axis];
    type = PromoteTypes(type, in->type);
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(budget, type, dims));
  int64_t outer = 1;
  for (int64_t k = 0; k < axis; ++k) outer *= dims[k];
  size_t di = 0;
  for (int64_t o = 0; o < outer; ++o) {
    for (const Const* in : ins) {
      const auto block =
          static_cast<size_t>(in->size() / static_cast<size_t>(outer > 0 ? outer : 1));
      const size_t base = static_cast<size_t>(o) * block;
      for (size_t j = 0; j < block; ++j) CopyElement(*in, base + j, out, di++);
    }
  }
  return out;
}

Result<Const> Gather(ConstantBudget& budget, const Const& data, const Const& indices,
                     int64_t axis_attr) {
  if (indices.is_real()) return Status::Error("indices must be integers");
  const auto rank = static_cast<int64_t>(data.dims.size());
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t axis, NormalizeAxis(axis_attr, rank, "axis"));
  Dims dims(data.dims.begin(), data.dims.begin() + axis);
  dims.insert(dims.end(), indices.dims.begin(), indices.dims.end());
  dims.insert(dims.end(), data.dims.begin() + axis + 1, data.dims.end());
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(budget, data.type, dims));
  int64_t outer = 1;
  int64_t inner = 1;
  for (int64_t k = 0; k < axis; ++k) outer *= data.dims[k];
  for (int64_t k = axis + 1; k < rank; ++k) inner *= data.dims[k];
  const int64_t extent = data.dims[axis];
  size_t di = 0;
  for (int64_t o = 0; o < outer; ++o) {
    for (size_t j = 0; j < indices.size(); ++j) {
      int64_t idx = indices.ints[j];
      if (idx < 0) idx += extent;
      if (idx < 0 || idx >= extent) {
        return Status::Error("index " + std::to_string(indices.ints[j]) +
                             " is out of range for axis of size " + std::to_string(extent));
      }
      for (int64_t i = 0; i < inner; ++i) {
        CopyElement(data, static_cast<size_t>((o * extent + idx) * inner + i), out, di++);
      }
    }
  }
  return out;
}

Result<Const> Reshaped(Const in, Dims dims) {
  SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t n, NumElements(dims));
  if (static_cast<size_t>(n) != in.size()) {
    return Status::Error("cannot reshape " + JoinInts(in.dims) + " to " + JoinInts(dims));
  }
  in.dims = std::move(dims);
  return in;
}

Result<Const> Reshape(Const in, const Const& shape, bool allow_zero) {
  if (shape.is_real() || shape.dims.size() != 1) {
    return Status::Error("input 'shape' must be a 1-D integer tensor");
  }
  Dims dims(shape.ints.begin(), shape.ints.end());
  int infer = -1;
  int64_t known = 1;
  for (size_t k = 0; k < dims.size(); ++k) {
    if (dims[k] == 0 && !allow_zero) {
      if (k >= in.dims.size())
        return Status::Error("shape " + JoinInts(shape.ints) + " copies a missing dimension");
      dims[k] = in.dims[k];
    }
    if (dims[k] == -1) {
      if (infer >= 0) return Status::Error("shape " + JoinInts(shape.ints) + " has two -1 entries");
      infer = static_cast<int>(k);
      continue;
    }
    if (dims[k] < 0) {
      return Status::Error("shape " + JoinInts(shape.ints) + " has a negative entry");
    }
    if (dims[k] > 0 && known > kMaxFoldedElements / dims[k]) {
      return Status::Error("shape " + JoinInts(shape.ints) + " is too large");
    }
    known *= dims[k];
  }
  if (infer >= 0) {
    const auto total = static_cast<int64_t>(in.size());
    if (known == 0 || total % known != 0) {
      return Status::Error("cannot reshape " + JoinInts(in.dims) + " to " + JoinInts(shape.ints));
    }
    dims[infer] = total / known;
  }
  return Reshaped(std::move(in), std::move(dims));
}

Result<Const> Unsqueeze(Const in, const std::vector<int64_t>& axes_in) {
  const auto out_rank = static_cast<int64_t>(in.dims.size() + axes_in.size());
  std::vector<int64_t> axes;
  for (int64_t a : axes_in) {
    SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t axis, NormalizeAxis(a, out_rank, "axis"));
    if (std::find(axes.begin(), axes.end(), axis) != axes.end()) {
      return Status::Error("axes " + JoinInts(axes_in) + " repeat an axis");
    }
    axes.push_back(axis);
  }
  Dims dims;
  size_t next = 0;
  for (int64_t k = 0; k < out_rank; ++k) {
    if (std::find(axes.begin(), axes.end(), k) != axes.end()) {
      dims.push_back(1);
    } else {
      dims.push_back(in.dims[next++]);
    }
  }
  return Reshaped(std::move(in), std::move(dims));
}

Result<Const> Squeeze(Const in, const std::vector<int64_t>& axes_in, bool have_axes) {
  const auto rank = static_cast<int64_t>(in.dims.size());
  std::vector<bool> drop(in.dims.size(), false);
  if (!have_axes) {
    for (int64_t k = 0; k < rank; ++k) drop[k] = in.dims[k] == 1;
  }
  for (int64_t a : axes_in) {
    SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t axis, NormalizeAxis(a, rank, "axis"));
    if (in.dims[axis] != 1) {
      return Status::Error("cannot squeeze axis " + std::to_string(a) + " of shape " +
                           JoinInts(in.dims));
    }
    drop[axis] = true;
  }
  Dims dims;
  for (int64_t k = 0; k < rank; ++k) {
    if (!drop[k]) dims.push_back(in.dims[k]);
  }
  return Reshaped(std::move(in), std::move(dims));
}

Result<Const> Transpose(ConstantBudget& budget, const Const& in, std::vector<int64_t> perm) {
  const size_t rank = in.dims.size();
  if (perm.empty()) {
    for (size_t k = rank; k-- > 0;) perm.push_back(static_cast<int64_t>(k));
  }
  if (perm.size() != rank)
    return Status::Error("attribute 'perm' " + JoinInts(perm) + " has the wrong length");
  std::vector<bool> seen(rank, false);
  for (int64_t p : perm) {
    if (p < 0 || static_cast<size_t>(p) >= rank || seen[p]) {
      return Status::Error("attribute 'perm' " + JoinInts(perm) + " is not a permutation");
    }
    seen[p] = true;
  }
  Dims dims(rank);
  for (size_t k = 0; k < rank; ++k) dims[k] = in.dims[perm[k]];
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(budget, in.type, dims));
  const Dims in_strides = Strides(in.dims);
  for (size_t i = 0; i < out.size(); ++i) {
    size_t flat = i;
    size_t src = 0;
    for (size_t k = rank; k-- > 0;) {
      const auto extent = static_cast<size_t>(dims[k]);
      src += (flat % extent) * static_cast<size_t>(in_strides[perm[k]]);
      flat /= extent;
    }
    CopyElement(in, src, out, i);
  }
  return out;
}

Result<Const> Expand(ConstantBudget& budget, const Const& in, const Const& shape) {
  if (shape.is_real() || shape.dims.size() != 1) {
    return Status::Error("input 'shape' must be a 1-D integer tensor");
  }
  const Dims target(shape.ints.begin(), shape.ints.end());
  SFRT_ONNX_ASSIGN_OR_RETURN(const Dims dims, BroadcastDims({&in.dims, &target}));
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(budget, in.type, dims));
  for (size_t i = 0; i < out.size(); ++i) CopyElement(in, SourceIndex(i, dims, in.dims), out, i);
  return out;
}

Result<Const> Tile(ConstantBudget& budget, const Const& in, const Const& repeats) {
  if (repeats.is_real() || repeats.size() != in.dims.size()) {
    return Status::Error("input 'repeats' must hold one integer per input dimension");
  }
  Dims dims = in.dims;
  for (size_t k = 0; k < dims.size(); ++k) {
    if (repeats.ints[k] < 0 || repeats.ints[k] > kMaxFoldedElements) {
      return Status::Error("input 'repeats' = " + JoinInts(repeats.ints) + " is not supported");
    }
    dims[k] *= repeats.ints[k];  // both factors <= 2^24: no overflow
  }
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(budget, in.type, dims));
  const Dims in_strides = Strides(in.dims);
  for (size_t i = 0; i < out.size(); ++i) {
    size_t flat = i;
    size_t src = 0;
    for (size_t k = dims.size(); k-- > 0;) {
      const auto extent = static_cast<size_t>(dims[k]);
      src +=
          ((flat % extent) % static_cast<size_t>(in.dims[k])) * static_cast<size_t>(in_strides[k]);
      flat /= extent;
    }
    CopyElement(in, src, out, i);
  }
  return out;
}

SliceAxis ClampSlice(int64_t start, int64_t end, int64_t step, int64_t dim) {
  SliceAxis s;
  // Steps beyond the extent select one element either way; clamping keeps the arithmetic exact.
  constexpr int64_t kMaxStep = int64_t{1} << 40;
  step = std::clamp(step, -kMaxStep, kMaxStep);
  s.step = step;
  if (start < 0) start += dim;
  if (end < 0) end += dim;
  if (step > 0) {
    start = std::clamp<int64_t>(start, 0, dim);
    end = std::clamp<int64_t>(end, 0, dim);
    s.count = end > start ? (end - start - 1) / step + 1 : 0;
  } else {
    start = std::clamp<int64_t>(start, 0, dim - 1);
    end = std::clamp<int64_t>(end, -1, dim - 1);
    s.count = start > end ? (start - end - 1) / (-step) + 1 : 0;
  }
  s.start = start;
  return s;
}

Result<SliceArgs> ReadSliceArgs(const Const* starts, const Const* ends, const Const* axes,
                                const Const* steps, int64_t rank) {
  auto ints = [](const Const* c, const char* name) -> Result<std::vector<int64_t>> {
    if (c->is_real() || c->dims.size() > 1) {
      return Status::Error(std::string("input '") + name + "' must be a 1-D integer tensor");
    }
    return c->ints;
  };
  SliceArgs a;
  SFRT_ONNX_ASSIGN_OR_RETURN(a.starts, ints(starts, "starts"));
  SFRT_ONNX_ASSIGN_OR_RETURN(a.ends, ints(ends, "ends"));
  if (axes != nullptr) {
    SFRT_ONNX_ASSIGN_OR_RETURN(a.axes, ints(axes, "axes"));
  } else {
    for (size_t k = 0; k < a.starts.size(); ++k) a.axes.push_back(static_cast<int64_t>(k));
  }
  if (steps != nullptr) {
    SFRT_ONNX_ASSIGN_OR_RETURN(a.steps, ints(steps, "steps"));
  } else {
    a.steps.assign(a.starts.size(), 1);
  }
  if (a.ends.size() != a.starts.size() || a.axes.size() != a.starts.size() ||
      a.steps.size() != a.starts.size()) {
    return Status::Error("inputs 'starts' " + JoinInts(a.starts) + ", 'ends' " + JoinInts(a.ends) +
                         ", 'axes' " + JoinInts(a.axes) + " and 'steps' " + JoinInts(a.steps) +
                         " differ in length");
  }
  std::vector<int64_t> seen;
  for (int64_t& axis : a.axes) {
    SFRT_ONNX_ASSIGN_OR_RETURN(axis, NormalizeAxis(axis, rank, "input 'axes' value"));
    if (std::find(seen.begin(), seen.end(), axis) != seen.end()) {
      return Status::Error("input 'axes' repeats axis " + std::to_string(axis));
    }
    seen.push_back(axis);
  }
  for (int64_t step : a.steps) {
    if (step == 0) return Status::Error("input 'steps' contains 0");
  }
  return a;
}

Result<Const> SliceConst(ConstantBudget& budget, const Const& in, const SliceArgs& args) {
  const size_t rank = in.dims.size();
  std::vector<SliceAxis> axes(rank);
  for (size_t k = 0; k < rank; ++k) axes[k] = SliceAxis{0, 1, in.dims[k]};
  for (size_t i = 0; i < args.axes.size(); ++i) {
    const auto k = static_cast<size_t>(args.axes[i]);
    axes[k] = ClampSlice(args.starts[i], args.ends[i], args.steps[i], in.dims[k]);
  }
  Dims dims(rank);
  for (size_t k = 0; k < rank; ++k) dims[k] = axes[k].count;
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(budget, in.type, dims));
  const Dims in_strides = Strides(in.dims);
  for (size_t i = 0; i < out.size(); ++i) {
    size_t flat = i;
    int64_t src = 0;
    for (size_t k = rank; k-- > 0;) {
      const auto extent = static_cast<size_t>(dims[k]);
      const auto coord = static_cast<int64_t>(flat % extent);
      flat /= extent;
      src += (axes[k].start + coord * axes[k].step) * in_strides[k];
    }
    CopyElement(in, static_cast<size_t>(src), out, i);
  }
  return out;
}

Result<Const> Range(ConstantBudget& budget, const Const& start, const Const& limit,
                    const Const& delta) {
  if (start.size() != 1 || limit.size() != 1 || delta.size() != 1) {
    return Status::Error("inputs must be scalars");
  }
  const int type = start.type;
  // The element count, computed in double: only small ranges are evaluated anyway.
  const double d = delta.Real(0);
  if (d == 0.0) return Status::Error("delta is 0");
  const double count_d = std::max(std::ceil((limit.Real(0) - start.Real(0)) / d), 0.0);
  if (!(count_d <= static_cast<double>(kMaxFoldedElements))) {
    return Status::Error("range of " + FormatDouble(count_d) + " elements is too large");
  }
  const auto count = static_cast<int64_t>(count_d);
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(budget, type, {count}));
  for (int64_t i = 0; i < count; ++i) {
    if (IsReal(type)) {
      out.Set(static_cast<size_t>(i), start.Real(0) + static_cast<double>(i) * delta.Real(0));
    } else {
      out.SetInt(static_cast<size_t>(i), WrapAdd(start.Int(0), WrapMul(i, delta.Int(0))));
    }
  }
  return out;
}

}  // namespace sfrt::exporter::onnx_import
