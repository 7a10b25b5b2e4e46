#include "cdr.h"

#include <bit>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>

namespace sfrt::ros2 {
namespace {

// Padding before a field of `alignment` bytes at `offset` bytes past the header.
size_t PaddingFor(size_t offset, size_t alignment) {
  return (alignment - offset % alignment) % alignment;
}

// CDR stores every length as uint32; a longer string or sequence cannot be written. Aborting is
// deliberate: Encode has no error channel and a silently truncated length corrupts the stream.
uint32_t CheckedLength(size_t length, const char* what) {
  if (length > std::numeric_limits<uint32_t>::max()) {
    std::fprintf(stderr,
                 "sfrt::ros2::CdrWriter: %s of %zu bytes does not fit CDR's uint32 length\n", what,
                 length);
    std::abort();
  }
  return static_cast<uint32_t>(length);
}

// Names of the RTPS representation identifiers (DDSI-RTPS 10.5), for refusals.
const char* EncapsulationName(uint8_t id) {
  switch (id) {
    case 0x02:
      return "PL_CDR_BE";
    case 0x03:
      return "PL_CDR_LE";
    case 0x04:
    case 0x05:
      return "XML";
    case 0x06:
      return "CDR2_BE";
    case 0x07:
      return "CDR2_LE";
    case 0x08:
      return "D_CDR2_BE";
    case 0x09:
      return "D_CDR2_LE";
    case 0x0a:
      return "PL_CDR2_BE";
    case 0x0b:
      return "PL_CDR2_LE";
    default:
      return "unknown";
  }
}

std::string Hex2(uint8_t a, uint8_t b) {
  char text[8];
  std::snprintf(text, sizeof(text), "%02x %02x", a, b);
  return text;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// CdrSizer

void CdrSizer::Add(size_t alignment, size_t bytes) {
  size_ += PaddingFor(size_ - kCdrHeaderSize, alignment) + bytes;
}

// ---------------------------------------------------------------------------------------------
// CdrWriter

CdrWriter::CdrWriter(std::vector<uint8_t>* out) : out_(out), origin_(out->size() + kCdrHeaderSize) {
  const uint8_t header[kCdrHeaderSize] = {0x00, 0x01, 0x00, 0x00};  // CDR_LE, no options
  out_->insert(out_->end(), header, header + kCdrHeaderSize);
}

void CdrWriter::Align(size_t alignment) {
  // resize value-initialises: padding bytes are zero, as rmw_cyclonedds writes them.
  out_->resize(out_->size() + PaddingFor(out_->size() - origin_, alignment));
}

void CdrWriter::WriteUint32(uint32_t value) {
  Align(4);
  const uint8_t bytes[4] = {static_cast<uint8_t>(value), static_cast<uint8_t>(value >> 8),
                            static_cast<uint8_t>(value >> 16), static_cast<uint8_t>(value >> 24)};
  out_->insert(out_->end(), bytes, bytes + 4);
}

void CdrWriter::AppendUint64(uint64_t value) {
  uint8_t bytes[8];
  for (int i = 0; i < 8; ++i) bytes[i] = static_cast<uint8_t>(value >> (8 * i));
  out_->insert(out_->end(), bytes, bytes + 8);
}

void CdrWriter::WriteFloat64(double value) {
  Align(8);
  AppendUint64(std::bit_cast<uint64_t>(value));
}

void CdrWriter::WriteString(std::string_view s) {
  WriteUint32(CheckedLength(s.size() + 1, "string"));
  out_->insert(out_->end(), s.begin(), s.end());
  out_->push_back(0);
}

void CdrWriter::WriteSequenceLength(size_t count) { WriteUint32(CheckedLength(count, "sequence")); }

void CdrWriter::WriteByteSequence(std::span<const uint8_t> bytes) {
  WriteSequenceLength(bytes.size());
  out_->insert(out_->end(), bytes.begin(), bytes.end());
}

void CdrWriter::WriteFloat64Array(std::span<const double> values) {
  if (values.empty()) return;  // no alignment for nothing, as Fast-CDR serialize_array
  Align(8);
  for (double v : values) AppendUint64(std::bit_cast<uint64_t>(v));
}

void CdrWriter::WriteFloat64Sequence(std::span<const double> values) {
  WriteSequenceLength(values.size());
  WriteFloat64Array(values);
}

// ---------------------------------------------------------------------------------------------
// CdrReader

CdrReader::CdrReader(std::span<const uint8_t> bytes, std::string_view type_name)
    : bytes_(bytes), type_name_(type_name) {}

CdrReader::Scope::Scope(CdrReader& reader, std::string_view field) : reader_(reader) {
  if (reader_.depth_ < kMaxDepth) reader_.frames_[reader_.depth_] = {field, 0, false};
  ++reader_.depth_;
}

CdrReader::Scope::Scope(CdrReader& reader, std::string_view field, size_t index) : reader_(reader) {
  if (reader_.depth_ < kMaxDepth) reader_.frames_[reader_.depth_] = {field, index, true};
  ++reader_.depth_;
}

CdrReader::Scope::~Scope() { --reader_.depth_; }

std::string CdrReader::Path(std::string_view field) const {
  std::string path(type_name_);
  const size_t recorded = depth_ < kMaxDepth ? depth_ : kMaxDepth;
  for (size_t i = 0; i < recorded; ++i) {
    path += '.';
    path += frames_[i].field;
    if (frames_[i].indexed) path += "[" + std::to_string(frames_[i].index) + "]";
  }
  if (!field.empty()) {
    path += '.';
    path += field;
  }
  return path;
}

Status CdrReader::Error(std::string_view field, const std::string& what) const {
  return Status::Error(Path(field) + ": " + what);
}

uint32_t CdrReader::Load32(const uint8_t* p) const {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) {
    const int shift = big_endian_ ? 8 * (3 - i) : 8 * i;
    v |= static_cast<uint32_t>(p[i]) << shift;
  }
  return v;
}

uint64_t CdrReader::Load64(const uint8_t* p) const {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) {
    const int shift = big_endian_ ? 8 * (7 - i) : 8 * i;
    v |= static_cast<uint64_t>(p[i]) << shift;
  }
  return v;
}

size_t CdrReader::AlignedPosition(size_t alignment) const {
  // Alignment counts from the byte after the header.
  const size_t body = pos_ >= kCdrHeaderSize ? pos_ - kCdrHeaderSize : 0;
  return pos_ + PaddingFor(body, alignment);
}

const uint8_t* CdrReader::Take(size_t alignment, size_t bytes) {
  const size_t start = AlignedPosition(alignment);
  if (start > bytes_.size() || bytes > bytes_.size() - start) return nullptr;
  pos_ = start + bytes;
  return bytes_.data() + start;
}

Status CdrReader::Truncated(std::string_view field, size_t alignment,
                            const std::string& what) const {
  const size_t start = AlignedPosition(alignment);
  const size_t left = start <= bytes_.size() ? bytes_.size() - start : 0;
  return Error(field, what + " at offset " + std::to_string(start) + ", only " +
                          std::to_string(left) + " left");
}

Status CdrReader::ReadEncapsulation() {
  if (bytes_.size() < kCdrHeaderSize) {
    return Status::Error(std::string(type_name_) + ": " + std::to_string(bytes_.size()) +
                         " bytes cannot hold the 4-byte CDR encapsulation header");
  }
  const uint8_t hi = bytes_[0];
  const uint8_t lo = bytes_[1];
  if (hi != 0 || lo > 1) {
    return Status::Error(std::string(type_name_) + ": encapsulation " + Hex2(hi, lo) + " (" +
                         (hi == 0 ? EncapsulationName(lo) : "unknown") +
                         ") is not supported; expected plain CDR: 00 01 (little-endian) or 00 00 "
                         "(big-endian)");
  }
  big_endian_ = lo == 0;
  pos_ = kCdrHeaderSize;  // the two option bytes are not interpreted (DDSI-RTPS 10.2)
  return Status::Ok();
}

Status CdrReader::ReadBool(std::string_view field, bool* value) {
  const uint8_t* at = Take(1, 1);
  if (at == nullptr) return Truncated(field, 1, "bool");
  if (*at > 1) {
    return Error(field, "bool at offset " + std::to_string(pos_ - 1) + " is " +
                            std::to_string(*at) + ", not 0 or 1");
  }
  *value = *at == 1;
  return Status::Ok();
}

Status CdrReader::ReadUint8(std::string_view field, uint8_t* value) {
  const uint8_t* at = Take(1, 1);
  if (at == nullptr) return Truncated(field, 1, "uint8");
  *value = *at;
  return Status::Ok();
}

Status CdrReader::ReadInt32(std::string_view field, int32_t* value) {
  const uint8_t* at = Take(4, 4);
  if (at == nullptr) return Truncated(field, 4, "int32");
  *value = static_cast<int32_t>(Load32(at));
  return Status::Ok();
}

Status CdrReader::ReadUint32(std::string_view field, uint32_t* value) {
  const uint8_t* at = Take(4, 4);
  if (at == nullptr) return Truncated(field, 4, "uint32");
  *value = Load32(at);
  return Status::Ok();
}

Status CdrReader::ReadFloat64(std::string_view field, double* value) {
  const uint8_t* at = Take(8, 8);
  if (at == nullptr) return Truncated(field, 8, "float64");
  *value = std::bit_cast<double>(Load64(at));
  return Status::Ok();
}

// Reads a uint32 count, then checks that count elements of element_bytes each fit in what is
// left (aligned to element_bytes when there is at least one): nothing is sized from the count
// before this check.
Status CdrReader::TakeCounted(std::string_view field, size_t element_bytes, std::string_view unit,
                              uint32_t* count, const uint8_t** at) {
  if (Status s = ReadUint32(field, count); !s.ok()) return s;
  if (*count == 0) {
    *at = bytes_.data() + pos_;
    return Status::Ok();
  }
  const size_t alignment = element_bytes >= 8 ? 8 : element_bytes;
  // A count that cannot fit is made SIZE_MAX bytes rather than multiplied: no overflow where
  // size_t has 32 bits, and Take still finds it too long.
  const size_t total = *count > bytes_.size() / element_bytes
                           ? std::numeric_limits<size_t>::max()
                           : static_cast<size_t>(*count) * element_bytes;
  *at = Take(alignment, total);
  if (*at == nullptr) {
    return Truncated(field, alignment,
                     "sequence of " + std::to_string(*count) + " " + std::string(unit));
  }
  return Status::Ok();
}

Status CdrReader::ReadStringBytes(std::string_view field, std::string_view* value) {
  uint32_t length = 0;
  if (Status s = ReadUint32(field, &length); !s.ok()) return s;
  if (length == 0) {
    *value = {};
    return Status::Ok();
  }
  const uint8_t* at = Take(1, length);
  if (at == nullptr) return Truncated(field, 1, "string of " + std::to_string(length) + " bytes");
  if (at[length - 1] != 0) {
    return Error(field, "string of " + std::to_string(length) + " bytes at offset " +
                            std::to_string(pos_ - length) + " does not end in NUL");
  }
  *value = std::string_view(reinterpret_cast<const char*>(at), length - 1);
  return Status::Ok();
}

Status CdrReader::ReadString(std::string_view field, std::string* value) {
  std::string_view view;
  if (Status s = ReadStringBytes(field, &view); !s.ok()) return s;
  value->assign(view.data(), view.size());
  return Status::Ok();
}

Status CdrReader::ReadStringView(std::string_view field, std::string_view* value) {
  return ReadStringBytes(field, value);
}

Status CdrReader::ReadByteSequenceView(std::string_view field, std::span<const uint8_t>* value) {
  uint32_t count = 0;
  const uint8_t* at = nullptr;
  if (Status s = TakeCounted(field, 1, "bytes", &count, &at); !s.ok()) return s;
  *value = std::span<const uint8_t>(at, count);
  return Status::Ok();
}

Status CdrReader::ReadByteSequence(std::string_view field, std::vector<uint8_t>* value) {
  std::span<const uint8_t> view;
  if (Status s = ReadByteSequenceView(field, &view); !s.ok()) return s;
  value->assign(view.begin(), view.end());
  return Status::Ok();
}

Status CdrReader::ReadFloat64Array(std::string_view field, std::span<double> values) {
  if (values.empty()) return Status::Ok();
  const uint8_t* at = Take(8, 8 * values.size());
  if (at == nullptr) {
    return Truncated(field, 8, "float64[" + std::to_string(values.size()) + "]");
  }
  for (size_t i = 0; i < values.size(); ++i) values[i] = std::bit_cast<double>(Load64(at + 8 * i));
  return Status::Ok();
}

Status CdrReader::ReadFloat64Sequence(std::string_view field, std::vector<double>* value) {
  uint32_t count = 0;
  const uint8_t* at = nullptr;
  if (Status s = TakeCounted(field, 8, "float64", &count, &at); !s.ok()) return s;
  value->resize(count);
  for (size_t i = 0; i < count; ++i) (*value)[i] = std::bit_cast<double>(Load64(at + 8 * i));
  return Status::Ok();
}

Status CdrReader::ReadSequenceLength(std::string_view field, size_t min_element_bytes,
                                     uint32_t* count) {
  if (Status s = ReadUint32(field, count); !s.ok()) return s;
  const size_t left = bytes_.size() - pos_;
  const size_t min_bytes = min_element_bytes > 0 ? min_element_bytes : 1;
  // Division, not multiplication: no overflow whatever the count.
  if (*count > left / min_bytes) {
    return Error(field, "sequence of " + std::to_string(*count) + " elements of at least " +
                            std::to_string(min_bytes) + " bytes at offset " + std::to_string(pos_) +
                            ", only " + std::to_string(left) + " left");
  }
  return Status::Ok();
}

Status CdrReader::Finish() const {
  const size_t left = bytes_.size() - pos_;
  if (left > kCdrMaxEndPadding) {
    return Status::Error(std::string(type_name_) + ": " + std::to_string(left) +
                         " bytes follow the message at offset " + std::to_string(pos_) +
                         "; at most " + std::to_string(kCdrMaxEndPadding) +
                         " bytes of end padding are allowed");
  }
  return Status::Ok();
}

}  // namespace sfrt::ros2
