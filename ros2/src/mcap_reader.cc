// The MCAP reader (mcap.h states the contract) and the CRC-32 both sides use.
#include <fcntl.h>
#include <lz4frame.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <string_view>
#include <utility>

#include "mcap.h"

namespace sfrt::ros2::mcap {
namespace {

constexpr uint64_t kRecordHeaderSize = 9;              // opcode u8 + content length u64
constexpr uint64_t kFooterRecordSize = 9 + 20;         // the Footer never grows (spec)
constexpr uint64_t kDataEndRecordSize = 9 + 4;         // nor does DataEnd
constexpr uint64_t kMessageFixedSize = 2 + 4 + 8 + 8;  // channel, sequence, log and publish time
// One record's content, at most: a whole chunk plus the Chunk record's own fields, with room
// for a codec's expansion of incompressible data.
constexpr uint64_t kMaxRecordSize = kMaxChunkSize + (uint64_t{1} << 20);
// The most one compressed byte can decompress to. zstd: a 4-byte RLE block (3-byte header, one
// byte) yields at most one 128 KiB block. lz4: each extra length byte adds at most 255 bytes.
constexpr uint64_t kZstdMaxRatio = 32768;
constexpr uint64_t kLz4MaxRatio = 256;
constexpr uint64_t kCodecSlack = uint64_t{1} << 17;  // one block of either codec
constexpr size_t kSkipPiece = size_t{1} << 16;       // read size when skipping under a CRC

// CRC-32, reflected polynomial 0xEDB88320, computed 8 bytes at a time (slicing-by-8).
using CrcTables = std::array<std::array<uint32_t, 256>, 8>;

constexpr CrcTables MakeCrcTables() {
  CrcTables t{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) != 0 ? (c >> 1) ^ 0xEDB88320u : c >> 1;
    t[0][i] = c;
  }
  for (size_t s = 1; s < 8; ++s) {
    for (size_t i = 0; i < 256; ++i) t[s][i] = (t[s - 1][i] >> 8) ^ t[0][t[s - 1][i] & 0xFF];
  }
  return t;
}

constexpr CrcTables kCrcTables = MakeCrcTables();

uint16_t Le16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }

uint32_t Le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

uint64_t Le64(const uint8_t* p) {
  return static_cast<uint64_t>(Le32(p)) | (static_cast<uint64_t>(Le32(p + 4)) << 32);
}

std::string Hex32(uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof(text), "0x%08x", value);
  return text;
}

// Text from the file, made safe for a one-line error message: escaped and shortened.
std::string Printable(std::string_view text) {
  std::string out;
  for (size_t i = 0; i < text.size() && i < 40; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7F && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\x%02x", c);
      out += escaped;
    }
  }
  if (text.size() > 40) out += "...";
  return out;
}

std::string RecordName(uint8_t opcode) {
  static constexpr const char* kNames[] = {
      nullptr,    "Header",        "Footer",        "Schema",     "Channel",         "Message",
      "Chunk",    "MessageIndex",  "ChunkIndex",    "Attachment", "AttachmentIndex", "Statistics",
      "Metadata", "MetadataIndex", "SummaryOffset", "DataEnd"};
  if (opcode != 0 && opcode < std::size(kNames)) return kNames[opcode];
  char text[24];
  std::snprintf(text, sizeof(text), "record 0x%02x", opcode);
  return text;
}

// Reads the fields of one record's content; every read first checks the bytes left, and a
// failed read remembers what it wanted for the error message.
class Cursor {
 public:
  explicit Cursor(std::span<const uint8_t> bytes) : bytes_(bytes) {}

  size_t remaining() const { return bytes_.size() - pos_; }

