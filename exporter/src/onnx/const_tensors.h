// The constant tensors of an ONNX import (initialisers, Constant nodes, and what the importer
// evaluates of the graph when every input of a node is a constant): their one type, Const; the
// budget every constant is charged to; and the tensor operations the constant folders
// (onnx/folders.cc) are made of. Errors are bare details; the importer prefixes the node.
#pragma once

// onnx_pb.h defines ONNX_API and then includes onnx-ml.pb.h (ONNX_ML=1); including
// onnx-ml.pb.h directly does not compile with Debian's headers.
#include <onnx/onnx_pb.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "sfrt/status.h"

#define SFRT_ONNX_CONCAT_INNER(a, b) a##b
#define SFRT_ONNX_CONCAT(a, b) SFRT_ONNX_CONCAT_INNER(a, b)

// Returns the Status of `expr` from the enclosing function when it is an error.
#define SFRT_ONNX_RETURN_IF_ERROR(expr)        \
  do {                                         \
    ::sfrt::Status sfrt_onnx_status_ = (expr); \
    if (!sfrt_onnx_status_.ok()) {             \
      return sfrt_onnx_status_;                \
    }                                          \
  } while (false)

// `lhs = value of expr`, or returns expr's error Status from the enclosing function.
#define SFRT_ONNX_ASSIGN_OR_RETURN(lhs, expr) \
  SFRT_ONNX_ASSIGN_OR_RETURN_IMPL(SFRT_ONNX_CONCAT(sfrt_onnx_result_, __LINE__), lhs, expr)
#define SFRT_ONNX_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                                    \
  if (!tmp.ok()) {                                      \
    return tmp.status();                                \
  }                                                     \
  lhs = std::move(tmp).value()

namespace sfrt::exporter::onnx_import {

using onnx::TensorProto;
using Dims = std::vector<int64_t>;

// Upper bound on the elements of one evaluated constant: shape arithmetic is tiny, and this keeps
// a hostile file from making the importer allocate without limit.
constexpr int64_t kMaxFoldedElements = int64_t{1} << 24;
// What an import may allocate for constants (ConstantBudget): this slack for shape arithmetic,
// plus this many bytes per byte of the file, room for every weight to be decoded, evaluated and
// copied a few times (a Const takes 8 bytes a value, twice a float32 weight's 4).
constexpr int64_t kConstantSlackBytes = int64_t{32} << 20;
constexpr int64_t kConstantBytesPerFileByte = 16;
// A Const holds every value as a double or an int64.
constexpr size_t kConstValueBytes = 8;
// Values of a list (a shape, scales, pads) written in one message; the rest are counted.
constexpr size_t kMaxListedValues = 16;

// A float for messages, as short as %g writes it.
std::string FormatFloat(float v);

// "[1, 2, 3]"; past kMaxListedValues, the first of them and the count, so that a message stays
// one readable line whatever length the file gives a list.
std::string JoinInts(const std::vector<int64_t>& values);

std::string FormatDouble(double v);

// As JoinInts.
std::string JoinReals(const std::vector<double>& values);

bool IsReal(int type);

// 8- and 16-bit integers: every value is exact in float32.
bool IsSmallInteger(int type);

bool IsSupportedType(int type);

std::string TypeName(int type);

// FLOAT values are kept exactly representable as float, as an ONNX runtime would compute them.
double RoundToType(int type, double v);

// double -> int64 without undefined behaviour: NaN gives 0, out-of-range values saturate.
int64_t ToInt64(double v);

// Two's-complement wrapping int64 arithmetic, as ONNX runtimes compute it (no UB on overflow).
int64_t WrapAdd(int64_t a, int64_t b);

int64_t WrapSub(int64_t a, int64_t b);

int64_t WrapMul(int64_t a, int64_t b);

int64_t WrapToType(int type, int64_t v);

// A constant tensor. Integer and bool values live in `ints`, FLOAT and DOUBLE values in `reals`.
struct Const {
  int type = TensorProto::INT64;
  Dims dims;
  std::vector<int64_t> ints;
  std::vector<double> reals;

