// The MCAP writer (mcap.h states the contract).
#include <fcntl.h>
#include <lz4frame.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <string>
#include <string_view>
#include <utility>

#include "mcap.h"

namespace sfrt::ros2::mcap {
namespace {

constexpr uint64_t kRecordHeaderSize = 9;
constexpr uint64_t kMessageFixedSize = 2 + 4 + 8 + 8;
constexpr size_t kOutputBuffer = size_t{1} << 20;  // small records are gathered up to this
constexpr size_t kDirectWrite = size_t{1} << 16;   // larger pieces go straight to write(2)
constexpr int kZstdLevel = 1;  // the reference writers' "Default": fast, still ~3x on images

void PutU8(std::vector<uint8_t>* out, uint8_t v) { out->push_back(v); }

void PutLe(std::vector<uint8_t>* out, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out->push_back(static_cast<uint8_t>(v >> (8 * i)));
}
void PutU16(std::vector<uint8_t>* out, uint16_t v) { PutLe(out, v, 2); }
void PutU32(std::vector<uint8_t>* out, uint32_t v) { PutLe(out, v, 4); }
void PutU64(std::vector<uint8_t>* out, uint64_t v) { PutLe(out, v, 8); }

void PatchU32(std::vector<uint8_t>* out, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) (*out)[at + i] = static_cast<uint8_t>(v >> (8 * i));
}
void PatchU64(std::vector<uint8_t>* out, size_t at, uint64_t v) {
  for (int i = 0; i < 8; ++i) (*out)[at + i] = static_cast<uint8_t>(v >> (8 * i));
}

// Callers keep strings and maps below 4 GiB (records are limited to kMaxChunkSize).
void PutBytes(std::vector<uint8_t>* out, std::span<const uint8_t> bytes) {
  PutU32(out, static_cast<uint32_t>(bytes.size()));
  out->insert(out->end(), bytes.begin(), bytes.end());
}
void PutString(std::vector<uint8_t>* out, std::string_view s) {
  PutBytes(out, {reinterpret_cast<const uint8_t*>(s.data()), s.size()});
}
void PutStringMap(std::vector<uint8_t>* out, const std::map<std::string, std::string>& map) {
  const size_t at = out->size();
  PutU32(out, 0);
  for (const auto& [key, value] : map) {
    PutString(out, key);
    PutString(out, value);
  }
  PatchU32(out, at, static_cast<uint32_t>(out->size() - at - 4));
}

// BeginRecord writes the opcode and a placeholder length; EndRecord fills the length in.
size_t BeginRecord(std::vector<uint8_t>* out, Opcode opcode) {
  const size_t at = out->size();
  PutU8(out, static_cast<uint8_t>(opcode));
  PutU64(out, 0);
  return at;
}
void EndRecord(std::vector<uint8_t>* out, size_t at) {
  PatchU64(out, at + 1, out->size() - at - kRecordHeaderSize);
}

void PutSchema(std::vector<uint8_t>* out, const Schema& schema) {
  const size_t at = BeginRecord(out, Opcode::kSchema);
  PutU16(out, schema.id);
  PutString(out, schema.name);
  PutString(out, schema.encoding);
  PutBytes(out, schema.data);
  EndRecord(out, at);
}

void PutChannel(std::vector<uint8_t>* out, const Channel& channel) {
  const size_t at = BeginRecord(out, Opcode::kChannel);
  PutU16(out, channel.id);
  PutU16(out, channel.schema_id);
  PutString(out, channel.topic);
  PutString(out, channel.message_encoding);
  PutStringMap(out, channel.metadata);
  EndRecord(out, at);
}

void PutStatistics(std::vector<uint8_t>* out, const Statistics& s) {
  const size_t at = BeginRecord(out, Opcode::kStatistics);
  PutU64(out, s.message_count);
  PutU16(out, s.schema_count);
  PutU32(out, s.channel_count);
  PutU32(out, s.attachment_count);
  PutU32(out, s.metadata_count);
  PutU32(out, s.chunk_count);
  PutU64(out, s.message_start_time);
  PutU64(out, s.message_end_time);
  PutU32(out, static_cast<uint32_t>(s.channel_message_counts.size() * 10));
  for (const auto& [channel, count] : s.channel_message_counts) {
    PutU16(out, channel);
    PutU64(out, count);
  }
  EndRecord(out, at);
}

// Message record header (everything but the data), for a message of `size` bytes.
std::vector<uint8_t> MessageHeader(uint16_t channel_id, uint32_t sequence, uint64_t log_time,
                                   uint64_t publish_time, uint64_t size) {
  std::vector<uint8_t> out;
  out.reserve(kRecordHeaderSize + kMessageFixedSize);
  PutU8(&out, static_cast<uint8_t>(Opcode::kMessage));
  PutU64(&out, kMessageFixedSize + size);
  PutU16(&out, channel_id);
  PutU32(&out, sequence);
  PutU64(&out, log_time);
  PutU64(&out, publish_time);
  return out;
}

uint64_t StringMapSize(const std::map<std::string, std::string>& map) {
  uint64_t size = 4;
  for (const auto& [key, value] : map) size += 8 + key.size() + value.size();
  return size;
}

}  // namespace

