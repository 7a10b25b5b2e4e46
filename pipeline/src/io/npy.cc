#include "sfrt/pipeline/io/npy.h"

#include <cctype>
#include <cstring>
#include <limits>
#include <optional>

#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/io/byte_order.h"

namespace sfrt::io {
namespace {

constexpr char kMagic[] = "\x93NUMPY";
constexpr size_t kMagicSize = 6;
constexpr size_t kAlignment = 64;

// A tiny parser for the Python dict literal in a .npy header. It accepts what numpy.save
// writes (and the usual variations in quoting and spacing), nothing more.
class HeaderParser {
 public:
  HeaderParser(std::string_view text, const std::string& label) : text_(text), label_(label) {}

  Status Parse() {
    SkipSpace();
    if (!Consume('{')) return Fail("header is not a Python dict (expected '{')");
    SkipSpace();
    while (!Peek('}')) {
      std::string key;
      if (Status s = ParseString(&key, "a quoted key"); !s.ok()) return s;
      SkipSpace();
      if (!Consume(':')) return Fail("expected ':' after key '" + key + "'");
      SkipSpace();
      if (key == "descr") {
        if (descr_) return Fail("duplicate field 'descr'");
        std::string value;
        if (Status s = ParseString(&value, "a quoted dtype in field 'descr'"); !s.ok()) return s;
        descr_ = value;
      } else if (key == "fortran_order") {
        if (fortran_order_) return Fail("duplicate field 'fortran_order'");
        if (ConsumeWord("True")) {
          fortran_order_ = true;
        } else if (ConsumeWord("False")) {
          fortran_order_ = false;
        } else {
          return Fail("field 'fortran_order' must be True or False");
        }
      } else if (key == "shape") {
        if (shape_) return Fail("duplicate field 'shape'");
        std::vector<int64_t> dims;
        if (Status s = ParseShape(&dims); !s.ok()) return s;
        shape_ = std::move(dims);
      } else {
        return Fail("unexpected field '" + key +
                    "' (a .npy header has exactly 'descr', 'fortran_order' and 'shape')");
      }
      SkipSpace();
      if (Consume(',')) {
        SkipSpace();
        continue;
      }
      if (!Peek('}')) return Fail("expected ',' or '}' after field '" + key + "'");
    }
    Consume('}');
    SkipSpace();
    if (pos_ != text_.size()) return Fail("unexpected text after the header dict");
    if (!descr_) return Fail("header has no field 'descr'");
    if (!fortran_order_) return Fail("header has no field 'fortran_order'");
    if (!shape_) return Fail("header has no field 'shape'");
    return Status::Ok();
  }

  const std::string& descr() const { return *descr_; }
  bool fortran_order() const { return *fortran_order_; }
  const std::vector<int64_t>& shape() const { return *shape_; }

 private:
  Status Fail(const std::string& what) const {
    return Status::Error(label_ + ": bad .npy header: " + what);
  }
  void SkipSpace() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
  }
  bool Peek(char c) const { return pos_ < text_.size() && text_[pos_] == c; }
  bool Consume(char c) {
    if (!Peek(c)) return false;
    ++pos_;
    return true;
  }
  bool ConsumeWord(std::string_view word) {
    if (text_.substr(pos_, word.size()) != word) return false;
    size_t end = pos_ + word.size();
    if (end < text_.size() &&
        (std::isalnum(static_cast<unsigned char>(text_[end])) || text_[end] == '_')) {
      return false;
    }
    pos_ = end;
    return true;
  }
  Status ParseString(std::string* out, const char* what) {
    if (!Peek('\'') && !Peek('"')) return Fail(std::string("expected ") + what);
    char quote = text_[pos_++];
    size_t end = text_.find(quote, pos_);
    if (end == std::string_view::npos) return Fail(std::string("unterminated string in ") + what);
    *out = std::string(text_.substr(pos_, end - pos_));
    pos_ = end + 1;
    return Status::Ok();
  }
  Status ParseShape(std::vector<int64_t>* dims) {
    if (!Consume('(')) return Fail("field 'shape' must be a tuple such as (540, 960, 12)");
    SkipSpace();
    while (!Peek(')')) {
      if (pos_ >= text_.size() || !std::isdigit(static_cast<unsigned char>(text_[pos_]))) {
        return Fail("field 'shape' must hold non-negative integers");
      }
      int64_t value = 0;
      while (pos_ < text_.size() && std::isdigit(static_cast<unsigned char>(text_[pos_]))) {
        int digit = text_[pos_++] - '0';
        if (value > (std::numeric_limits<int64_t>::max() - digit) / 10) {
          return Fail("field 'shape' has a dimension too large");
        }
        value = value * 10 + digit;
      }
      Consume('L');  // Python 2 long suffix, as old numpy versions wrote it
      dims->push_back(value);
      SkipSpace();
      if (Consume(',')) {
        SkipSpace();
        continue;
      }
      if (!Peek(')')) return Fail("field 'shape': expected ',' or ')'");
    }
    Consume(')');
    return Status::Ok();
  }

