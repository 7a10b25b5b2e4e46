// MCAP files (mcap.dev/spec, major version 0), read and written as rosbag2 (rosbag2_storage_mcap)
// and the Foxglove tools write and read them: profile "ros2", schema encoding "ros2msg", message
// encoding "cdr". Written from the specification; no MCAP library is used.
//
// File layout (all integers little-endian; every record is <opcode u8><length u64><content>):
//   <magic><Header><data section ... DataEnd>[<summary section>][<summary offsets>]<Footer><magic>
//
// Reader (the contract):
//   - Accepts any MCAP file that starts with the magic and a Header and ends with a Footer and the
//     magic: messages in Chunks (compression "", "zstd", or "lz4" in the LZ4 *frame* format) or
//     directly in the data section, with or without a summary section. Records it does not use
//     are skipped, as the spec requires: unknown and private opcodes (0x10-0xFF), Attachment,
//     Metadata, MessageIndex, ChunkIndex and the other index records. Fields a newer writer
//     appends to a record are ignored.
//   - Open() reads the summary (Schema, Channel, Statistics) when the Footer points at one; a file
//     without a summary is read from its data section alone, and schemas()/channels() then fill
//     in as Next() meets their records.
//   - Next() returns the messages in file order: the order the writer stored them. rosbag2
//     stores messages as they arrive, which is log_time order up to small inversions between
//     topics; the reader never re-sorts (it would have to hold a whole file to do so).
//   - Refused, with an error (never a crash or undefined behaviour): a missing or wrong magic
//     (a truncated file, or one still being recorded, has no closing magic and Footer), a
//     record whose length runs past the data section, summary or chunk that holds it, a field
//     that runs past its record, a CRC that does not match (chunk uncompressed_crc, the
//     summary CRC in the Footer, the data-section CRC in DataEnd; each checked when non-zero),
//     a chunk that does not decompress to exactly its uncompressed_size, an unknown
//     compression, a Message on a channel no earlier Channel record defined, a Channel whose
//     schema no earlier Schema record defined, two Schema or Channel records with one id and
//     different contents, opcode 0, and a data section that ends without a DataEnd record.
//   - Errors are one line naming the file, the record and its byte offset, e.g.
//     "'x.mcap': Chunk at offset 1234: uncompressed size 5000000000 exceeds the 1073741824-byte
//     limit"; a record inside a chunk is named by its offset in the chunk's uncompressed bytes
//     and the chunk's file offset. After an error, Next() keeps returning it.
//   - Memory: the reader streams. It holds one record or one chunk at a time (the compressed
//     bytes and the decompressed bytes, each in a buffer reused from chunk to chunk), the
//     summary section, and the schemas and channels. Every length is checked against the bytes
//     that hold it before anything is allocated; a decompressed chunk is limited to
//     kMaxChunkSize and to what its codec can expand its compressed bytes to (zstd: 32768x,
//     lz4: 256x, plus a block), so a small file cannot make the reader allocate much.
//
// Writer (the contract):
//   - Writes what rosbag2's MCAP storage writes: Header, Chunks (compressed with "zstd", "lz4"
//     (LZ4 frame) or stored with "") each followed by one MessageIndex record per channel in it,
//     a DataEnd with the data-section CRC, then the summary (every Schema, every Channel,
//     Statistics with per-channel message counts, ChunkIndex, MetadataIndex), SummaryOffset
//     records for each group, the Footer with the summary CRC, and the closing magic. With
//     chunk_size == 0 messages go straight into the data section (no chunks, no indexes).
//   - A Schema and the Channel records are written into the data section (inside the current
//     chunk) just before the first message on that channel, as rosbag2 does; every schema and
//     channel added is also in the summary.
//   - A chunk whose compressed form is not smaller than its records is stored uncompressed
//     (compression ""), as the reference writers do.
//   - Every write is checked; the first failure (e.g. "'x.mcap': cannot write 1048576 bytes at
//     offset 4096: No space left on device") is returned and then returned by every later call.
//     The file is incomplete until Close() succeeds; the destructor of an unclosed Writer writes
//     out the bytes it buffered and closes the file without the open chunk, DataEnd, summary or
//     Footer (the Reader refuses such a file as truncated). Atomic replacement (temporary file +
//     rename) and fsync are the caller's: Open() writes the path it is given.
//   - Memory: one chunk (at most chunk_size plus one message) and its compressed form, plus the
//     index entries (16 bytes per message in the open chunk, ~100 bytes per chunk).
//
// Thread safety: none inside. One Reader or Writer per thread; distinct objects are independent.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::ros2::mcap {