  bool Take(uint64_t size, std::span<const uint8_t>* out) {
    if (size > remaining()) {
      wanted_ = size;
      return false;
    }
    *out = bytes_.subspan(pos_, static_cast<size_t>(size));
    pos_ += static_cast<size_t>(size);
    return true;
  }
  bool U16(uint16_t* v) {
    return Fixed(2, [&](const uint8_t* p) { *v = Le16(p); });
  }
  bool U32(uint32_t* v) {
    return Fixed(4, [&](const uint8_t* p) { *v = Le32(p); });
  }
  bool U64(uint64_t* v) {
    return Fixed(8, [&](const uint8_t* p) { *v = Le64(p); });
  }
  bool String(std::string* s) {
    std::span<const uint8_t> bytes;
    if (!Prefixed(&bytes)) return false;
    s->assign(reinterpret_cast<const char*>(bytes.data()), bytes.size());
    return true;
  }
  bool Bytes(std::vector<uint8_t>* v) {
    std::span<const uint8_t> bytes;
    if (!Prefixed(&bytes)) return false;
    v->assign(bytes.begin(), bytes.end());
    return true;
  }
  // A uint32 byte length and that many bytes (String, Bytes, Map and Array all start so).
  bool Prefixed(std::span<const uint8_t>* out) {
    uint32_t size = 0;
    return U32(&size) && Take(size, out);
  }
  std::string Missing(const char* field) const {
    return "field '" + std::string(field) + "' needs " + std::to_string(wanted_) +
           " bytes but only " + std::to_string(remaining()) + " are left";
  }

 private:
  template <typename Store>
  bool Fixed(size_t size, Store store) {
    std::span<const uint8_t> bytes;
    if (!Take(size, &bytes)) return false;
    store(bytes.data());
    return true;
  }

  std::span<const uint8_t> bytes_;
  size_t pos_ = 0;
  uint64_t wanted_ = 0;
};

// Each Parse function returns "" or what is wrong with the record's content.
std::string ParseStringMap(Cursor* c, const char* field, std::map<std::string, std::string>* out) {
  std::span<const uint8_t> bytes;
  if (!c->Prefixed(&bytes)) return c->Missing(field);
  Cursor entries(bytes);
  while (entries.remaining() > 0) {
    std::string key, value;
    if (!entries.String(&key)) return entries.Missing("metadata key");
    if (!entries.String(&value)) return entries.Missing("metadata value");
    out->insert_or_assign(std::move(key), std::move(value));  // duplicates: the last wins
  }
  return {};
}

std::string ParseSchema(std::span<const uint8_t> body, Schema* s) {
  Cursor c(body);
  if (!c.U16(&s->id)) return c.Missing("id");
  if (!c.String(&s->name)) return c.Missing("name");
  if (!c.String(&s->encoding)) return c.Missing("encoding");
  if (!c.Bytes(&s->data)) return c.Missing("data");
  return {};
}

std::string ParseChannel(std::span<const uint8_t> body, Channel* ch) {
  Cursor c(body);
  if (!c.U16(&ch->id)) return c.Missing("id");
  if (!c.U16(&ch->schema_id)) return c.Missing("schema_id");
  if (!c.String(&ch->topic)) return c.Missing("topic");
  if (!c.String(&ch->message_encoding)) return c.Missing("message_encoding");
  return ParseStringMap(&c, "metadata", &ch->metadata);
}

std::string ParseStatistics(std::span<const uint8_t> body, Statistics* s) {
  Cursor c(body);
  if (!c.U64(&s->message_count)) return c.Missing("message_count");
  if (!c.U16(&s->schema_count)) return c.Missing("schema_count");
  if (!c.U32(&s->channel_count)) return c.Missing("channel_count");
  if (!c.U32(&s->attachment_count)) return c.Missing("attachment_count");
  if (!c.U32(&s->metadata_count)) return c.Missing("metadata_count");
  if (!c.U32(&s->chunk_count)) return c.Missing("chunk_count");
  if (!c.U64(&s->message_start_time)) return c.Missing("message_start_time");
  if (!c.U64(&s->message_end_time)) return c.Missing("message_end_time");
  std::span<const uint8_t> counts;
  if (!c.Prefixed(&counts)) return c.Missing("channel_message_counts");
  if (counts.size() % 10 != 0) {
    return "channel_message_counts holds " + std::to_string(counts.size()) +
           " bytes, not a whole number of 10-byte entries";
  }
  for (size_t at = 0; at < counts.size(); at += 10) {
    s->channel_message_counts[Le16(counts.data() + at)] = Le64(counts.data() + at + 2);
  }
  return {};
}

struct ChunkFields {
  uint64_t message_start_time = 0;
  uint64_t message_end_time = 0;
  uint64_t uncompressed_size = 0;
  uint32_t uncompressed_crc = 0;
  std::string compression;
  std::span<const uint8_t> records;
};

