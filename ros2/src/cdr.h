// CDR (XCDR1, "plain CDR") primitives: the encoding ROS 2 messages have on the DDS wire and in
// rosbag2 bags (MCAP message_encoding "cdr", sqlite3 .db3 rows).
//
// Format (DDS-XTypes 7.4.1 / DDSI-RTPS 10; checked against Fast-CDR Cdr.cpp, rmw_cyclonedds
// Serialization.cpp and @foxglove/cdr, see /tmp/cdr_helper_notes.md):
//   * A 4-byte encapsulation header: 0x00 then 0x01 for little-endian (CDR_LE) or 0x00 for
//     big-endian (CDR_BE), then two option bytes that a reader ignores (RTPS says so).
//   * Fields follow with natural alignment: a primitive of size n (1, 2, 4 or 8) starts at a
//     multiple of n counted from the first byte AFTER the header. Padding bytes are not checked.
//   * string: uint32 length including the terminating NUL, the bytes, the NUL.
//   * sequence (T[]): uint32 element count, then the elements; a fixed array (T[9]) has no count.
//     An empty float64 sequence is not followed by alignment padding (as Fast-CDR writes it).
//   * A writer may pad the end of a message to a multiple of 4 (rmw_cyclonedds does on the wire
//     and in bags); CdrReader::Finish accepts up to 3 such bytes. CdrWriter does not pad, as
//     rmw_serialize (Fast DDS and Cyclone DDS) and @foxglove/rosmsg2-serialization do not.
//
// CdrWriter writes little-endian only. CdrReader reads both byte orders and refuses every other
// encapsulation (parameter lists PL_CDR, XCDR2) with an error saying which it found.
//
// Bounds: every CdrReader read is checked against the bytes left before anything is read or
// allocated. A string or sequence length is compared with the bytes left (for sequences of
// structs, times a lower bound of each element's size) BEFORE any container is resized, so a
// decoder never allocates more than a small multiple of its input, whatever the input declares.
//
// Errors name the message type, the field path and the byte offset in the input (header
// included), e.g. "sensor_msgs/msg/Image.data: sequence of 4294967295 bytes at offset 48, only 6
// left". For a string or sequence the offset is where its bytes begin, right after the count.
//
// Allocation: CdrWriter appends to a caller-owned vector and so reuses its capacity; CdrSizer
// counts the bytes a message will take so the caller can reserve once. CdrReader never allocates
// on success except through the containers the caller passes (ReadString, ReadByteSequence,
// ReadFloat64Sequence), which reuse their capacity; the *View reads never allocate.
//
// Thread-safety: none of these classes is shared; distinct instances may be used concurrently.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::ros2 {

// Size of the encapsulation header that starts every CDR message.
inline constexpr size_t kCdrHeaderSize = 4;
// The most trailing bytes a reader accepts after the last field: padding to a multiple of 4.
inline constexpr size_t kCdrMaxEndPadding = 3;

// Counts the bytes a message will take; same interface as CdrWriter, writes nothing.
class CdrSizer {
 public:
  CdrSizer() = default;
  void WriteBool(bool) { size_ += 1; }
  void WriteUint8(uint8_t) { size_ += 1; }
  void WriteInt32(int32_t) { Add(4, 4); }
  void WriteUint32(uint32_t) { Add(4, 4); }
  void WriteFloat64(double) { Add(8, 8); }
  void WriteString(std::string_view s) { Add(4, 4 + s.size() + 1); }
  void WriteSequenceLength(size_t) { Add(4, 4); }
  void WriteByteSequence(std::span<const uint8_t> bytes) { Add(4, 4 + bytes.size()); }
  void WriteFloat64Array(std::span<const double> values) {
    if (!values.empty()) Add(8, 8 * values.size());
  }
  void WriteFloat64Sequence(std::span<const double> values) {
    WriteSequenceLength(values.size());
    WriteFloat64Array(values);
  }
  // Total bytes, header included.
  size_t size() const { return size_; }

 private:
  void Add(size_t alignment, size_t bytes);
  size_t size_ = kCdrHeaderSize;
};

// Appends one little-endian CDR message to a caller-owned vector.
//
// Precondition (checked; a violation aborts rather than writing a corrupt stream): every string
// and sequence is shorter than 4 GiB, since CDR stores lengths as uint32.
class CdrWriter {
 public:
  // Appends the CDR_LE encapsulation header to *out; alignment counts from the byte after it.
  // *out must outlive the writer. Bytes already in *out are kept (they are not part of the
  // message); Encode functions clear it first.
  explicit CdrWriter(std::vector<uint8_t>* out);