// The 8 bytes that open and close every MCAP file; byte 5 is the major version ('0').
inline constexpr uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

// The largest chunk (uncompressed records) and the largest single record either side handles.
inline constexpr uint64_t kMaxChunkSize = uint64_t{1} << 30;
// The largest summary section the reader loads (it holds it whole to check its CRC).
inline constexpr uint64_t kMaxSummarySize = uint64_t{256} << 20;

// Record opcodes (mcap.dev/spec "Records"). 0x80-0xFF are private records.
enum class Opcode : uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

struct Schema {
  uint16_t id = 0;       // never 0 (a Schema record with id 0 is ignored, as the spec says)
  std::string name;      // e.g. "sensor_msgs/msg/Image"
  std::string encoding;  // e.g. "ros2msg"; empty: no schema
  std::vector<uint8_t> data;
  bool operator==(const Schema&) const = default;
};

struct Channel {
  uint16_t id = 0;         // any value, 0 included (the TypeScript writer starts at 0)
  uint16_t schema_id = 0;  // 0: no schema
  std::string topic;
  std::string message_encoding;                 // e.g. "cdr"
  std::map<std::string, std::string> metadata;  // rosbag2: "offered_qos_profiles", ...
  bool operator==(const Channel&) const = default;
};

struct Statistics {
  uint64_t message_count = 0;
  uint16_t schema_count = 0;
  uint32_t channel_count = 0;
  uint32_t attachment_count = 0;
  uint32_t metadata_count = 0;
  uint32_t chunk_count = 0;
  uint64_t message_start_time = 0;                      // earliest log_time; 0 without messages
  uint64_t message_end_time = 0;                        // latest log_time; 0 without messages
  std::map<uint16_t, uint64_t> channel_message_counts;  // empty: not available
  bool operator==(const Statistics&) const = default;
};

// One message as Next() returns it; `data` points into the reader's buffers.
struct MessageView {
  uint16_t channel_id = 0;
  uint32_t sequence = 0;
  uint64_t log_time = 0;
  uint64_t publish_time = 0;
  const uint8_t* data = nullptr;
  size_t size = 0;
  // Where it is, for error messages: the file offset of the Message record, or of the Chunk
  // that holds it, and then its offset in that chunk's uncompressed records.
  uint64_t record_offset = 0;
  std::optional<uint64_t> offset_in_chunk;
};

// CRC-32 (ISO-HDLC, as zlib and MCAP use it), continuable: Crc32(b, Crc32(a)) == Crc32(a + b).
uint32_t Crc32(std::span<const uint8_t> bytes, uint32_t crc = 0);

class Reader {
 public:
  Reader();
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  // Opens `path`: checks both magics, the Header and the Footer, and reads the summary (schemas,
  // channels, statistics, with its CRC) when there is one. May be called again to read another
  // file; the channel filter is kept.
  Status Open(const std::string& path);

  const std::map<uint16_t, Schema>& schemas() const { return schemas_; }
  const std::map<uint16_t, Channel>& channels() const { return channels_; }
  const std::optional<Statistics>& statistics() const { return statistics_; }
  // The number of messages on `channel_id`, from the Statistics record; nullopt when the file
  // has none or it does not count per channel.
  std::optional<uint64_t> message_count(uint16_t channel_id) const;
  const std::string& profile() const { return profile_; }
  const std::string& library() const { return library_; }