std::string ParseChunk(std::span<const uint8_t> body, ChunkFields* chunk) {
  Cursor c(body);
  if (!c.U64(&chunk->message_start_time)) return c.Missing("message_start_time");
  if (!c.U64(&chunk->message_end_time)) return c.Missing("message_end_time");
  if (!c.U64(&chunk->uncompressed_size)) return c.Missing("uncompressed_size");
  if (!c.U32(&chunk->uncompressed_crc)) return c.Missing("uncompressed_crc");
  if (!c.String(&chunk->compression)) return c.Missing("compression");
  uint64_t size = 0;
  if (!c.U64(&size)) return c.Missing("records length");
  if (!c.Take(size, &chunk->records)) return c.Missing("records");
  return {};
}

}  // namespace

uint32_t Crc32(std::span<const uint8_t> bytes, uint32_t crc) {
  const auto& t = kCrcTables;
  uint32_t c = ~crc;
  const uint8_t* p = bytes.data();
  size_t n = bytes.size();
  for (; n >= 8; p += 8, n -= 8) {
    const uint32_t lo = c ^ Le32(p);
    const uint32_t hi = Le32(p + 4);
    c = t[7][lo & 0xFF] ^ t[6][(lo >> 8) & 0xFF] ^ t[5][(lo >> 16) & 0xFF] ^ t[4][lo >> 24] ^
        t[3][hi & 0xFF] ^ t[2][(hi >> 8) & 0xFF] ^ t[1][(hi >> 16) & 0xFF] ^ t[0][hi >> 24];
  }
  for (; n > 0; ++p, --n) c = t[0][(c ^ *p) & 0xFF] ^ (c >> 8);
  return ~c;
}

// A record's position: its file offset, or its offset in the records of the chunk at
// chunk_offset.
struct Reader::Where {
  uint8_t opcode = 0;
  uint64_t offset = 0;
  std::optional<uint64_t> chunk_offset;
};

struct Reader::Decompressor {
  ZSTD_DCtx* zstd = nullptr;
  LZ4F_dctx* lz4 = nullptr;

  ~Decompressor() {
    ZSTD_freeDCtx(zstd);
    LZ4F_freeDecompressionContext(lz4);
  }

  // Each returns "" or the codec's complaint; `out` must come out exactly full.
  std::string Zstd(std::span<const uint8_t> in, std::span<uint8_t> out) {
    if (zstd == nullptr && (zstd = ZSTD_createDCtx()) == nullptr)
      return "cannot create a zstd context";
    const size_t size = ZSTD_decompressDCtx(zstd, out.data(), out.size(), in.data(), in.size());
    if (ZSTD_isError(size)) return std::string("zstd: ") + ZSTD_getErrorName(size);
    if (size != out.size()) {
      return "zstd data decompresses to " + std::to_string(size) + " bytes, not the " +
             std::to_string(out.size()) + " the chunk declares";
    }
    return {};
  }

  std::string Lz4(std::span<const uint8_t> in, std::span<uint8_t> out) {
    if (lz4 == nullptr && LZ4F_isError(LZ4F_createDecompressionContext(&lz4, LZ4F_VERSION))) {
      return "cannot create an lz4 context";
    }
    LZ4F_resetDecompressionContext(lz4);  // a failed chunk leaves it mid-frame
    uint8_t unused = 0;                   // a non-null destination for an empty chunk
    size_t in_pos = 0, out_pos = 0, hint = 1;
    while (in_pos < in.size()) {
      size_t out_size = out.size() - out_pos, in_size = in.size() - in_pos;
      uint8_t* dst = out.empty() ? &unused : out.data() + out_pos;
      hint = LZ4F_decompress(lz4, dst, &out_size, in.data() + in_pos, &in_size, nullptr);
      if (LZ4F_isError(hint)) return std::string("lz4: ") + LZ4F_getErrorName(hint);
      if (in_size == 0 && out_size == 0) {
        return "lz4 data decompresses to more than the " + std::to_string(out.size()) +
               " bytes the chunk declares";
      }
      in_pos += in_size;
      out_pos += out_size;
    }
    if (hint != 0) return "the lz4 frame ends before its end mark";
    if (out_pos != out.size()) {
      return "lz4 data decompresses to " + std::to_string(out_pos) + " bytes, not the " +
             std::to_string(out.size()) + " the chunk declares";
    }
    return {};
  }
};

Reader::Reader() = default;

Reader::~Reader() {
  if (fd_ >= 0) ::close(fd_);
}