struct Writer::Compressor {
  ZSTD_CCtx* zstd = nullptr;
  ~Compressor() { ZSTD_freeCCtx(zstd); }
};

Writer::Writer() = default;

Writer::~Writer() {
  if (fd_ < 0) return;
  // An unfinished file stays unfinished (see mcap.h), but what was written reaches it, for
  // tools that recover the data section of an interrupted recording.
  (void)FlushOutput();
  ::close(fd_);
}

Status Writer::CheckOpen() const {
  if (fd_ < 0) return Status::Error("mcap::Writer: no file is open");
  return failed_;
}

void Writer::Reset() {
  failed_ = Status::Ok();
  pending_.clear();
  offset_ = written_ = 0;
  crc_ = 0;
  schemas_.clear();
  channels_.clear();
  schema_written_.clear();
  channel_written_.clear();
  statistics_ = Statistics();
  chunk_.clear();
  chunk_messages_.clear();
  chunk_indexes_.clear();
  metadata_indexes_.clear();
}

Status Writer::Abandon(Status error) {
  failed_ = error;
  return error;
}

Status Writer::Open(const std::string& path, const WriterOptions& options) {
  if (fd_ >= 0) return Status::Error("'" + path_ + "': still open; Close() it before Open()");
  const std::string& c = options.compression;
  if (!c.empty() && c != "zstd" && c != "lz4") {
    return Status::Error("'" + path + "': compression '" + c +
                         "' is not supported (only \"\", \"zstd\" and \"lz4\")");
  }
  if (options.chunk_size > kMaxChunkSize) {
    return Status::Error("'" + path + "': chunk_size " + std::to_string(options.chunk_size) +
                         " exceeds the " + std::to_string(kMaxChunkSize) + "-byte limit");
  }
  Reset();
  path_ = path;
  options_ = options;
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) return Status::Error("'" + path + "': cannot create: " + std::strerror(errno));
  std::vector<uint8_t> head(std::begin(kMagic), std::end(kMagic));
  const size_t at = BeginRecord(&head, Opcode::kHeader);
  PutString(&head, options.profile);
  PutString(&head, options.library);
  EndRecord(&head, at);
  return Emit(head);
}

Result<uint16_t> Writer::AddSchema(const std::string& name, const std::string& encoding,
                                   std::span<const uint8_t> data) {
  if (Status s = CheckOpen(); !s.ok()) return s;
  if (schemas_.size() >= 0xFFFF) {
    return Status::Error("'" + path_ + "': AddSchema: 65535 schemas (ids are 16-bit)");
  }
  if (name.size() + encoding.size() + data.size() > kMaxChunkSize - 64) {
    return Status::Error("'" + path_ + "': AddSchema '" + name + "': too large for one record");
  }
  const auto id = static_cast<uint16_t>(schemas_.size() + 1);
  schemas_.push_back(Schema{id, name, encoding, {data.begin(), data.end()}});
  schema_written_.push_back(false);
  statistics_.schema_count = id;
  return id;
}

Result<uint16_t> Writer::AddChannel(uint16_t schema_id, const std::string& topic,
                                    const std::string& message_encoding,
                                    const std::map<std::string, std::string>& metadata) {
  if (Status s = CheckOpen(); !s.ok()) return s;
  if (schema_id > schemas_.size()) {
    return Status::Error("'" + path_ + "': AddChannel '" + topic + "': schema id " +
                         std::to_string(schema_id) + " was not returned by AddSchema");
  }
  if (channels_.size() >= 0xFFFF) {
    return Status::Error("'" + path_ + "': AddChannel: 65535 channels (ids are 16-bit)");
  }
  if (topic.size() + message_encoding.size() + StringMapSize(metadata) > kMaxChunkSize - 64) {
    return Status::Error("'" + path_ + "': AddChannel '" + topic + "': too large for one record");
  }
  const auto id = static_cast<uint16_t>(channels_.size() + 1);
  channels_.push_back(Channel{id, schema_id, topic, message_encoding, metadata});
  channel_written_.push_back(false);
  statistics_.channel_count = id;
  statistics_.channel_message_counts[id] = 0;
  return id;
}