  void WriteBool(bool value) { out_->push_back(value ? 1 : 0); }
  void WriteUint8(uint8_t value) { out_->push_back(value); }
  void WriteInt32(int32_t value) { WriteUint32(static_cast<uint32_t>(value)); }
  void WriteUint32(uint32_t value);
  void WriteFloat64(double value);
  void WriteString(std::string_view s);
  void WriteSequenceLength(size_t count);
  // uint8[]: count then the bytes.
  void WriteByteSequence(std::span<const uint8_t> bytes);
  // float64[N]: the values, no count.
  void WriteFloat64Array(std::span<const double> values);
  // float64[]: count then the values.
  void WriteFloat64Sequence(std::span<const double> values);

 private:
  void Align(size_t alignment);
  void AppendUint64(uint64_t value);
  std::vector<uint8_t>* out_;
  size_t origin_;  // index in *out_ of the first byte after the header
};

// Reads one CDR message from a byte span, every read bounds-checked.
//
// Usage: ReadEncapsulation(), the fields in order (each named for errors, nested structs and
// sequence elements inside a Scope), then Finish(). After an error the reader's position is
// unspecified; stop reading.
class CdrReader {
 public:
  // `type_name` (e.g. "sensor_msgs/msg/Image") starts every error message; it and `bytes` must
  // outlive the reader.
  CdrReader(std::span<const uint8_t> bytes, std::string_view type_name);

  // Names a nested struct or sequence element in error messages while it lives:
  // "type.header.stamp.sec", "type.status[2].name". Nesting deeper than kMaxDepth is read
  // correctly but reported at depth kMaxDepth.
  class Scope {
   public:
    Scope(CdrReader& reader, std::string_view field);
    Scope(CdrReader& reader, std::string_view field, size_t index);
    ~Scope();
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    CdrReader& reader_;
  };
  static constexpr size_t kMaxDepth = 6;

  // Reads the 4-byte header: CDR_LE or CDR_BE, anything else is refused.
  Status ReadEncapsulation();
  Status ReadBool(std::string_view field, bool* value);  // 0 or 1; any other byte is refused
  Status ReadUint8(std::string_view field, uint8_t* value);
  Status ReadInt32(std::string_view field, int32_t* value);
  Status ReadUint32(std::string_view field, uint32_t* value);
  Status ReadFloat64(std::string_view field, double* value);
  // A string must end in NUL (every ROS 2 writer puts one); a length of 0 reads as "" (Fast-CDR
  // writes it for a null char*). Reuses value's capacity.
  Status ReadString(std::string_view field, std::string* value);
  // As ReadString; *value points into the input.
  Status ReadStringView(std::string_view field, std::string_view* value);
  // uint8[]: reuses value's capacity.
  Status ReadByteSequence(std::string_view field, std::vector<uint8_t>* value);
  // uint8[]: *value points into the input.
  Status ReadByteSequenceView(std::string_view field, std::span<const uint8_t>* value);
  // float64[N] with N = values.size().
  Status ReadFloat64Array(std::string_view field, std::span<double> values);
  // float64[]: reuses value's capacity.
  Status ReadFloat64Sequence(std::string_view field, std::vector<double>* value);
  // The count of a sequence of structs whose encodings take at least `min_element_bytes` each
  // (0 counts as 1): refused when count * min_element_bytes exceeds the bytes left, so the caller
  // may resize its vector to `count` safely.
  Status ReadSequenceLength(std::string_view field, size_t min_element_bytes, uint32_t* count);
  // Succeeds when at most kCdrMaxEndPadding bytes are left.
  Status Finish() const;

  // Offset of the next byte to read, counted from the start of the input (header included).
  size_t offset() const { return pos_; }
  bool big_endian() const { return big_endian_; }

 private:
  struct Frame {
    std::string_view field;
    size_t index;
    bool indexed;
  };
  // Where a field of `alignment` bytes would start.
  size_t AlignedPosition(size_t alignment) const;
  // Aligns and consumes `bytes` bytes, returning where they start; nullptr (nothing consumed)
  // when they are not all there. Builds no message: the success path must not allocate.
  const uint8_t* Take(size_t alignment, size_t bytes);
  // The error for a field of `alignment` that does not fit: "<path>: <what> at offset N, only M
  // left".
  Status Truncated(std::string_view field, size_t alignment, const std::string& what) const;
  Status TakeCounted(std::string_view field, size_t element_bytes, std::string_view unit,
                     uint32_t* count, const uint8_t** at);
  Status ReadStringBytes(std::string_view field, std::string_view* value);
  Status Error(std::string_view field, const std::string& what) const;
  std::string Path(std::string_view field) const;
  uint32_t Load32(const uint8_t* p) const;
  uint64_t Load64(const uint8_t* p) const;

  std::span<const uint8_t> bytes_;
  std::string_view type_name_;
  size_t pos_ = 0;
  bool big_endian_ = false;
  Frame frames_[kMaxDepth] = {};
  size_t depth_ = 0;  // may exceed kMaxDepth; frames past it are not recorded
};

}  // namespace sfrt::ros2