  std::string_view text_;
  const std::string& label_;
  size_t pos_ = 0;
  std::optional<std::string> descr_;
  std::optional<bool> fortran_order_;
  std::optional<std::vector<int64_t>> shape_;
};

// Product of dims, or nullopt on overflow beyond `limit`.
std::optional<uint64_t> CheckedProduct(std::span<const int64_t> dims, uint64_t limit) {
  uint64_t product = 1;
  for (int64_t d : dims) {
    if (d < 0) return std::nullopt;
    uint64_t u = static_cast<uint64_t>(d);
    if (u != 0 && product > limit / u) return std::nullopt;
    product *= u;
  }
  return product;
}

std::string ShapeToString(std::span<const int64_t> shape) {
  std::string s = "(";
  for (size_t i = 0; i < shape.size(); ++i) {
    if (i > 0) s += ", ";
    s += std::to_string(shape[i]);
  }
  if (shape.size() == 1) s += ",";
  return s + ")";
}

}  // namespace

size_t NpyArray::element_count() const {
  size_t n = 1;
  for (int64_t d : shape) n *= static_cast<size_t>(d);
  return n;
}

std::string NpyArray::ShapeString() const { return ShapeToString(shape); }

Result<NpyArray> ParseNpy(std::string_view bytes, const std::string& label) {
  if (bytes.size() < kMagicSize + 2 || std::memcmp(bytes.data(), kMagic, kMagicSize) != 0) {
    return Status::Error(label + ": not a .npy file (missing the \\x93NUMPY magic)");
  }
  const int major = static_cast<unsigned char>(bytes[6]);
  const int minor = static_cast<unsigned char>(bytes[7]);
  size_t header_len = 0;
  size_t prefix = 0;
  if (major == 1 && minor == 0) {
    if (bytes.size() < 10) return Status::Error(label + ": truncated .npy header");
    header_len = static_cast<unsigned char>(bytes[8]) |
                 (static_cast<size_t>(static_cast<unsigned char>(bytes[9])) << 8);
    prefix = 10;
  } else if (major == 2 && minor == 0) {
    if (bytes.size() < 12) return Status::Error(label + ": truncated .npy header");
    for (int i = 3; i >= 0; --i) {
      header_len = (header_len << 8) | static_cast<unsigned char>(bytes[8 + i]);
    }
    prefix = 12;
  } else {
    return Status::Error(label + ": unsupported .npy format version " + std::to_string(major) +
                         "." + std::to_string(minor) + " (supported: 1.0, 2.0)");
  }
  if (header_len > bytes.size() - prefix) {
    return Status::Error(label + ": truncated .npy header (header length " +
                         std::to_string(header_len) + " bytes, file has " +
                         std::to_string(bytes.size()) + ")");
  }
  std::string_view header = bytes.substr(prefix, header_len);
  for (char c : header) {
    if (static_cast<unsigned char>(c) >= 0x80 || c == '\0') {
      return Status::Error(label + ": bad .npy header: non-ASCII byte in the header dict");
    }
  }
  HeaderParser parser(header, label);
  if (Status s = parser.Parse(); !s.ok()) return s;

  if (parser.descr() != "<f4") {
    std::string hint = parser.descr() == ">f4" ? " (big-endian)" : "";
    return Status::Error(label + ": unsupported dtype '" + parser.descr() + "'" + hint +
                         " in field 'descr' (only '<f4', little-endian float32, is supported; "
                         "convert with arr.astype('<f4'))");
  }
  if (parser.fortran_order()) {
    return Status::Error(label +
                         ": field 'fortran_order' is True; only C-order arrays are supported "
                         "(save np.ascontiguousarray(arr))");
  }

  NpyArray array;
  array.shape = parser.shape();
  const size_t data_bytes = bytes.size() - prefix - header_len;
  std::optional<uint64_t> count =
      CheckedProduct(array.shape, std::numeric_limits<uint64_t>::max() / sizeof(float));
  if (!count) {
    return Status::Error(label + ": field 'shape' " + ShapeToString(array.shape) + " is too large");
  }
  if (*count * sizeof(float) != data_bytes) {
    return Status::Error(label + ": shape " + ShapeToString(array.shape) + " needs " +
                         std::to_string(*count * sizeof(float)) + " bytes of float32 data but " +
                         std::to_string(data_bytes) + " follow the header" +
                         (*count * sizeof(float) > data_bytes ? " (file truncated?)" : ""));
  }
  array.data.resize(static_cast<size_t>(*count));
  LoadFloats(bytes.data() + prefix + header_len, array.data.size(), /*little_endian=*/true,
             array.data.data());
  return array;
}