Status Writer::Write(uint16_t channel_id, uint32_t sequence, uint64_t log_time,
                     uint64_t publish_time, std::span<const uint8_t> data) {
  if (Status s = CheckOpen(); !s.ok()) return s;
  if (channel_id == 0 || channel_id > channels_.size()) {
    return Status::Error("'" + path_ + "': Write: channel id " + std::to_string(channel_id) +
                         " was not returned by AddChannel");
  }
  const uint64_t record_size = kRecordHeaderSize + kMessageFixedSize + data.size();
  if (record_size > kMaxChunkSize) {
    return Status::Error("'" + path_ + "': Write: a message of " + std::to_string(data.size()) +
                         " bytes exceeds the " + std::to_string(kMaxChunkSize) +
                         "-byte record limit");
  }
  if (Status s = EnsureChannelWritten(channel_id); !s.ok()) return s;
  const std::vector<uint8_t> header =
      MessageHeader(channel_id, sequence, log_time, publish_time, data.size());
  if (options_.chunk_size == 0) {
    if (Status s = Emit(header); !s.ok()) return s;
    if (Status s = Emit(data); !s.ok()) return s;
  } else {
    if (!chunk_.empty() && chunk_.size() + record_size > options_.chunk_size) {
      if (Status s = FlushChunk(); !s.ok()) return s;
    }
    if (chunk_messages_.empty()) chunk_start_time_ = chunk_end_time_ = log_time;
    chunk_start_time_ = std::min(chunk_start_time_, log_time);
    chunk_end_time_ = std::max(chunk_end_time_, log_time);
    chunk_messages_[channel_id].emplace_back(log_time, chunk_.size());
    chunk_.insert(chunk_.end(), header.begin(), header.end());
    chunk_.insert(chunk_.end(), data.begin(), data.end());
  }
  Statistics& s = statistics_;
  if (s.message_count == 0) s.message_start_time = s.message_end_time = log_time;
  s.message_start_time = std::min(s.message_start_time, log_time);
  s.message_end_time = std::max(s.message_end_time, log_time);
  ++s.message_count;
  ++s.channel_message_counts[channel_id];
  if (options_.chunk_size != 0 && chunk_.size() >= options_.chunk_size) return FlushChunk();
  return Status::Ok();
}

Status Writer::EnsureChannelWritten(uint16_t channel_id) {
  if (channel_written_[channel_id - 1]) return Status::Ok();
  const Channel& channel = channels_[channel_id - 1];
  std::vector<uint8_t> records;
  if (channel.schema_id != 0 && !schema_written_[channel.schema_id - 1]) {
    PutSchema(&records, schemas_[channel.schema_id - 1]);
    schema_written_[channel.schema_id - 1] = true;
  }
  PutChannel(&records, channel);
  channel_written_[channel_id - 1] = true;
  return AppendToData(records);
}

Status Writer::AppendToData(std::span<const uint8_t> records) {
  if (options_.chunk_size == 0) return Emit(records);
  chunk_.insert(chunk_.end(), records.begin(), records.end());
  return Status::Ok();
}

Status Writer::WriteMetadata(const std::string& name,
                             const std::map<std::string, std::string>& metadata) {
  if (Status s = CheckOpen(); !s.ok()) return s;
  if (name.size() + StringMapSize(metadata) > kMaxChunkSize - 64) {
    return Status::Error("'" + path_ + "': WriteMetadata '" + name + "': too large for a record");
  }
  if (Status s = FlushChunk(); !s.ok()) return s;  // Metadata records never go in chunks
  std::vector<uint8_t> record;
  const size_t at = BeginRecord(&record, Opcode::kMetadata);
  PutString(&record, name);
  PutStringMap(&record, metadata);
  EndRecord(&record, at);
  metadata_indexes_.push_back(MetadataIndexEntry{offset_, record.size(), name});
  ++statistics_.metadata_count;
  return Emit(record);
}