  bool is_real() const { return IsReal(type); }
  size_t size() const { return is_real() ? reals.size() : ints.size(); }
  double Real(size_t i) const { return is_real() ? reals[i] : static_cast<double>(ints[i]); }
  // Integer view; only used where the tensor is an integer tensor or the value is known whole.
  int64_t Int(size_t i) const { return is_real() ? ToInt64(reals[i]) : ints[i]; }
  void Set(size_t i, double v) {
    if (is_real()) {
      reals[i] = RoundToType(type, v);
    } else {
      ints[i] = WrapToType(type, ToInt64(v));
    }
  }
  void SetInt(size_t i, int64_t v) {
    if (is_real()) {
      reals[i] = RoundToType(type, static_cast<double>(v));
    } else {
      ints[i] = WrapToType(type, v);
    }
  }
};

Result<int64_t> NumElements(const Dims& dims);

// The bytes an import may still allocate for constants. A file's shapes and counts are only
// declarations: a 257-byte file declared a 2 GB weight (issue 38), and a few bytes of nodes can
// repeat, broadcast or expand a tensor without limit. So every constant the importer decodes,
// copies or evaluates, and every weight it reads, is charged here before it is allocated, which
// keeps an import within kConstantSlackBytes plus kConstantBytesPerFileByte times the file,
// whatever the file declares.
class ConstantBudget {
 public:
  explicit ConstantBudget(size_t file_bytes)
      : file_bytes_(file_bytes),
        limit_(kConstantSlackBytes + kConstantBytesPerFileByte * static_cast<int64_t>(file_bytes)),
        left_(limit_) {}

  // Charges `values` values of `value_bytes` bytes each. The error starts with `what` (a tensor
  // and its shape) and says what it needed against what was left.
  Status Take(size_t values, size_t value_bytes, const std::string& what) {
    // values <= 2^30 (NumElements) or a field the parsed file holds; value_bytes <= 8.
    const auto bytes = static_cast<int64_t>(values * value_bytes);
    if (bytes > left_) {
      return Status::Error(what + " needs " + std::to_string(bytes) +
                           " bytes, more than this import may still allocate for constants (" +
                           std::to_string(left_) + " of " + std::to_string(limit_) +
                           " bytes: " + std::to_string(kConstantSlackBytes >> 20) + " MiB plus " +
                           std::to_string(kConstantBytesPerFileByte) + " per byte of the " +
                           std::to_string(file_bytes_) + "-byte file)");
    }
    left_ -= bytes;
    return Status::Ok();
  }