Result<NpyArray> ReadNpy(const std::string& path) {
  Result<std::string> bytes = ReadWholeFile(path);
  if (!bytes.ok()) return bytes.status();
  return ParseNpy(*bytes, path);
}

Result<std::vector<uint8_t>> SerializeNpy(std::span<const int64_t> shape,
                                          std::span<const float> data) {
  std::optional<uint64_t> count =
      CheckedProduct(shape, std::numeric_limits<uint64_t>::max() / sizeof(float));
  if (!count) return Status::Error("cannot write .npy: invalid shape " + ShapeToString(shape));
  if (*count != data.size()) {
    return Status::Error("cannot write .npy: shape " + ShapeToString(shape) + " holds " +
                         std::to_string(*count) + " elements but " + std::to_string(data.size()) +
                         " were given");
  }
  std::string dict =
      "{'descr': '<f4', 'fortran_order': False, 'shape': " + ShapeToString(shape) + ", }";
  // Pad with spaces so that magic + version + length + header is a multiple of 64, ending in '\n'.
  size_t prefix = 10;
  size_t total = prefix + dict.size() + 1;
  if ((total + kAlignment - 1) / kAlignment * kAlignment - prefix > 0xffff) prefix = 12;
  total = prefix + dict.size() + 1;
  const size_t padded = (total + kAlignment - 1) / kAlignment * kAlignment;
  dict.append(padded - total, ' ');
  dict.push_back('\n');
  const size_t header_len = dict.size();

  std::vector<uint8_t> out(prefix + header_len + data.size() * sizeof(float));
  std::memcpy(out.data(), kMagic, kMagicSize);
  out[6] = prefix == 10 ? 1 : 2;
  out[7] = 0;
  for (size_t i = 0; i < prefix - 8; ++i) out[8 + i] = static_cast<uint8_t>(header_len >> (8 * i));
  std::memcpy(out.data() + prefix, dict.data(), header_len);
  StoreFloatsLittleEndian(data.data(), data.size(), out.data() + prefix + header_len);
  return out;
}

Status WriteNpy(const std::string& path, std::span<const int64_t> shape,
                std::span<const float> data) {
  Result<std::vector<uint8_t>> bytes = SerializeNpy(shape, data);
  if (!bytes.ok()) return Status::Error(path + ": " + bytes.message());
  return WriteFileAtomically(path, *bytes);
}

}  // namespace sfrt::io