Status Writer::FlushChunk() {
  if (chunk_.empty()) return Status::Ok();
  ChunkIndexEntry entry;
  if (!chunk_messages_.empty()) {
    entry.message_start_time = chunk_start_time_;
    entry.message_end_time = chunk_end_time_;
  }
  entry.uncompressed_size = chunk_.size();
  const uint32_t crc = options_.chunk_crc ? Crc32(chunk_) : 0;
  std::span<const uint8_t> payload;
  if (Status s = Compress(&entry.compression, &payload); !s.ok()) return s;
  entry.compressed_size = payload.size();
  std::vector<uint8_t> head;
  BeginRecord(&head, Opcode::kChunk);
  PutU64(&head, entry.message_start_time);
  PutU64(&head, entry.message_end_time);
  PutU64(&head, entry.uncompressed_size);
  PutU32(&head, crc);
  PutString(&head, entry.compression);
  PutU64(&head, payload.size());
  PatchU64(&head, 1, head.size() - kRecordHeaderSize + payload.size());  // records follow
  entry.chunk_start_offset = offset_;
  if (Status s = Emit(head); !s.ok()) return s;
  if (Status s = Emit(payload); !s.ok()) return s;
  entry.chunk_length = offset_ - entry.chunk_start_offset;
  if (Status s = WriteMessageIndexes(&entry); !s.ok()) return s;
  chunk_indexes_.push_back(std::move(entry));
  ++statistics_.chunk_count;
  chunk_.clear();
  chunk_messages_.clear();
  return Status::Ok();
}

Status Writer::Compress(std::string* compression, std::span<const uint8_t>* payload) {
  *compression = "";
  *payload = chunk_;
  size_t size = 0;
  if (options_.compression == "zstd") {
    if (!compressor_) compressor_ = std::make_unique<Compressor>();
    if (compressor_->zstd == nullptr && (compressor_->zstd = ZSTD_createCCtx()) == nullptr) {
      return Abandon(Status::Error("'" + path_ + "': cannot create a zstd context"));
    }
    compressed_.resize(ZSTD_compressBound(chunk_.size()));
    size = ZSTD_compressCCtx(compressor_->zstd, compressed_.data(), compressed_.size(),
                             chunk_.data(), chunk_.size(), kZstdLevel);
    if (ZSTD_isError(size)) {
      return Abandon(Status::Error("'" + path_ + "': zstd: " + ZSTD_getErrorName(size)));
    }
  } else if (options_.compression == "lz4") {
    LZ4F_preferences_t preferences{};  // defaults: 64 KiB linked blocks, fast level
    preferences.frameInfo.contentSize = chunk_.size();
    compressed_.resize(LZ4F_compressFrameBound(chunk_.size(), &preferences));
    size = LZ4F_compressFrame(compressed_.data(), compressed_.size(), chunk_.data(), chunk_.size(),
                              &preferences);
    if (LZ4F_isError(size)) {
      return Abandon(Status::Error("'" + path_ + "': lz4: " + LZ4F_getErrorName(size)));
    }
  } else {
    return Status::Ok();
  }
  // Incompressible records (JPEG images, say) are stored as they are, as the reference
  // writers do: smaller and faster to read.
  if (size < chunk_.size()) {
    *compression = options_.compression;
    *payload = std::span<const uint8_t>(compressed_.data(), size);
  }
  return Status::Ok();
}

Status Writer::WriteMessageIndexes(ChunkIndexEntry* entry) {
  const uint64_t start = offset_;
  std::vector<uint8_t> record;
  for (const auto& [channel_id, messages] : chunk_messages_) {
    record.clear();
    const size_t at = BeginRecord(&record, Opcode::kMessageIndex);
    PutU16(&record, channel_id);
    PutU32(&record, static_cast<uint32_t>(messages.size() * 16));
    for (const auto& [log_time, offset] : messages) {
      PutU64(&record, log_time);
      PutU64(&record, offset);
    }
    EndRecord(&record, at);
    entry->message_index_offsets[channel_id] = offset_;
    if (Status s = Emit(record); !s.ok()) return s;
  }
  entry->message_index_length = offset_ - start;
  return Status::Ok();
}

Status Writer::Close() {
  if (fd_ < 0) return Status::Error("mcap::Writer::Close: no file is open");
  Status status = failed_;
  if (status.ok()) status = FlushChunk();
  if (status.ok()) {
    std::vector<uint8_t> data_end;
    const size_t at = BeginRecord(&data_end, Opcode::kDataEnd);
    PutU32(&data_end, crc_);  // the CRC of every byte before this record
    EndRecord(&data_end, at);
    status = Emit(data_end);
  }
  crc_ = 0;  // from here on: the summary CRC
  uint64_t summary_start = 0, summary_offset_start = 0;
  if (status.ok()) status = WriteSummary(&summary_start, &summary_offset_start);
  if (status.ok()) status = WriteFooter(summary_start, summary_offset_start);
  if (status.ok()) status = FlushOutput();
  if (::close(fd_) != 0 && status.ok()) {
    status = Status::Error("'" + path_ + "': close: " + std::strerror(errno));
  }
  fd_ = -1;
  return status;
}