 private:
  size_t file_bytes_;
  int64_t limit_;
  int64_t left_;
};

// A zero constant of `dims`, charged to `budget`.
Result<Const> MakeConst(ConstantBudget& budget, int type, Dims dims);

// Copies element `si` of `src` into element `di` of `dst`, converting the type if needed.
void CopyElement(const Const& src, size_t si, Const& dst, size_t di);

template <typename T>
T LoadLittleEndian(const char* p) {
  using U = std::conditional_t<sizeof(T) == 8, uint64_t, uint32_t>;
  U u = 0;
  for (size_t b = 0; b < sizeof(T); ++b) {
    u |= static_cast<U>(static_cast<unsigned char>(p[b])) << (8 * b);
  }
  return std::bit_cast<T>(u);
}

// The bytes one value of a supported `type` takes in raw_data.
size_t RawWidth(int type);

// The values a tensor of a supported type holds: whole values in raw_data, or the length of the
// typed field its type uses (int32_data for the integer types narrower than 64 bits and BOOL).
size_t HeldValues(const TensorProto& t);

// Decodes an initialiser or a Constant node's tensor, charged to `budget`. `what` names it in
// errors.
Result<Const> DecodeTensor(const TensorProto& t, const std::string& what, ConstantBudget& budget);

// Numpy-style (multidirectional) broadcasting of several shapes.
Result<Dims> BroadcastDims(const std::vector<const Dims*>& shapes);

// The flat index into a tensor of shape `in` (broadcast to `out`) for flat output index `flat`.
size_t SourceIndex(size_t flat, const Dims& out, const Dims& in);

int PromoteTypes(int a, int b);

// Elementwise op over broadcast inputs. `real_fn(double, double) -> double` is used when the
// computation type is real, `int_fn(int64, int64) -> Result<int64>` otherwise. The output has
// `out_type` (which may differ from the computation type, e.g. BOOL for comparisons).
template <typename RealFn, typename IntFn>
Result<Const> Elementwise(ConstantBudget& budget, const Const& a, const Const& b, int out_type,
                          RealFn real_fn, IntFn int_fn) {
  SFRT_ONNX_ASSIGN_OR_RETURN(Dims dims, BroadcastDims({&a.dims, &b.dims}));
  SFRT_ONNX_ASSIGN_OR_RETURN(Const out, MakeConst(budget, out_type, dims));
  const bool real = a.is_real() || b.is_real();
  for (size_t i = 0; i < out.size(); ++i) {
    const size_t ia = SourceIndex(i, dims, a.dims);
    const size_t ib = SourceIndex(i, dims, b.dims);
    if (real) {
      out.Set(i, real_fn(a.Real(ia), b.Real(ib)));
    } else {
      SFRT_ONNX_ASSIGN_OR_RETURN(const int64_t v, int_fn(a.ints[ia], b.ints[ib]));
      out.SetInt(i, v);
    }
  }
  return out;
}

Result<int64_t> IntOk(int64_t v);

int64_t FloorDiv(int64_t n, int64_t d);

Result<Const> Cast(ConstantBudget& budget, const Const& in, int to);

// Normalises an axis in [-rank, rank) to [0, rank).
Result<int64_t> NormalizeAxis(int64_t axis, int64_t rank, const std::string& what);

Dims Strides(const Dims& dims);

Result<Const> Concat(ConstantBudget& budget, const std::vector<const Const*>& ins,
                     int64_t axis_attr);

Result<Const> Gather(ConstantBudget& budget, const Const& data, const Const& indices,
                     int64_t axis_attr);

// `in` with shape `dims`; it takes `in`'s values (no copy, so nothing to charge).
Result<Const> Reshaped(Const in, Dims dims);

Result<Const> Reshape(Const in, const Const& shape, bool allow_zero);

Result<Const> Unsqueeze(Const in, const std::vector<int64_t>& axes_in);

Result<Const> Squeeze(Const in, const std::vector<int64_t>& axes_in, bool have_axes);

Result<Const> Transpose(ConstantBudget& budget, const Const& in, std::vector<int64_t> perm);

Result<Const> Expand(ConstantBudget& budget, const Const& in, const Const& shape);

Result<Const> Tile(ConstantBudget& budget, const Const& in, const Const& repeats);

struct SliceAxis {
  int64_t start = 0;
  int64_t step = 1;
  int64_t count = 0;
};

// ONNX Slice clamping for one axis of extent `dim`.
SliceAxis ClampSlice(int64_t start, int64_t end, int64_t step, int64_t dim);

struct SliceArgs {
  std::vector<int64_t> starts, ends, axes, steps;
};

Result<SliceArgs> ReadSliceArgs(const Const* starts, const Const* ends, const Const* axes,
                                const Const* steps, int64_t rank);

Result<Const> SliceConst(ConstantBudget& budget, const Const& in, const SliceArgs& args);

Result<Const> Range(ConstantBudget& budget, const Const& start, const Const& limit,
                    const Const& delta);

}  // namespace sfrt::exporter::onnx_import