Status Reader::Fail(const std::string& what) const {
  return Status::Error("'" + path_ + "': " + what);
}

Status Reader::Fail(const Where& where, const std::string& what) const {
  std::string text = RecordName(where.opcode) + " at offset " + std::to_string(where.offset);
  if (where.chunk_offset) text += " in the chunk at offset " + std::to_string(*where.chunk_offset);
  return Fail(text + ": " + what);
}

Status Reader::ReadAt(uint64_t offset, size_t size, uint8_t* out) const {
  while (size > 0) {
    const ssize_t n = ::pread(fd_, out, size, static_cast<off_t>(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      return Fail("cannot read " + std::to_string(size) + " bytes at offset " +
                  std::to_string(offset) + ": " + std::strerror(errno));
    }
    if (n == 0) return Fail("the file ended at offset " + std::to_string(offset) + " (it shrank?)");
    out += n;
    size -= static_cast<size_t>(n);
    offset += static_cast<uint64_t>(n);
  }
  return Status::Ok();
}

void Reader::SetChannelFilter(std::optional<std::set<uint16_t>> channel_ids) {
  filter_ = std::move(channel_ids);
}

std::optional<uint64_t> Reader::message_count(uint16_t channel_id) const {
  if (!statistics_ || statistics_->channel_message_counts.empty()) return std::nullopt;
  const auto it = statistics_->channel_message_counts.find(channel_id);
  if (it != statistics_->channel_message_counts.end()) return it->second;
  if (channels_.count(channel_id) != 0) return 0;  // counted channels, this one had none
  return std::nullopt;
}

Status Reader::Open(const std::string& path) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  path_ = path;
  profile_.clear();
  library_.clear();
  schemas_.clear();
  channels_.clear();
  statistics_.reset();
  open_ = done_ = false;
  failed_ = Status::Ok();
  chunk_ = {};
  chunk_pos_ = 0;
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) return Fail(std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd_, &st) != 0) return Fail(std::string("cannot stat: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return Fail("not a regular file");
  file_size_ = static_cast<uint64_t>(st.st_size);
  Footer footer;
  if (Status s = ReadMagicAndHeader(); !s.ok()) return s;
  if (Status s = ReadFooter(&footer); !s.ok()) return s;
  if (Status s = ReadSummary(footer); !s.ok()) return s;
  if (Status s = PrepareDataScan(footer); !s.ok()) return s;
  open_ = true;
  return Status::Ok();
}

Status Reader::ReadMagicAndHeader() {
  uint8_t start[sizeof(kMagic) + kRecordHeaderSize];
  if (file_size_ < sizeof(start)) {
    return Fail("the file ends at offset " + std::to_string(file_size_) +
                ", too soon for the MCAP magic and a Header: it is truncated or not MCAP");
  }
  if (Status s = ReadAt(0, sizeof(start), start); !s.ok()) return s;
  if (std::memcmp(start, kMagic, 5) != 0 || start[6] != '\r' || start[7] != '\n') {
    return Fail("offset 0: not an MCAP file (the magic bytes are wrong)");
  }
  if (start[5] != kMagic[5]) {
    return Fail("offset 0: MCAP major version '" + Printable(std::string(1, char(start[5]))) +
                "' is not supported (only '0')");
  }
  const Where where{start[8], sizeof(kMagic), std::nullopt};
  if (where.opcode != static_cast<uint8_t>(Opcode::kHeader)) {
    return Fail(where, "the first record must be a Header");
  }
  const uint64_t length = Le64(start + 9);
  if (length > file_size_ - sizeof(start) || length > kMaxRecordSize) {
    return Fail(where, "length " + std::to_string(length) + " runs past the end of the file (" +
                           std::to_string(file_size_) + " bytes)");
  }
  record_.resize(static_cast<size_t>(length));
  if (Status s = ReadAt(sizeof(start), record_.size(), record_.data()); !s.ok()) return s;
  Cursor c(record_);
  if (!c.String(&profile_)) return Fail(where, c.Missing("profile"));
  if (!c.String(&library_)) return Fail(where, c.Missing("library"));
  data_crc_ = Crc32(record_, Crc32(start));
  offset_ = sizeof(start) + length;
  return Status::Ok();
}

Status Reader::ReadFooter(Footer* footer) {
  uint8_t tail[kFooterRecordSize + sizeof(kMagic)];
  if (file_size_ < offset_ + sizeof(tail)) {
    return Fail("the file ends at offset " + std::to_string(file_size_) +
                " without a Footer and the closing magic: it is truncated or still being written");
  }
  footer->offset = file_size_ - sizeof(tail);
  if (Status s = ReadAt(footer->offset, sizeof(tail), tail); !s.ok()) return s;
  if (std::memcmp(tail + kFooterRecordSize, kMagic, sizeof(kMagic)) != 0) {
    return Fail("no closing magic at offset " + std::to_string(file_size_ - sizeof(kMagic)) +
                ": the file is truncated or still being written");
  }
  const Where where{tail[0], footer->offset, std::nullopt};
  if (tail[0] != static_cast<uint8_t>(Opcode::kFooter) || Le64(tail + 1) != 20) {
    return Fail(where, "expected a Footer (opcode 0x02, length 20) before the closing magic");
  }
  footer->summary_start = Le64(tail + 9);
  footer->summary_offset_start = Le64(tail + 17);
  footer->summary_crc = Le32(tail + 25);
  std::memcpy(footer->prefix, tail, sizeof(footer->prefix));
  return Status::Ok();
}

Status Reader::ReadSummary(const Footer& footer) {
  const Where where{static_cast<uint8_t>(Opcode::kFooter), footer.offset, std::nullopt};
  const uint64_t header_end = offset_;
  const auto outside = [&](uint64_t at, uint64_t from) { return at < from || at > footer.offset; };
  if (footer.summary_start != 0 && outside(footer.summary_start, header_end)) {
    return Fail(where, "summary_start " + std::to_string(footer.summary_start) +
                           " lies outside the records between the Header and the Footer");
  }
  const uint64_t start = footer.summary_start != 0 ? footer.summary_start : header_end;
  if (footer.summary_offset_start != 0 && outside(footer.summary_offset_start, start)) {
    return Fail(where, "summary_offset_start " + std::to_string(footer.summary_offset_start) +
                           " lies outside the summary");
  }
  const uint64_t begin = footer.summary_start != 0          ? footer.summary_start
                         : footer.summary_offset_start != 0 ? footer.summary_offset_start
                                                            : footer.offset;
  data_limit_ = begin;
  if (begin == footer.offset) return Status::Ok();  // no summary
  if (footer.offset - begin > kMaxSummarySize) {
    return Fail(where, "the summary section's " + std::to_string(footer.offset - begin) +
                           " bytes exceed the " + std::to_string(kMaxSummarySize) + "-byte limit");
  }
  std::vector<uint8_t> summary(static_cast<size_t>(footer.offset - begin));
  if (Status s = ReadAt(begin, summary.size(), summary.data()); !s.ok()) return s;
  if (footer.summary_crc != 0) {
    const uint32_t crc = Crc32(footer.prefix, Crc32(summary));
    if (crc != footer.summary_crc) {
      return Fail(where, "the summary's CRC " + Hex32(crc) + " does not match the Footer's " +
                             Hex32(footer.summary_crc));
    }
  }
  for (size_t pos = 0; pos < summary.size();) {
    const Where at{summary[pos], begin + pos, std::nullopt};
    const size_t left = summary.size() - pos;
    const uint64_t length = left < kRecordHeaderSize ? 0 : Le64(summary.data() + pos + 1);
    if (left < kRecordHeaderSize || length > left - kRecordHeaderSize) {
      return Fail(at, "the record runs past the end of the summary at offset " +
                          std::to_string(footer.offset));
    }
    const std::span<const uint8_t> body(summary.data() + pos + kRecordHeaderSize, length);
    if (Status s = ReadSummaryRecord(at, body); !s.ok()) return s;
    pos += kRecordHeaderSize + length;
  }
  for (const auto& [id, channel] : channels_) {
    if (channel.schema_id != 0 && schemas_.count(channel.schema_id) == 0) {
      return Fail("summary: Channel " + std::to_string(id) + " ('" + Printable(channel.topic) +
                  "') refers to schema " + std::to_string(channel.schema_id) +
                  ", which the summary does not hold");
    }
  }
  return Status::Ok();
}

Status Reader::ReadSummaryRecord(const Where& where, std::span<const uint8_t> body) {
  switch (static_cast<Opcode>(where.opcode)) {
    case Opcode::kSchema:
      return AddSchema(where, body);
    case Opcode::kChannel:
      return AddChannel(where, body);  // its schema may come later in the summary
    case Opcode::kStatistics: {
      if (statistics_) return Fail(where, "a second Statistics record");
      Statistics statistics;
      if (std::string error = ParseStatistics(body, &statistics); !error.empty()) {
        return Fail(where, error);
      }
      statistics_ = std::move(statistics);
      return Status::Ok();
    }
    default:
      if (where.opcode == 0) return Fail(where, "opcode 0 is not a valid record");
      return Status::Ok();  // indexes and unknown records: not needed to stream messages
  }
}

Status Reader::PrepareDataScan(const Footer& footer) {
  // The data-section CRC costs a pass over every byte, skipped records included: pay it only
  // when DataEnd holds one. Without a summary, DataEnd's place is unknown until the scan meets
  // it, so the CRC is computed and used if it turns out to be non-zero.
  check_data_crc_ = true;
  if (footer.summary_start != 0 && footer.summary_start - offset_ >= kDataEndRecordSize) {
    uint8_t data_end[kDataEndRecordSize];
    if (Status s = ReadAt(footer.summary_start - sizeof(data_end), sizeof(data_end), data_end);
        !s.ok()) {
      return s;
    }
    if (data_end[0] == static_cast<uint8_t>(Opcode::kDataEnd) && Le64(data_end + 1) == 4) {
      check_data_crc_ = Le32(data_end + 9) != 0;
    }
  }
  return Status::Ok();
}

Status Reader::AddSchema(const Where& where, std::span<const uint8_t> body) {
  Schema schema;
  if (std::string error = ParseSchema(body, &schema); !error.empty()) return Fail(where, error);
  if (schema.id == 0) return Status::Ok();  // invalid; the spec says to ignore it
  const auto it = schemas_.find(schema.id);
  if (it == schemas_.end()) {
    schemas_.emplace(schema.id, std::move(schema));
  } else if (it->second != schema) {
    return Fail(where, "Schema " + std::to_string(schema.id) +
                           " differs from the earlier Schema record with that id");
  }
  return Status::Ok();
}

Status Reader::AddChannel(const Where& where, std::span<const uint8_t> body) {
  Channel channel;
  if (std::string error = ParseChannel(body, &channel); !error.empty()) return Fail(where, error);
  // In the data section a Channel must follow its Schema; the summary is checked as a whole.
  const bool in_data = where.chunk_offset.has_value() || where.offset < data_limit_;
  if (in_data && channel.schema_id != 0 && schemas_.count(channel.schema_id) == 0) {
    return Fail(where, "Channel " + std::to_string(channel.id) + " ('" + Printable(channel.topic) +
                           "') refers to schema " + std::to_string(channel.schema_id) +
                           ", which no earlier Schema record defines");
  }
  const auto it = channels_.find(channel.id);
  if (it == channels_.end()) {
    channels_.emplace(channel.id, std::move(channel));
  } else if (it->second != channel) {
    return Fail(where, "Channel " + std::to_string(channel.id) +
                           " differs from the earlier Channel record with that id");
  }
  return Status::Ok();
}

Result<bool> Reader::Next(MessageView* out) {
  if (!open_) return Status::Error("mcap::Reader::Next: no file is open");
  if (!failed_.ok()) return failed_;
  while (!done_) {
    Result<bool> step = chunk_pos_ < chunk_.size() ? NextInChunk(out) : NextInDataSection(out);
    if (!step.ok()) {
      failed_ = step.status();
      return failed_;
    }
    if (*step) return true;
  }
  return false;
}

Result<bool> Reader::NextInChunk(MessageView* out) {
  const size_t at = chunk_pos_;
  const Where where{chunk_[at], at, chunk_offset_};
  const size_t left = chunk_.size() - at;
  const uint64_t length = left < kRecordHeaderSize ? 0 : Le64(chunk_.data() + at + 1);
  if (left < kRecordHeaderSize || length > left - kRecordHeaderSize) {
    return Fail(where, "the record runs past the end of the chunk's " +
                           std::to_string(chunk_.size()) + " bytes of records");
  }
  const auto body = chunk_.subspan(at + kRecordHeaderSize, static_cast<size_t>(length));
  chunk_pos_ = at + kRecordHeaderSize + static_cast<size_t>(length);
  switch (static_cast<Opcode>(where.opcode)) {
    case Opcode::kSchema:
      if (Status s = AddSchema(where, body); !s.ok()) return s;
      return false;
    case Opcode::kChannel:
      if (Status s = AddChannel(where, body); !s.ok()) return s;
      return false;
    case Opcode::kMessage:
      return TakeMessage(where, body, out);
    default:
      if (where.opcode == 0) return Fail(where, "opcode 0 is not a valid record");
      return false;  // records a newer spec or a private extension puts in chunks
  }
}

Result<bool> Reader::NextInDataSection(MessageView* out) {
  if (offset_ == data_limit_) {
    return Fail("the data section ends at offset " + std::to_string(offset_) +
                " without a DataEnd record");
  }
  if (data_limit_ - offset_ < kRecordHeaderSize) {
    return Fail("offset " + std::to_string(offset_) + ": a record's opcode and length run past " +
                "the end of the data section at offset " + std::to_string(data_limit_));
  }
  uint8_t header[kRecordHeaderSize];
  if (Status s = ReadAt(offset_, sizeof(header), header); !s.ok()) return s;
  const Where where{header[0], offset_, std::nullopt};
  const uint64_t length = Le64(header + 1);
  if (length > data_limit_ - offset_ - kRecordHeaderSize) {
    return Fail(where, "the record (length " + std::to_string(length) +
                           ") runs past the end of the data section at offset " +
                           std::to_string(data_limit_));
  }
  // The data-section CRC covers everything before the DataEnd record.
  if (check_data_crc_ && where.opcode != static_cast<uint8_t>(Opcode::kDataEnd)) {
    data_crc_ = Crc32(header, data_crc_);
  }
  offset_ += kRecordHeaderSize;
  return HandleDataRecord(where, length, out);
}

Result<bool> Reader::HandleDataRecord(const Where& where, uint64_t length, MessageView* out) {
  const uint32_t crc_before = data_crc_;
  switch (static_cast<Opcode>(where.opcode)) {
    case Opcode::kSchema:
    case Opcode::kChannel:
    case Opcode::kMessage:
    case Opcode::kChunk:
    case Opcode::kDataEnd:
      if (Status s = ReadBody(where, length); !s.ok()) return s;
      break;
    case Opcode::kHeader:
      return Fail(where, "a second Header record");
    case Opcode::kFooter:
      return Fail(where, "a Footer inside the data section");
    default:
      if (where.opcode == 0) return Fail(where, "opcode 0 is not a valid record");
      if (Status s = SkipBody(length); !s.ok()) return s;
      return false;  // attachments, metadata, indexes, unknown and private records
  }
  switch (static_cast<Opcode>(where.opcode)) {
    case Opcode::kSchema:
      if (Status s = AddSchema(where, record_); !s.ok()) return s;
      return false;
    case Opcode::kChannel:
      if (Status s = AddChannel(where, record_); !s.ok()) return s;
      return false;
    case Opcode::kMessage:
      return TakeMessage(where, record_, out);
    case Opcode::kChunk:
      if (Status s = LoadChunk(where); !s.ok()) return s;
      return false;
    default: {  // DataEnd
      data_crc_ = crc_before;
      if (Status s = FinishDataSection(where); !s.ok()) return s;
      return false;
    }
  }
}

Status Reader::ReadBody(const Where& where, uint64_t length) {
  if (length > kMaxRecordSize) {
    return Fail(where, "length " + std::to_string(length) + " exceeds the " +
                           std::to_string(kMaxRecordSize) + "-byte limit on one record");
  }
  record_.resize(static_cast<size_t>(length));
  if (Status s = ReadAt(offset_, record_.size(), record_.data()); !s.ok()) return s;
  if (check_data_crc_) data_crc_ = Crc32(record_, data_crc_);
  offset_ += length;
  return Status::Ok();
}

Status Reader::SkipBody(uint64_t length) {
  if (!check_data_crc_) {
    offset_ += length;
    return Status::Ok();
  }
  record_.resize(kSkipPiece);
  while (length > 0) {
    const size_t piece = static_cast<size_t>(std::min<uint64_t>(length, kSkipPiece));
    if (Status s = ReadAt(offset_, piece, record_.data()); !s.ok()) return s;
    data_crc_ = Crc32(std::span<const uint8_t>(record_.data(), piece), data_crc_);
    offset_ += piece;
    length -= piece;
  }
  return Status::Ok();
}

Result<bool> Reader::TakeMessage(const Where& where, std::span<const uint8_t> body,
                                 MessageView* out) {
  if (body.size() < kMessageFixedSize) {
    return Fail(where, "its " + std::to_string(body.size()) +
                           " bytes are fewer than a Message's 22 bytes of fixed fields");
  }
  const uint16_t channel_id = Le16(body.data());
  if (channels_.count(channel_id) == 0) {
    return Fail(where, "channel " + std::to_string(channel_id) + " has no earlier Channel record");
  }
  if (filter_ && filter_->count(channel_id) == 0) return false;
  out->channel_id = channel_id;
  out->sequence = Le32(body.data() + 2);
  out->log_time = Le64(body.data() + 6);
  out->publish_time = Le64(body.data() + 14);
  out->data = body.data() + kMessageFixedSize;
  out->size = body.size() - kMessageFixedSize;
  out->record_offset = where.chunk_offset.value_or(where.offset);
  out->offset_in_chunk = where.chunk_offset ? std::optional<uint64_t>(where.offset) : std::nullopt;
  return true;
}

Status Reader::LoadChunk(const Where& where) {
  chunk_ = {};
  chunk_pos_ = 0;
  ChunkFields chunk;
  if (std::string error = ParseChunk(record_, &chunk); !error.empty()) return Fail(where, error);
  if (chunk.uncompressed_size > kMaxChunkSize) {
    return Fail(where, "uncompressed size " + std::to_string(chunk.uncompressed_size) +
                           " exceeds the " + std::to_string(kMaxChunkSize) + "-byte limit");
  }
  std::span<const uint8_t> records = chunk.records;
  if (chunk.compression.empty()) {
    if (chunk.uncompressed_size != records.size()) {
      return Fail(where, "uncompressed size " + std::to_string(chunk.uncompressed_size) +
                             " differs from the " + std::to_string(records.size()) +
                             " bytes of its uncompressed records");
    }
  } else {
    if (Status s = Decompress(where, chunk.compression, records, chunk.uncompressed_size);
        !s.ok()) {
      return s;
    }
    records = decompressed_;
  }
  if (chunk.uncompressed_crc != 0) {
    const uint32_t crc = Crc32(records);
    if (crc != chunk.uncompressed_crc) {
      return Fail(where, "the CRC " + Hex32(crc) + " of its records does not match its " +
                             "uncompressed_crc " + Hex32(chunk.uncompressed_crc));
    }
  }
  chunk_ = records;
  chunk_offset_ = where.offset;
  return Status::Ok();
}

Status Reader::Decompress(const Where& where, const std::string& compression,
                          std::span<const uint8_t> compressed, uint64_t uncompressed_size) {
  const bool zstd = compression == "zstd";
  if (!zstd && compression != "lz4") {
    return Fail(where, "compression '" + Printable(compression) +
                           "' is not supported (only \"\", \"zstd\" and \"lz4\")");
  }
  // Bound the allocation by what the compressed bytes can possibly expand to.
  const uint64_t most = compressed.size() * (zstd ? kZstdMaxRatio : kLz4MaxRatio) + kCodecSlack;
  if (uncompressed_size > most) {
    return Fail(where, "uncompressed size " + std::to_string(uncompressed_size) + " is more than " +
                           std::to_string(compressed.size()) + " bytes of " + compression +
                           " can hold");
  }
  decompressed_.resize(static_cast<size_t>(uncompressed_size));
  if (!decompressor_) decompressor_ = std::make_unique<Decompressor>();
  const std::string error = zstd ? decompressor_->Zstd(compressed, decompressed_)
                                 : decompressor_->Lz4(compressed, decompressed_);
  if (!error.empty()) return Fail(where, error);
  return Status::Ok();
}

Status Reader::FinishDataSection(const Where& where) {
  Cursor c(record_);
  uint32_t stored = 0;
  if (!c.U32(&stored)) return Fail(where, c.Missing("data_section_crc"));
  if (check_data_crc_ && stored != 0 && stored != data_crc_) {
    return Fail(where, "the data section's CRC " + Hex32(data_crc_) +
                           " does not match the DataEnd's " + Hex32(stored));
  }
  done_ = true;
  return Status::Ok();
}

}  // namespace sfrt::ros2::mcap