  // Next() returns only messages on these channels (nullopt, the default: all channels).
  void SetChannelFilter(std::optional<std::set<uint16_t>> channel_ids);

  // The next message in file order. true: *out is valid until the next call; false: no more
  // messages; an error Status: the file is corrupt or unreadable (and stays so).
  Result<bool> Next(MessageView* out);

 private:
  struct Decompressor;  // zstd and lz4 contexts, reused from chunk to chunk
  struct Where;         // a record's position, for error messages
  struct Footer {
    uint64_t offset = 0;
    uint64_t summary_start = 0;
    uint64_t summary_offset_start = 0;
    uint32_t summary_crc = 0;
    uint8_t prefix[25] = {};  // opcode, length, summary_start, summary_offset_start: CRC'd
  };

  Status Fail(const std::string& what) const;
  Status Fail(const Where& where, const std::string& what) const;
  Status ReadAt(uint64_t offset, size_t size, uint8_t* out) const;
  Status ReadMagicAndHeader();
  Status ReadFooter(Footer* footer);
  Status ReadSummary(const Footer& footer);
  Status ReadSummaryRecord(const Where& where, std::span<const uint8_t> body);
  Status PrepareDataScan(const Footer& footer);
  Status AddSchema(const Where& where, std::span<const uint8_t> body);
  Status AddChannel(const Where& where, std::span<const uint8_t> body);
  Result<bool> NextInChunk(MessageView* out);
  Result<bool> NextInDataSection(MessageView* out);
  Result<bool> HandleDataRecord(const Where& where, uint64_t length, MessageView* out);
  Result<bool> TakeMessage(const Where& where, std::span<const uint8_t> body, MessageView* out);
  Status ReadBody(const Where& where, uint64_t length);
  Status SkipBody(uint64_t length);
  Status LoadChunk(const Where& where);
  Status Decompress(const Where& where, const std::string& compression,
                    std::span<const uint8_t> compressed, uint64_t uncompressed_size);
  Status FinishDataSection(const Where& where);

  std::string path_;
  int fd_ = -1;
  uint64_t file_size_ = 0;
  std::string profile_;
  std::string library_;
  std::map<uint16_t, Schema> schemas_;
  std::map<uint16_t, Channel> channels_;
  std::optional<Statistics> statistics_;
  std::optional<std::set<uint16_t>> filter_;

  // The scan of the data section.
  bool open_ = false;
  bool done_ = false;
  Status failed_;
  uint64_t offset_ = 0;      // the next top-level record
  uint64_t data_limit_ = 0;  // where the data section must end: summary or Footer
  bool check_data_crc_ = false;
  uint32_t data_crc_ = 0;              // CRC of the bytes [0, offset_) when check_data_crc_
  std::vector<uint8_t> record_;        // the current top-level record's content
  std::vector<uint8_t> decompressed_;  // the current chunk's records, decompressed
  std::span<const uint8_t> chunk_;     // the current chunk's records (in one of the two above)
  size_t chunk_pos_ = 0;
  uint64_t chunk_offset_ = 0;
  std::unique_ptr<Decompressor> decompressor_;
};

struct WriterOptions {
  std::string profile = "ros2";
  std::string compression = "zstd";  // "", "zstd" or "lz4" (LZ4 frame format)
  uint64_t chunk_size = 4 << 20;     // bytes of records per chunk; 0: no chunks (and no indexes)
  bool chunk_crc = true;             // compute each chunk's uncompressed_crc
  std::string library = "sfrt";
};