Status Writer::WriteSummary(uint64_t* summary_start, uint64_t* summary_offset_start) {
  *summary_start = offset_;
  std::vector<uint8_t> out;
  struct Group {
    Opcode opcode;
    size_t begin, end;
  };
  std::vector<Group> groups;
  const auto group = [&](Opcode opcode, size_t begin) {
    if (out.size() > begin) groups.push_back(Group{opcode, begin, out.size()});
  };
  size_t begin = out.size();
  for (const Schema& schema : schemas_) PutSchema(&out, schema);
  group(Opcode::kSchema, begin);
  begin = out.size();
  for (const Channel& channel : channels_) PutChannel(&out, channel);
  group(Opcode::kChannel, begin);
  begin = out.size();
  PutStatistics(&out, statistics_);
  group(Opcode::kStatistics, begin);
  begin = out.size();
  for (const ChunkIndexEntry& e : chunk_indexes_) {
    const size_t at = BeginRecord(&out, Opcode::kChunkIndex);
    PutU64(&out, e.message_start_time);
    PutU64(&out, e.message_end_time);
    PutU64(&out, e.chunk_start_offset);
    PutU64(&out, e.chunk_length);
    PutU32(&out, static_cast<uint32_t>(e.message_index_offsets.size() * 10));
    for (const auto& [channel_id, offset] : e.message_index_offsets) {
      PutU16(&out, channel_id);
      PutU64(&out, offset);
    }
    PutU64(&out, e.message_index_length);
    PutString(&out, e.compression);
    PutU64(&out, e.compressed_size);
    PutU64(&out, e.uncompressed_size);
    EndRecord(&out, at);
  }
  group(Opcode::kChunkIndex, begin);
  begin = out.size();
  for (const MetadataIndexEntry& e : metadata_indexes_) {
    const size_t at = BeginRecord(&out, Opcode::kMetadataIndex);
    PutU64(&out, e.offset);
    PutU64(&out, e.length);
    PutString(&out, e.name);
    EndRecord(&out, at);
  }
  group(Opcode::kMetadataIndex, begin);
  *summary_offset_start = *summary_start + out.size();
  for (const Group& g : groups) {
    const size_t at = BeginRecord(&out, Opcode::kSummaryOffset);
    PutU8(&out, static_cast<uint8_t>(g.opcode));
    PutU64(&out, *summary_start + g.begin);
    PutU64(&out, g.end - g.begin);
    EndRecord(&out, at);
  }
  return Emit(out);
}

Status Writer::WriteFooter(uint64_t summary_start, uint64_t summary_offset_start) {
  std::vector<uint8_t> footer;
  const size_t at = BeginRecord(&footer, Opcode::kFooter);
  PutU64(&footer, summary_start);
  PutU64(&footer, summary_offset_start);
  PatchU64(&footer, at + 1, 20);  // the CRC field that follows is part of the record
  // The summary CRC runs from the summary's start through summary_offset_start.
  PutU32(&footer, Crc32(footer, crc_));
  footer.insert(footer.end(), std::begin(kMagic), std::end(kMagic));
  return Emit(footer);
}

Status Writer::Emit(std::span<const uint8_t> bytes) {
  if (!failed_.ok()) return failed_;
  crc_ = Crc32(bytes, crc_);
  offset_ += bytes.size();
  if (bytes.size() >= kDirectWrite) {
    if (Status s = FlushOutput(); !s.ok()) return s;
    return WriteAll(bytes.data(), bytes.size());
  }
  pending_.insert(pending_.end(), bytes.begin(), bytes.end());
  if (pending_.size() >= kOutputBuffer) return FlushOutput();
  return Status::Ok();
}

Status Writer::FlushOutput() {
  if (pending_.empty()) return failed_;
  Status s = WriteAll(pending_.data(), pending_.size());
  pending_.clear();
  return s;
}

Status Writer::WriteAll(const uint8_t* data, size_t size) {
  if (!failed_.ok()) return failed_;
  while (size > 0) {
    const ssize_t n = ::write(fd_, data, std::min<size_t>(size, size_t{1} << 30));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = n < 0 ? errno : EIO;
      return Abandon(Status::Error("'" + path_ + "': cannot write " + std::to_string(size) +
                                   " bytes at offset " + std::to_string(written_) + ": " +
                                   std::strerror(error)));
    }
    data += n;
    size -= static_cast<size_t>(n);
    written_ += static_cast<uint64_t>(n);
  }
  return Status::Ok();
}

}  // namespace sfrt::ros2::mcap