class Writer {
 public:
  Writer();
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // Creates (or truncates) `path` and writes the magic and the Header. Refuses an unknown
  // compression and a chunk_size above kMaxChunkSize.
  Status Open(const std::string& path, const WriterOptions& options = {});
  // Ids are assigned from 1 upwards; at most 65535 schemas and 65535 channels.
  Result<uint16_t> AddSchema(const std::string& name, const std::string& encoding,
                             std::span<const uint8_t> data);
  // `schema_id` 0 means no schema; otherwise it must come from AddSchema.
  Result<uint16_t> AddChannel(uint16_t schema_id, const std::string& topic,
                              const std::string& message_encoding,
                              const std::map<std::string, std::string>& metadata);
  // Appends one message (a record of at most kMaxChunkSize bytes) to the current chunk, closing
  // the chunk first when the message would take it past chunk_size.
  Status Write(uint16_t channel_id, uint32_t sequence, uint64_t log_time, uint64_t publish_time,
               std::span<const uint8_t> data);
  // A Metadata record in the data section (closing the current chunk first) and its
  // MetadataIndex in the summary; rosbag2 stores its bag metadata as name "rosbag2", key
  // "serialized_metadata" (the YAML of metadata.yaml).
  Status WriteMetadata(const std::string& name, const std::map<std::string, std::string>& metadata);
  // Writes the last chunk, DataEnd, the summary, the summary offsets, the Footer and the magic,
  // then closes the file. The Writer may then Open another file.
  Status Close();

 private:
  struct Compressor;  // the zstd context, reused from chunk to chunk
  struct ChunkIndexEntry {
    uint64_t message_start_time = 0;
    uint64_t message_end_time = 0;
    uint64_t chunk_start_offset = 0;
    uint64_t chunk_length = 0;
    std::map<uint16_t, uint64_t> message_index_offsets;
    uint64_t message_index_length = 0;
    std::string compression;
    uint64_t compressed_size = 0;
    uint64_t uncompressed_size = 0;
  };
  struct MetadataIndexEntry {
    uint64_t offset = 0;
    uint64_t length = 0;
    std::string name;
  };

  void Reset();
  Status CheckOpen() const;
  Status Emit(std::span<const uint8_t> bytes);
  Status FlushOutput();
  Status WriteAll(const uint8_t* data, size_t size);
  Status EnsureChannelWritten(uint16_t channel_id);
  Status AppendToData(std::span<const uint8_t> record);
  Status FlushChunk();
  Status Compress(std::string* compression, std::span<const uint8_t>* payload);
  Status WriteMessageIndexes(ChunkIndexEntry* entry);
  Status WriteSummary(uint64_t* summary_start, uint64_t* summary_offset_start);
  Status WriteFooter(uint64_t summary_start, uint64_t summary_offset_start);
  Status Abandon(Status error);

  std::string path_;
  WriterOptions options_;
  int fd_ = -1;
  Status failed_;
  std::vector<uint8_t> pending_;  // bytes not yet handed to write(2)
  uint64_t offset_ = 0;           // bytes emitted so far (written or pending)
  uint64_t written_ = 0;          // bytes handed to write(2)
  uint32_t crc_ = 0;              // CRC of the data section, then of the summary

  std::vector<Schema> schemas_;    // id = index + 1
  std::vector<Channel> channels_;  // id = index + 1
  std::vector<bool> schema_written_;
  std::vector<bool> channel_written_;
  Statistics statistics_;

  // The open chunk: its records, and per channel the (log_time, offset) of each message.
  std::vector<uint8_t> chunk_;
  std::map<uint16_t, std::vector<std::pair<uint64_t, uint64_t>>> chunk_messages_;
  uint64_t chunk_start_time_ = 0;
  uint64_t chunk_end_time_ = 0;
  std::vector<uint8_t> compressed_;
  std::unique_ptr<Compressor> compressor_;
  std::vector<ChunkIndexEntry> chunk_indexes_;
  std::vector<MetadataIndexEntry> metadata_indexes_;
};

}  // namespace sfrt::ros2::mcap
