// The MCAP reader and writer (ros2/src/mcap.h): round trips through every compression, the
// layout the writer promises (indexes, summary offsets, CRCs, codec frames), hand-made files
// with what other writers may put in them (no summary, no chunks, unknown records, padded
// records, channel id 0), and every kind of damage a file can come with. Files are built here
// byte by byte, independently of the implementation; tests/ros2/mcap_oracle_check.mjs compares
// both directions with the format authors' TypeScript implementation.
#include "mcap.h"

#include <gtest/gtest.h>
#include <lz4frame.h>
#include <zstd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <new>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <vector>

// The largest single allocation while g_track_allocations is set: a claimed size in a small file
// must never turn into a large buffer.
namespace {
std::atomic<bool> g_track_allocations{false};
std::atomic<size_t> g_largest_allocation{0};
// Out of line, so that the compiler does not see operator new's memory reach free() (it warns).
[[gnu::noinline]] void Release(void* p) noexcept { std::free(p); }
}  // namespace

void* operator new(size_t size) {
  if (g_track_allocations.load(std::memory_order_relaxed)) {
    size_t largest = g_largest_allocation.load();
    while (size > largest && !g_largest_allocation.compare_exchange_weak(largest, size)) {
    }
  }
  void* p = std::malloc(size == 0 ? 1 : size);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
void* operator new[](size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { Release(p); }
void operator delete[](void* p) noexcept { Release(p); }
void operator delete(void* p, size_t) noexcept { Release(p); }
void operator delete[](void* p, size_t) noexcept { Release(p); }

namespace {

namespace mcap = sfrt::ros2::mcap;
namespace fs = std::filesystem;
using Bytes = std::vector<uint8_t>;

constexpr uint8_t kMagicBytes[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

// ---- files and bytes ----

Bytes ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void WriteFile(const fs::path& path, const Bytes& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

uint64_t GetLe(const Bytes& b, size_t at, int size) {
  uint64_t v = 0;
  for (int i = 0; i < size; ++i) v |= static_cast<uint64_t>(b.at(at + i)) << (8 * i);
  return v;
}

void SetLe(Bytes* b, size_t at, uint64_t v, int size) {
  for (int i = 0; i < size; ++i) b->at(at + i) = static_cast<uint8_t>(v >> (8 * i));
}

Bytes Concat(Bytes a, const Bytes& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// Builds record content field by field, little-endian, as the spec lays it out.
class Fields {
 public:
  Fields& U8(uint64_t v) { return Le(v, 1); }
  Fields& U16(uint64_t v) { return Le(v, 2); }
  Fields& U32(uint64_t v) { return Le(v, 4); }
  Fields& U64(uint64_t v) { return Le(v, 8); }
  Fields& Raw(const Bytes& b) {
    bytes_.insert(bytes_.end(), b.begin(), b.end());
    return *this;
  }
  Fields& Str(const std::string& s) { return U32(s.size()).Raw(Bytes(s.begin(), s.end())); }
  Fields& Map(const std::vector<std::pair<std::string, std::string>>& map) {
    Fields entries;
    for (const auto& [key, value] : map) entries.Str(key).Str(value);
    return U32(entries.bytes().size()).Raw(entries.bytes());
  }
  const Bytes& bytes() const { return bytes_; }

 private:
  Fields& Le(uint64_t v, int size) {
    for (int i = 0; i < size; ++i) bytes_.push_back(static_cast<uint8_t>(v >> (8 * i)));
    return *this;
  }
  Bytes bytes_;
};

Bytes Record(uint8_t opcode, const Fields& content) {
  return Fields().U8(opcode).U64(content.bytes().size()).Raw(content.bytes()).bytes();
}

Bytes SchemaRecord(uint16_t id, const std::string& name, const std::string& data = "uint8 x") {
  return Record(0x03, Fields().U16(id).Str(name).Str("ros2msg").Str(data));
}

Bytes ChannelRecord(uint16_t id, uint16_t schema_id, const std::string& topic) {
  return Record(0x04, Fields().U16(id).U16(schema_id).Str(topic).Str("cdr").Map(
                          {{"offered_qos_profiles", "- history: 3\n  depth: 0\n"}}));
}

Bytes MessageRecord(uint16_t channel, uint32_t sequence, uint64_t log_time, const Bytes& data) {
  return Record(0x05,
                Fields().U16(channel).U32(sequence).U64(log_time).U64(log_time + 1).Raw(data));
}

Bytes ChunkRecord(const Bytes& payload, uint64_t uncompressed_size, const std::string& compression,
                  uint32_t crc = 0) {
  return Record(0x06, Fields()
                          .U64(1)
                          .U64(2)
                          .U64(uncompressed_size)
                          .U32(crc)
                          .Str(compression)
                          .U64(payload.size())
                          .Raw(payload));
}

Bytes FooterAndMagic(uint64_t summary_start, uint64_t summary_offset_start, uint32_t crc) {
  return Concat(Record(0x02, Fields().U64(summary_start).U64(summary_offset_start).U32(crc)),
                Bytes(std::begin(kMagicBytes), std::end(kMagicBytes)));
}

// A hand-made file: magic and Header, then whatever records a test appends.
class FileBuilder {
 public:
  explicit FileBuilder(const Bytes& header_padding = {})
      : bytes_(std::begin(kMagicBytes), std::end(kMagicBytes)) {
    Append(Record(0x01, Fields().Str("ros2").Str("mcap_test").Raw(header_padding)));
  }
  uint64_t Append(const Bytes& record) {
    const uint64_t offset = bytes_.size();
    bytes_.insert(bytes_.end(), record.begin(), record.end());
    return offset;
  }
  uint64_t size() const { return bytes_.size(); }
  // DataEnd (CRC not given), no summary, Footer, magic.
  Bytes Finish() {
    Append(Record(0x0F, Fields().U32(0)));
    return Concat(bytes_, FooterAndMagic(0, 0, 0));
  }
  const Bytes& bytes() const { return bytes_; }

 private:
  Bytes bytes_;
};

// The top-level records of a file (Header to Footer), found by their opcode and length only.
struct TopRecord {
  uint8_t opcode;
  uint64_t offset;
  uint64_t length;  // content length
  uint64_t end() const { return offset + 9 + length; }
};

std::vector<TopRecord> Walk(const Bytes& file) {
  std::vector<TopRecord> records;
  for (uint64_t at = 8; at + 9 <= file.size() - 8;) {
    records.push_back({file[at], at, GetLe(file, at + 1, 8)});
    at = records.back().end();
  }
  return records;
}

std::vector<TopRecord> OfType(const std::vector<TopRecord>& records, uint8_t opcode) {
  std::vector<TopRecord> out;
  std::copy_if(records.begin(), records.end(), std::back_inserter(out),
               [&](const TopRecord& r) { return r.opcode == opcode; });
  return out;
}

// ---- what a file holds, read back through mcap::Reader ----

struct Message {
  uint16_t channel_id = 0;
  uint32_t sequence = 0;
  uint64_t log_time = 0;
  uint64_t publish_time = 0;
  Bytes data;
  bool operator==(const Message&) const = default;
};

void PrintTo(const Message& m, std::ostream* os) {
  *os << "{channel " << m.channel_id << ", seq " << m.sequence << ", log " << m.log_time
      << ", publish " << m.publish_time << ", " << m.data.size() << " bytes}";
}

struct Contents {
  std::vector<Message> messages;
  std::map<uint16_t, mcap::Schema> schemas;
  std::map<uint16_t, mcap::Channel> channels;
  std::optional<mcap::Statistics> statistics;
  std::string profile;
};

sfrt::Result<Contents> ReadAll(const fs::path& path,
                               std::optional<std::set<uint16_t>> filter = std::nullopt) {
  mcap::Reader reader;
  reader.SetChannelFilter(std::move(filter));
  if (sfrt::Status s = reader.Open(path); !s.ok()) return s;
  Contents contents;
  mcap::MessageView view;
  for (;;) {
    sfrt::Result<bool> next = reader.Next(&view);
    if (!next.ok()) return next.status();
    if (!*next) break;
    contents.messages.push_back({view.channel_id, view.sequence, view.log_time, view.publish_time,
                                 Bytes(view.data, view.data + view.size)});
  }
  contents.schemas = reader.schemas();
  contents.channels = reader.channels();
  contents.statistics = reader.statistics();
  contents.profile = reader.profile();
  return contents;
}

// The error Open or Next ends with; "" when the whole file reads.
std::string ReadError(const fs::path& path) {
  sfrt::Result<Contents> contents = ReadAll(path);
  return contents.ok() ? "" : contents.message();
}

// ---- a recording to write: 3 channels, 2 schemas, messages of every size ----

struct Scenario {
  std::vector<mcap::Schema> schemas;
  std::vector<mcap::Channel> channels;
  std::vector<Message> messages;
};

Bytes Payload(std::mt19937_64& rng, size_t size, bool compressible) {
  Bytes data(size);
  for (size_t i = 0; i < size; ++i) {
    data[i] =
        compressible ? static_cast<uint8_t>((i / 7) % 13 + (i % 3)) : static_cast<uint8_t>(rng());
  }
  return data;
}

Scenario MakeScenario(uint64_t seed, size_t count, bool compressible = true) {
  std::mt19937_64 rng(seed);
  Scenario s;
  s.schemas = {{1, "sensor_msgs/msg/Image", "ros2msg", Payload(rng, 300, true)},
               {2, "sensor_msgs/msg/CompressedImage", "ros2msg", Payload(rng, 120, true)}};
  s.channels = {{1,
                 1,
                 "/camera/left/image_raw",
                 "cdr",
                 {{"offered_qos_profiles", "- history: 3\n  depth: 0\n  reliability: 1\n"},
                  {"topic_type_hash",
                   "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47"}}},
                {2, 2, "/camera/left/image_raw/compressed", "cdr", {}},
                {3, 0, "/raw_bytes", "cdr", {{"note", "no schema"}}}};
  std::map<uint16_t, uint32_t> sequence;
  for (size_t i = 0; i < count; ++i) {
    const auto channel = static_cast<uint16_t>(1 + rng() % 3);
    // Log times rise with small inversions, as rosbag2's arrival times across topics do.
    const uint64_t log_time = 1'700'000'000'000'000'000ull + i * 1000 + rng() % 3000;
    const size_t size = i % 17 == 0 ? 0 : rng() % (i % 5 == 0 ? 20000 : 300);
    s.messages.push_back({channel, sequence[channel]++, log_time, log_time - rng() % 500,
                          Payload(rng, size, compressible)});
  }
  return s;
}

sfrt::Status WriteScenario(const fs::path& path, const Scenario& s,
                           const mcap::WriterOptions& options) {
  mcap::Writer writer;
  if (sfrt::Status st = writer.Open(path, options); !st.ok()) return st;
  for (const mcap::Schema& schema : s.schemas) {
    sfrt::Result<uint16_t> id = writer.AddSchema(schema.name, schema.encoding, schema.data);
    if (!id.ok()) return id.status();
    if (*id != schema.id) return sfrt::Status::Error("unexpected schema id");
  }
  for (const mcap::Channel& c : s.channels) {
    sfrt::Result<uint16_t> id =
        writer.AddChannel(c.schema_id, c.topic, c.message_encoding, c.metadata);
    if (!id.ok()) return id.status();
    if (*id != c.id) return sfrt::Status::Error("unexpected channel id");
  }
  for (const Message& m : s.messages) {
    if (sfrt::Status st =
            writer.Write(m.channel_id, m.sequence, m.log_time, m.publish_time, m.data);
        !st.ok()) {
      return st;
    }
  }
  return writer.Close();
}

mcap::Statistics ExpectedStatistics(const Scenario& s, uint32_t chunk_count) {
  mcap::Statistics st;
  st.message_count = s.messages.size();
  st.schema_count = static_cast<uint16_t>(s.schemas.size());
  st.channel_count = static_cast<uint32_t>(s.channels.size());
  st.chunk_count = chunk_count;
  for (const mcap::Channel& c : s.channels) st.channel_message_counts[c.id] = 0;
  for (const Message& m : s.messages) ++st.channel_message_counts[m.channel_id];
  const auto [lo, hi] = std::minmax_element(
      s.messages.begin(), s.messages.end(),
      [](const Message& a, const Message& b) { return a.log_time < b.log_time; });
  st.message_start_time = lo->log_time;
  st.message_end_time = hi->log_time;
  return st;
}

class TempDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "sfrt-mcap-test-XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path Path(const std::string& name) const { return dir_ / name; }
  // A written recording, as bytes, for tests that damage it.
  Bytes WrittenFile(const std::string& name, const mcap::WriterOptions& options,
                    size_t count = 40) {
    const Scenario s = MakeScenario(7, count);
    EXPECT_TRUE(WriteScenario(Path(name), s, options).ok());
    return ReadFile(Path(name));
  }

  fs::path dir_;
};

// ============================== round trips ==============================

struct RoundTripCase {
  const char* compression;
  uint64_t chunk_size;
};

using McapReader = TempDirTest;
using McapWriter = TempDirTest;

class McapRoundTrip : public TempDirTest, public ::testing::WithParamInterface<RoundTripCase> {};

TEST_P(McapRoundTrip, KeepsEveryMessageSchemaChannelAndStatistic) {
  const Scenario s = MakeScenario(42, 400);
  mcap::WriterOptions options;
  options.compression = GetParam().compression;
  options.chunk_size = GetParam().chunk_size;
  const fs::path path = Path("round.mcap");
  ASSERT_TRUE(WriteScenario(path, s, options).ok());

  sfrt::Result<Contents> got = ReadAll(path);
  ASSERT_TRUE(got.ok()) << got.message();
  EXPECT_EQ(got->profile, "ros2");
  EXPECT_EQ(got->messages, s.messages);  // file order is write order
  ASSERT_EQ(got->schemas.size(), s.schemas.size());
  for (const mcap::Schema& schema : s.schemas) EXPECT_EQ(got->schemas.at(schema.id), schema);
  ASSERT_EQ(got->channels.size(), s.channels.size());
  for (const mcap::Channel& c : s.channels) EXPECT_EQ(got->channels.at(c.id), c);
  const auto chunks = OfType(Walk(ReadFile(path)), 0x06).size();
  if (options.chunk_size == 0) {
    EXPECT_EQ(chunks, 0u);
  } else if (options.chunk_size == 4096) {
    EXPECT_GT(chunks, 10u);
  }
  ASSERT_TRUE(got->statistics.has_value());
  EXPECT_EQ(*got->statistics, ExpectedStatistics(s, static_cast<uint32_t>(chunks)));

  mcap::Reader reader;
  ASSERT_TRUE(reader.Open(path).ok());
  for (const auto& [id, count] : ExpectedStatistics(s, 0).channel_message_counts) {
    EXPECT_EQ(reader.message_count(id), count) << "channel " << id;
  }
}

INSTANTIATE_TEST_SUITE_P(Compressions, McapRoundTrip,
                         ::testing::Values(RoundTripCase{"zstd", 4 << 20},
                                           RoundTripCase{"zstd", 4096},
                                           RoundTripCase{"lz4", 4 << 20},
                                           RoundTripCase{"lz4", 4096}, RoundTripCase{"", 4 << 20},
                                           RoundTripCase{"", 4096}, RoundTripCase{"zstd", 0}),
                         [](const ::testing::TestParamInfo<RoundTripCase>& test) {
                           const std::string c = test.param.compression;
                           return (c.empty() ? std::string("Uncompressed") : c) +
                                  (test.param.chunk_size == 0      ? "Unchunked"
                                   : test.param.chunk_size == 4096 ? "SmallChunks"
                                                                   : "DefaultChunks");
                         });

TEST_F(McapReader, ChannelFilterReturnsOnlyTheChosenChannelsInFileOrder) {
  const Scenario s = MakeScenario(3, 200);
  mcap::WriterOptions options;
  options.chunk_size = 2048;
  ASSERT_TRUE(WriteScenario(Path("f.mcap"), s, options).ok());
  sfrt::Result<Contents> got = ReadAll(Path("f.mcap"), std::set<uint16_t>{1, 3});
  ASSERT_TRUE(got.ok()) << got.message();
  std::vector<Message> expected;
  std::copy_if(s.messages.begin(), s.messages.end(), std::back_inserter(expected),
               [](const Message& m) { return m.channel_id != 2; });
  EXPECT_EQ(got->messages, expected);
}

// ============================== the writer's layout ==============================

TEST_F(McapWriter, CompressesChunksAsZstdAndLz4FramesAndStoresIncompressibleOnesPlain) {
  for (const std::string codec : {"zstd", "lz4"}) {
    for (const bool compressible : {true, false}) {
      SCOPED_TRACE(codec + (compressible ? " compressible" : " incompressible"));
      mcap::WriterOptions options;
      options.compression = codec;
      options.chunk_size = 16384;
      Scenario s = MakeScenario(11, 100, compressible);
      if (!compressible) {  // only random bytes: no schema text, nothing small
        s.schemas.clear();
        s.channels = {{1, 0, "/r", "cdr", {}}};
        std::mt19937_64 rng(12);
        for (Message& m : s.messages) {
          m.channel_id = 1;
          m.data = Payload(rng, 8000, false);
        }
      }
      ASSERT_TRUE(WriteScenario(Path("c.mcap"), s, options).ok());
      const Bytes file = ReadFile(Path("c.mcap"));
      const auto chunks = OfType(Walk(file), 0x06);
      ASSERT_GT(chunks.size(), 1u);
      for (const TopRecord& chunk : chunks) {
        const size_t name_at = chunk.offset + 9 + 28;
        const auto name_size = GetLe(file, name_at, 4);
        const std::string name(file.begin() + name_at + 4, file.begin() + name_at + 4 + name_size);
        const size_t payload_at = name_at + 4 + name_size + 8;
        if (!compressible) {
          EXPECT_EQ(name, "");
          continue;
        }
        EXPECT_EQ(name, codec);
        // The frame magic numbers: zstd 0xFD2FB528, LZ4 frame (not block) 0x184D2204.
        EXPECT_EQ(GetLe(file, payload_at, 4), codec == "zstd" ? 0xFD2FB528u : 0x184D2204u);
      }
    }
  }
}

// Reads a ChunkIndex or MessageIndex field by field (the test's own parser).
struct Cursor {
  const Bytes& b;
  size_t at;
  uint64_t U(int size) {
    const uint64_t v = GetLe(b, at, size);
    at += size;
    return v;
  }
  std::string Str() {
    const size_t size = U(4);
    at += size;
    return std::string(b.begin() + at - size, b.begin() + at);
  }
};

TEST_F(McapWriter, IndexesAndSummaryOffsetsPointAtTheirRecords) {
  const Scenario s = MakeScenario(5, 150);
  mcap::WriterOptions options;
  options.compression = "zstd";
  options.chunk_size = 8192;
  ASSERT_TRUE(WriteScenario(Path("i.mcap"), s, options).ok());
  const Bytes file = ReadFile(Path("i.mcap"));
  const std::vector<TopRecord> records = Walk(file);
  const uint64_t footer = file.size() - 8 - 29;
  ASSERT_EQ(records.back().offset, footer);
  const uint64_t summary_start = GetLe(file, footer + 9, 8);
  const uint64_t offsets_start = GetLe(file, footer + 17, 8);
  // The DataEnd just before the summary; the summary CRC over summary .. summary_offset_start.
  EXPECT_EQ(file.at(summary_start - 13), 0x0F);
  const Bytes summary_and_prefix(file.begin() + summary_start, file.begin() + footer + 25);
  EXPECT_EQ(GetLe(file, footer + 25, 4), mcap::Crc32(summary_and_prefix));
  // Each SummaryOffset covers exactly the run of records with its opcode.
  size_t groups = 0;
  for (const TopRecord& r : records) {
    if (r.opcode != 0x0E) continue;
    ++groups;
    ASSERT_GE(r.offset, offsets_start);
    const uint8_t opcode = file[r.offset + 9];
    const uint64_t start = GetLe(file, r.offset + 10, 8), length = GetLe(file, r.offset + 18, 8);
    uint64_t covered = 0;
    for (const TopRecord& g : records) {
      if (g.offset >= start && g.offset < start + length) {
        EXPECT_EQ(g.opcode, opcode);
        covered += g.end() - g.offset;
      } else if (g.offset >= summary_start && g.offset < offsets_start) {
        EXPECT_NE(g.opcode, opcode) << "a record of the group outside its SummaryOffset";
      }
    }
    EXPECT_EQ(covered, length);
  }
  EXPECT_EQ(groups, 4u);  // Schema, Channel, Statistics, ChunkIndex

  // Every ChunkIndex finds its chunk; every MessageIndex entry finds its message in it.
  size_t indexed_messages = 0;
  const auto chunk_indexes = OfType(records, 0x08);
  EXPECT_EQ(chunk_indexes.size(), OfType(records, 0x06).size());
  for (const TopRecord& ci : chunk_indexes) {
    Cursor c{file, ci.offset + 9};
    c.U(8);  // message start time
    c.U(8);  // message end time
    const uint64_t chunk_at = c.U(8), chunk_length = c.U(8);
    ASSERT_EQ(file.at(chunk_at), 0x06);
    EXPECT_EQ(chunk_length, 9 + GetLe(file, chunk_at + 1, 8));
    std::map<uint16_t, uint64_t> index_offsets;
    for (uint64_t n = c.U(4) / 10; n > 0; --n) {
      const auto channel = static_cast<uint16_t>(c.U(2));
      index_offsets[channel] = c.U(8);
    }
    const uint64_t index_length = c.U(8);
    EXPECT_EQ(c.Str(), "zstd");
    const uint64_t compressed_size = c.U(8), uncompressed_size = c.U(8);
    Cursor chunk{file, chunk_at + 9 + 28};
    chunk.Str();
    ASSERT_EQ(chunk.U(8), compressed_size);
    Bytes records_in_chunk(uncompressed_size);
    ASSERT_EQ(ZSTD_decompress(records_in_chunk.data(), records_in_chunk.size(),
                              file.data() + chunk.at, compressed_size),
              uncompressed_size);
    uint64_t index_bytes = 0;
    for (const auto& [channel, offset] : index_offsets) {
      ASSERT_EQ(file.at(offset), 0x07);
      index_bytes += 9 + GetLe(file, offset + 1, 8);
      Cursor mi{file, offset + 9};
      EXPECT_EQ(mi.U(2), channel);
      for (uint64_t n = mi.U(4) / 16; n > 0; --n, ++indexed_messages) {
        const uint64_t log_time = mi.U(8), at = mi.U(8);
        ASSERT_EQ(records_in_chunk.at(at), 0x05);
        EXPECT_EQ(GetLe(records_in_chunk, at + 9, 2), channel);
        EXPECT_EQ(GetLe(records_in_chunk, at + 9 + 6, 8), log_time);
      }
    }
    EXPECT_EQ(index_bytes, index_length);
  }
  EXPECT_EQ(indexed_messages, s.messages.size());
}

TEST_F(McapWriter, WritesRosbag2MetadataWithItsIndex) {
  mcap::Writer writer;
  ASSERT_TRUE(writer.Open(Path("m.mcap")).ok());
  const auto schema = writer.AddSchema("std_msgs/msg/String", "ros2msg", Bytes{'s'});
  ASSERT_TRUE(schema.ok());
  const auto channel = writer.AddChannel(*schema, "/chatter", "cdr", {});
  ASSERT_TRUE(channel.ok());
  ASSERT_TRUE(writer.Write(*channel, 0, 10, 10, Bytes{1, 2, 3}).ok());
  ASSERT_TRUE(writer.WriteMetadata("rosbag2", {{"serialized_metadata", "version: 9\n"}}).ok());
  ASSERT_TRUE(writer.Close().ok());
  const Bytes file = ReadFile(Path("m.mcap"));
  const auto records = Walk(file);
  const auto metadata = OfType(records, 0x0C), index = OfType(records, 0x0D);
  ASSERT_EQ(metadata.size(), 1u);
  ASSERT_EQ(index.size(), 1u);
  Cursor m{file, metadata[0].offset + 9};
  EXPECT_EQ(m.Str(), "rosbag2");
  m.U(4);
  EXPECT_EQ(m.Str(), "serialized_metadata");
  EXPECT_EQ(m.Str(), "version: 9\n");
  Cursor mi{file, index[0].offset + 9};
  EXPECT_EQ(mi.U(8), metadata[0].offset);
  EXPECT_EQ(mi.U(8), metadata[0].end() - metadata[0].offset);
  EXPECT_EQ(mi.Str(), "rosbag2");
  sfrt::Result<Contents> got = ReadAll(Path("m.mcap"));
  ASSERT_TRUE(got.ok()) << got.message();
  EXPECT_EQ(got->statistics->metadata_count, 1u);
  EXPECT_EQ(got->messages.size(), 1u);
}

TEST_F(McapWriter, AFullDiskIsReportedWithTheErrnoTextAndThePath) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  mcap::Writer writer;
  mcap::WriterOptions options;
  options.chunk_size = 0;                               // messages go straight to the file
  ASSERT_TRUE(writer.Open("/dev/full", options).ok());  // the Header is still buffered
  const auto channel = writer.AddChannel(0, "/big", "cdr", {});
  ASSERT_TRUE(channel.ok());
  const sfrt::Status first = writer.Write(*channel, 0, 1, 1, Bytes(1 << 17, 7));
  ASSERT_FALSE(first.ok());
  EXPECT_NE(first.message().find("'/dev/full'"), std::string::npos) << first.message();
  EXPECT_NE(first.message().find("No space left on device"), std::string::npos) << first.message();
  // The failure sticks: later calls report it rather than writing past a hole.
  EXPECT_EQ(writer.Write(*channel, 1, 2, 2, Bytes{1}).message(), first.message());
  EXPECT_EQ(writer.Close().message(), first.message());
}

TEST_F(McapWriter, RefusesWhatItCannotWrite) {
  mcap::Writer writer;
  EXPECT_FALSE(writer.Write(1, 0, 0, 0, {}).ok());  // not open
  mcap::WriterOptions options;
  options.compression = "brotli";
  EXPECT_NE(writer.Open(Path("x.mcap"), options).message().find("brotli"), std::string::npos);
  options.compression = "zstd";
  options.chunk_size = mcap::kMaxChunkSize + 1;
  EXPECT_FALSE(writer.Open(Path("x.mcap"), options).ok());
  ASSERT_TRUE(writer.Open(Path("x.mcap")).ok());
  EXPECT_FALSE(writer.AddChannel(5, "/t", "cdr", {}).ok());  // no schema 5
  EXPECT_FALSE(writer.Write(0, 0, 0, 0, {}).ok());
  EXPECT_FALSE(writer.Write(1, 0, 0, 0, {}).ok());  // no channel yet
  EXPECT_FALSE(writer.Open(Path("y.mcap")).ok());   // still open
  EXPECT_TRUE(writer.Close().ok());
  EXPECT_FALSE(writer.Close().ok());
  EXPECT_NE(writer.Open((dir_ / "no" / "such" / "dir.mcap").string())
                .message()
                .find("No such file or directory"),
            std::string::npos);
}

TEST_F(McapWriter, AnUnclosedFileIsRefusedAsTruncated) {
  {
    mcap::Writer writer;
    mcap::WriterOptions options;
    options.chunk_size = 1024;
    ASSERT_TRUE(writer.Open(Path("u.mcap"), options).ok());
    const auto channel = writer.AddChannel(0, "/t", "cdr", {});
    ASSERT_TRUE(channel.ok());
    for (uint32_t i = 0; i < 100; ++i)
      ASSERT_TRUE(writer.Write(*channel, i, i, i, Bytes(1000, 1)).ok());
  }
  ASSERT_GT(fs::file_size(Path("u.mcap")), 0u);
  EXPECT_NE(ReadError(Path("u.mcap")).find("truncated or still being written"), std::string::npos)
      << ReadError(Path("u.mcap"));
}

TEST(McapCrc32, MatchesTheStandardCheckValueAndContinues) {
  const std::string text = "123456789";
  const Bytes bytes(text.begin(), text.end());
  EXPECT_EQ(mcap::Crc32(bytes), 0xCBF43926u);  // the CRC-32/ISO-HDLC check value
  EXPECT_EQ(mcap::Crc32({}), 0u);
  for (size_t split = 0; split <= bytes.size(); ++split) {
    const std::span<const uint8_t> all(bytes);
    EXPECT_EQ(mcap::Crc32(all.subspan(split), mcap::Crc32(all.first(split))), 0xCBF43926u);
  }
}

// ============================== other writers' files ==============================

TEST_F(McapReader, ReadsAFileWithoutChunksOrSummary) {
  FileBuilder b;
  b.Append(SchemaRecord(1, "std_msgs/msg/String"));
  b.Append(ChannelRecord(4, 1, "/chatter"));
  b.Append(MessageRecord(4, 0, 100, Bytes{1, 2}));
  b.Append(MessageRecord(4, 1, 90, Bytes{}));
  WriteFile(Path("plain.mcap"), b.Finish());
  sfrt::Result<Contents> got = ReadAll(Path("plain.mcap"));
  ASSERT_TRUE(got.ok()) << got.message();
  const std::vector<Message> expected = {{4, 0, 100, 101, {1, 2}}, {4, 1, 90, 91, {}}};
  EXPECT_EQ(got->messages, expected);
  EXPECT_EQ(got->channels.at(4).topic, "/chatter");
  EXPECT_EQ(got->channels.at(4).metadata.at("offered_qos_profiles"), "- history: 3\n  depth: 0\n");
  EXPECT_EQ(got->schemas.at(1).name, "std_msgs/msg/String");
  EXPECT_FALSE(got->statistics.has_value());
  mcap::Reader reader;
  ASSERT_TRUE(reader.Open(Path("plain.mcap")).ok());
  EXPECT_EQ(reader.message_count(4), std::nullopt);  // no Statistics record
}

TEST_F(McapReader, AcceptsChannelIdZeroAndIgnoresSchemaIdZero) {
  FileBuilder b;
  b.Append(SchemaRecord(0, "invalid"));
  b.Append(ChannelRecord(0, 0, "/zero"));
  b.Append(MessageRecord(0, 5, 1, Bytes{9}));
  WriteFile(Path("zero.mcap"), b.Finish());
  sfrt::Result<Contents> got = ReadAll(Path("zero.mcap"));
  ASSERT_TRUE(got.ok()) << got.message();
  EXPECT_TRUE(got->schemas.empty());
  ASSERT_EQ(got->messages.size(), 1u);
  EXPECT_EQ(got->messages[0].channel_id, 0);
}

TEST_F(McapReader, SkipsUnknownPrivateAndIndexRecordsAndPaddedFields) {
  const Bytes pad = {0xAA, 0xBB, 0xCC};  // fields a newer writer appends, to be ignored
  FileBuilder b(pad);
  b.Append(Record(0x80, Fields().Str("private record")));
  b.Append(Record(0x03, Fields().U16(1).Str("pkg/msg/A").Str("ros2msg").Str("int8 a").Raw(pad)));
  b.Append(Record(0x04, Fields().U16(2).U16(1).Str("/a").Str("cdr").Map({}).Raw(pad)));
  const Bytes records = Concat(Concat(Record(0x20, Fields().U64(1)), MessageRecord(2, 0, 5, {7})),
                               Concat(Record(0xFF, Fields()), MessageRecord(2, 1, 6, {8, 8})));
  b.Append(Record(0x06, Fields()
                            .U64(5)
                            .U64(6)
                            .U64(records.size())
                            .U32(mcap::Crc32(records))
                            .Str("")
                            .U64(records.size())
                            .Raw(records)
                            .Raw(pad)));
  b.Append(Record(0x07, Fields().U16(2).U32(16).U64(5).U64(0)));  // a MessageIndex
  b.Append(Record(0x09, Fields()
                            .U64(1)
                            .U64(1)
                            .Str("calib.yaml")
                            .Str("text/yaml")
                            .U64(3)
                            .Raw({'a', ':', '1'})
                            .U32(0)));  // an Attachment
  b.Append(Record(0x0C, Fields().Str("rosbag2").Map({{"serialized_metadata", "x"}})));
  b.Append(MessageRecord(2, 2, 7, {9}));
  b.Append(Record(0x0F, Fields().U32(0).Raw(pad)));
  const uint64_t summary = b.Append(Record(0x7F, Fields().U32(1)));  // a future summary record
  b.Append(Record(0x04, Fields().U16(2).U16(1).Str("/a").Str("cdr").Map({})));
  b.Append(SchemaRecord(1, "pkg/msg/A", "int8 a"));  // groups in any order
  b.Append(Record(
      0x0B,
      Fields().U64(3).U16(1).U32(1).U32(1).U32(1).U32(1).U64(5).U64(7).U32(10).U16(2).U64(3).Raw(
          pad)));
  WriteFile(Path("odd.mcap"), Concat(b.bytes(), FooterAndMagic(summary, 0, 0)));
  sfrt::Result<Contents> got = ReadAll(Path("odd.mcap"));
  ASSERT_TRUE(got.ok()) << got.message();
  const std::vector<Message> expected = {
      {2, 0, 5, 6, {7}}, {2, 1, 6, 7, {8, 8}}, {2, 2, 7, 8, {9}}};
  EXPECT_EQ(got->messages, expected);
  ASSERT_TRUE(got->statistics.has_value());
  EXPECT_EQ(got->statistics->channel_message_counts.at(2), 3u);
}

TEST_F(McapReader, ReadsLz4FramesWithChecksumsAndIndependentBlocksAndZstdFramesConcatenated) {
  Bytes records;
  for (uint32_t i = 0; i < 40; ++i)
    records = Concat(records, MessageRecord(1, i, i, Bytes(5000, i)));
  LZ4F_preferences_t prefs{};
  prefs.frameInfo.blockMode = LZ4F_blockIndependent;
  prefs.frameInfo.contentChecksumFlag = LZ4F_contentChecksumEnabled;
  prefs.frameInfo.blockChecksumFlag = LZ4F_blockChecksumEnabled;
  Bytes lz4(LZ4F_compressFrameBound(records.size(), &prefs));
  lz4.resize(LZ4F_compressFrame(lz4.data(), lz4.size(), records.data(), records.size(), &prefs));
  const size_t half = records.size() / 2;  // two zstd frames back to back
  Bytes zstd(ZSTD_compressBound(records.size()) + 64);
  const size_t first = ZSTD_compress(zstd.data(), zstd.size(), records.data(), half, 3);
  const size_t second = ZSTD_compress(zstd.data() + first, zstd.size() - first,
                                      records.data() + half, records.size() - half, 3);
  zstd.resize(first + second);
  for (const auto& [name, payload] : {std::pair{"lz4", lz4}, std::pair{"zstd", zstd}}) {
    FileBuilder b;
    b.Append(ChannelRecord(1, 0, "/c"));
    b.Append(ChunkRecord(payload, records.size(), name, mcap::Crc32(records)));
    WriteFile(Path("codec.mcap"), b.Finish());
    sfrt::Result<Contents> got = ReadAll(Path("codec.mcap"));
    ASSERT_TRUE(got.ok()) << name << ": " << got.message();
    ASSERT_EQ(got->messages.size(), 40u);
    EXPECT_EQ(got->messages[39].data, Bytes(5000, 39));
  }
}

// ============================== damage ==============================

// Opening `file` cut to `size` bytes must fail; so must reading it once a Footer is appended
// (a file whose data section was cut), unless the cut keeps the whole data section.
void ExpectCutRefused(const fs::path& dir, const Bytes& file, uint64_t size, uint64_t data_end,
                      size_t messages) {
  SCOPED_TRACE("cut at " + std::to_string(size));
  const Bytes cut(file.begin(), file.begin() + size);
  WriteFile(dir / "cut.mcap", cut);
  const std::string plain = ReadError(dir / "cut.mcap");
  EXPECT_NE(plain.find("offset"), std::string::npos) << plain;
  EXPECT_NE(plain.find("cut.mcap"), std::string::npos) << plain;
  if (size < 8 + 9 + 8) return;  // no whole Header to build on
  WriteFile(dir / "cut.mcap", Concat(cut, FooterAndMagic(0, 0, 0)));
  sfrt::Result<Contents> got = ReadAll(dir / "cut.mcap");
  if (size >= data_end) {
    ASSERT_TRUE(got.ok()) << got.message();
    EXPECT_EQ(got->messages.size(), messages);
  } else if (got.ok()) {
    ADD_FAILURE() << "a file cut inside its data section reads as whole";
  } else {
    EXPECT_NE(got.message().find("offset"), std::string::npos) << got.message();
  }
}

TEST_F(McapReader, TruncationAtEveryRecordBoundaryIsRefused) {
  mcap::WriterOptions options;
  options.chunk_size = 4096;
  const Bytes file = WrittenFile("w.mcap", options);
  const auto records = Walk(file);
  const auto data_end = OfType(records, 0x0F).at(0).end();
  ASSERT_GT(records.size(), 20u);
  ExpectCutRefused(dir_, file, 0, data_end, 40);
  ExpectCutRefused(dir_, file, 8, data_end, 40);
  for (const TopRecord& r : records) ExpectCutRefused(dir_, file, r.end(), data_end, 40);
}

TEST_F(McapReader, TruncationAtRandomPointsIsRefused) {
  for (const char* codec : {"", "zstd", "lz4"}) {
    mcap::WriterOptions options;
    options.compression = codec;
    options.chunk_size = 4096;
    const Bytes file = WrittenFile("w.mcap", options);
    const auto data_end = OfType(Walk(file), 0x0F).at(0).end();
    std::mt19937_64 rng(99);
    for (int i = 0; i < 60; ++i) ExpectCutRefused(dir_, file, rng() % file.size(), data_end, 40);
  }
}

TEST_F(McapReader, ATruncatedChunkIsRefusedNamingItsOffset) {
  mcap::WriterOptions options;
  options.chunk_size = 4096;
  const Bytes file = WrittenFile("w.mcap", options);
  const TopRecord chunk = OfType(Walk(file), 0x06).at(2);
  const Bytes cut(file.begin(), file.begin() + chunk.offset + chunk.length / 2);
  WriteFile(Path("t.mcap"), Concat(cut, FooterAndMagic(0, 0, 0)));
  const std::string error = ReadError(Path("t.mcap"));
  EXPECT_NE(error.find("'" + Path("t.mcap").string() + "': Chunk at offset " +
                       std::to_string(chunk.offset) + ": "),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("runs past the end of the data section"), std::string::npos) << error;
}

TEST_F(McapReader, BadMagicIsRefused) {
  const Bytes file = WrittenFile("w.mcap", {});
  Bytes bad = file;
  bad[1] = 'X';
  WriteFile(Path("b.mcap"), bad);
  EXPECT_NE(ReadError(Path("b.mcap")).find("offset 0: not an MCAP file"), std::string::npos);
  bad = file;
  bad[5] = '1';
  WriteFile(Path("b.mcap"), bad);
  EXPECT_NE(ReadError(Path("b.mcap")).find("major version '1'"), std::string::npos);
  bad = file;
  bad[bad.size() - 3] ^= 1;
  WriteFile(Path("b.mcap"), bad);
  EXPECT_NE(ReadError(Path("b.mcap"))
                .find("no closing magic at offset " + std::to_string(file.size() - 8)),
            std::string::npos);
  WriteFile(Path("b.mcap"), Bytes{});
  EXPECT_NE(ReadError(Path("b.mcap")).find("ends at offset 0, too soon"), std::string::npos);
  EXPECT_NE(ReadError(Path("missing.mcap")).find("No such file or directory"), std::string::npos);
}

TEST_F(McapReader, ABadChunkCrcIsRefusedNamingTheChunk) {
  mcap::WriterOptions options;
  options.compression = "";
  options.chunk_size = 4096;
  Bytes file = WrittenFile("w.mcap", options);
  const TopRecord chunk = OfType(Walk(file), 0x06).at(1);
  file[chunk.end() - 1] ^= 0x40;  // the last byte of the last message's data
  WriteFile(Path("crc.mcap"), file);
  const std::string error = ReadError(Path("crc.mcap"));
  EXPECT_NE(error.find("Chunk at offset " + std::to_string(chunk.offset) + ": the CRC"),
            std::string::npos)
      << error;
}

TEST_F(McapReader, ABadSummaryCrcIsRefusedAtOpen) {
  Bytes file = WrittenFile("w.mcap", {});
  const TopRecord statistics = OfType(Walk(file), 0x0B).at(0);
  file[statistics.offset + 9] ^= 1;  // message_count
  WriteFile(Path("s.mcap"), file);
  mcap::Reader reader;
  const sfrt::Status s = reader.Open(Path("s.mcap"));
  EXPECT_NE(s.message().find("Footer at offset " + std::to_string(file.size() - 37) +
                             ": the summary's CRC"),
            std::string::npos)
      << s.message();
}

TEST_F(McapReader, ABadDataSectionCrcIsRefusedAtDataEndAndOnlyWhenDataEndHasOne) {
  mcap::WriterOptions options;
  options.chunk_size = 0;  // messages in the data section: only the data CRC covers them
  Bytes file = WrittenFile("w.mcap", options);
  const auto records = Walk(file);
  const TopRecord message = OfType(records, 0x05).at(3);
  const TopRecord data_end = OfType(records, 0x0F).at(0);
  file[message.offset + 9 + 10] ^= 4;  // its log_time
  WriteFile(Path("d.mcap"), file);
  const std::string error = ReadError(Path("d.mcap"));
  EXPECT_NE(error.find("DataEnd at offset " + std::to_string(data_end.offset) +
                       ": the data section's CRC"),
            std::string::npos)
      << error;
  SetLe(&file, data_end.offset + 9, 0, 4);  // "not available": nothing to check against
  WriteFile(Path("d.mcap"), file);
  EXPECT_EQ(ReadError(Path("d.mcap")), "");
}

TEST_F(McapReader, ALengthBeyondItsContainerIsRefusedNamingTheRecord) {
  mcap::WriterOptions options;
  options.chunk_size = 4096;
  const Bytes file = WrittenFile("w.mcap", options);
  const auto records = Walk(file);
  const TopRecord chunk = OfType(records, 0x06).at(1);
  for (const uint64_t length : {file.size(), ~uint64_t{0}, uint64_t{1} << 40}) {
    Bytes bad = file;
    SetLe(&bad, chunk.offset + 1, length, 8);
    WriteFile(Path("l.mcap"), bad);
    const std::string error = ReadError(Path("l.mcap"));
    EXPECT_NE(error.find("Chunk at offset " + std::to_string(chunk.offset) +
                         ": the record (length " + std::to_string(length) + ") runs past"),
              std::string::npos)
        << error;
  }
  // A string inside a summary record: the record names the field (summary CRC disabled).
  const TopRecord channel = OfType(records, 0x04).back();
  Bytes bad = file;
  SetLe(&bad, channel.offset + 9 + 4, 0xFFFFFFF0u, 4);  // topic length
  SetLe(&bad, bad.size() - 8 - 4, 0, 4);
  WriteFile(Path("l.mcap"), bad);
  EXPECT_NE(ReadError(Path("l.mcap"))
                .find("Channel at offset " + std::to_string(channel.offset) +
                      ": field 'topic' needs 4294967280 bytes"),
            std::string::npos)
      << ReadError(Path("l.mcap"));
  // A record inside a chunk: named by its offset in the chunk, and the chunk's.
  Bytes records_in_chunk = MessageRecord(1, 0, 0, {1, 2, 3});
  SetLe(&records_in_chunk, 1, 500, 8);
  FileBuilder b;
  b.Append(ChannelRecord(1, 0, "/c"));
  const uint64_t at = b.Append(ChunkRecord(records_in_chunk, records_in_chunk.size(), ""));
  WriteFile(Path("l.mcap"), b.Finish());
  EXPECT_NE(ReadError(Path("l.mcap"))
                .find("Message at offset 0 in the chunk at offset " + std::to_string(at) +
                      ": the record runs past"),
            std::string::npos)
      << ReadError(Path("l.mcap"));
}

TEST_F(McapReader, AChunkClaimingAHugeUncompressedSizeIsRefusedBeforeAllocating) {
  struct Case {
    const char* compression;
    uint64_t claimed;
    const char* error;
  };
  for (const Case& c : {Case{"zstd", uint64_t{1} << 40, "exceeds the 1073741824-byte limit"},
                        Case{"zstd", uint64_t{500} << 20, "is more than 16 bytes of zstd can hold"},
                        Case{"lz4", uint64_t{1} << 20, "is more than 16 bytes of lz4 can hold"},
                        Case{"", 17, "differs from the 16 bytes"}}) {
    FileBuilder b;
    b.Append(ChannelRecord(1, 0, "/c"));
    const uint64_t at = b.Append(ChunkRecord(Bytes(16, 0x5A), c.claimed, c.compression));
    WriteFile(Path("h.mcap"), b.Finish());
    g_largest_allocation = 0;
    g_track_allocations = true;
    const std::string error = ReadError(Path("h.mcap"));
    g_track_allocations = false;
    EXPECT_NE(error.find("Chunk at offset " + std::to_string(at) + ": "), std::string::npos);
    EXPECT_NE(error.find(c.error), std::string::npos) << error;
    EXPECT_LT(g_largest_allocation.load(), size_t{1} << 20) << c.compression;
  }
}

TEST_F(McapReader, NoSmallFileMakesItAllocateMoreThanItsCodecsCanExpand) {
  mcap::WriterOptions options;
  options.chunk_size = 300;
  const Bytes file = WrittenFile("w.mcap", options, 6);
  ASSERT_LT(file.size(), 16384u);
  std::mt19937_64 rng(1);
  size_t refused = 0;
  for (int i = 0; i < 1500; ++i) {
    Bytes bad = file;
    for (int flips = 1 + rng() % 4; flips > 0; --flips) {
      const size_t at = rng() % bad.size();
      bad[at] = rng() % 3 == 0 ? 0xFF : static_cast<uint8_t>(rng());
    }
    WriteFile(Path("a.mcap"), bad);
    g_largest_allocation = 0;
    g_track_allocations = true;
    refused += ReadError(Path("a.mcap")).empty() ? 0 : 1;
    g_track_allocations = false;
    ASSERT_LE(g_largest_allocation.load(), bad.size() * 32768 + (size_t{1} << 20)) << i;
  }
  EXPECT_GT(refused, 1000u);  // the CRCs catch nearly every flip
}

TEST_F(McapReader, CorruptCompressedDataIsRefusedNamingTheChunk) {
  for (const char* codec : {"zstd", "lz4"}) {
    mcap::WriterOptions options;
    options.compression = codec;
    options.chunk_size = 8192;
    options.chunk_crc = false;  // the codec itself must notice
    Bytes file = WrittenFile("w.mcap", options);
    const TopRecord chunk = OfType(Walk(file), 0x06).at(0);
    for (uint64_t i = chunk.offset + 70; i < chunk.end() - 1; i += 7) file[i] ^= 0x55;
    WriteFile(Path("z.mcap"), file);
    const std::string error = ReadError(Path("z.mcap"));
    EXPECT_NE(error.find("Chunk at offset " + std::to_string(chunk.offset)), std::string::npos)
        << codec << ": " << error;
  }
}

TEST_F(McapReader, AChunkDecompressingToAnotherSizeIsRefused) {
  const Bytes records = MessageRecord(1, 0, 0, Bytes(300, 1));
  Bytes zstd(ZSTD_compressBound(records.size()));
  zstd.resize(ZSTD_compress(zstd.data(), zstd.size(), records.data(), records.size(), 1));
  for (const uint64_t claimed : {records.size() - 1, records.size() + 1}) {
    FileBuilder b;
    b.Append(ChannelRecord(1, 0, "/c"));
    b.Append(ChunkRecord(zstd, claimed, "zstd"));
    WriteFile(Path("n.mcap"), b.Finish());
    const std::string error = ReadError(Path("n.mcap"));
    EXPECT_NE(error.find("zstd"), std::string::npos) << error;
    EXPECT_NE(error.find("Chunk at offset"), std::string::npos) << error;
  }
}

TEST_F(McapReader, RefusesWhatTheSpecForbids) {
  struct Case {
    std::vector<Bytes> records;
    std::string error;
  };
  const std::vector<Case> cases = {
      {{MessageRecord(3, 0, 0, {})}, "Message at offset 38: channel 3 has no earlier Channel"},
      {{ChannelRecord(1, 2, "/c")}, "refers to schema 2, which no earlier Schema record defines"},
      {{ChannelRecord(1, 0, "/c"), ChannelRecord(1, 0, "/d")},
       "Channel 1 differs from the earlier Channel record"},
      {{SchemaRecord(1, "a"), SchemaRecord(1, "b")}, "Schema 1 differs from the earlier Schema"},
      {{Record(0x00, Fields())}, "record 0x00 at offset 38: opcode 0 is not a valid record"},
      {{Record(0x01, Fields().Str("").Str(""))}, "Header at offset 38: a second Header"},
      {{ChannelRecord(1, 0, "/c"), ChunkRecord(Bytes(4, 0), 4, "brotli")},
       "compression 'brotli' is not supported"},
      {{Record(0x05, Fields().U16(1).U32(0))}, "fewer than a Message's 22 bytes"},
  };
  for (const Case& c : cases) {
    FileBuilder b;  // magic (8) + Header (9 + 4 + 4 + 4 + 9) = 38 bytes
    for (const Bytes& r : c.records) b.Append(r);
    WriteFile(Path("f.mcap"), b.Finish());
    EXPECT_NE(ReadError(Path("f.mcap")).find(c.error), std::string::npos)
        << ReadError(Path("f.mcap")) << "\n expected: " << c.error;
  }
  FileBuilder b;  // no DataEnd
  b.Append(ChannelRecord(1, 0, "/c"));
  const uint64_t end = b.size();
  WriteFile(Path("f.mcap"), Concat(b.bytes(), FooterAndMagic(0, 0, 0)));
  EXPECT_NE(
      ReadError(Path("f.mcap"))
          .find("the data section ends at offset " + std::to_string(end) + " without a DataEnd"),
      std::string::npos);
}

TEST_F(McapReader, KeepsReturningTheFirstError) {
  FileBuilder b;
  b.Append(ChannelRecord(1, 0, "/c"));
  b.Append(MessageRecord(1, 0, 0, {1}));
  b.Append(MessageRecord(2, 0, 0, {1}));
  b.Append(MessageRecord(1, 1, 0, {1}));
  WriteFile(Path("e.mcap"), b.Finish());
  mcap::Reader reader;
  ASSERT_TRUE(reader.Open(Path("e.mcap")).ok());
  mcap::MessageView view;
  sfrt::Result<bool> first = reader.Next(&view);
  ASSERT_TRUE(first.ok() && *first);
  sfrt::Result<bool> second = reader.Next(&view);
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.message().find("channel 2"), std::string::npos);
  sfrt::Result<bool> third = reader.Next(&view);
  ASSERT_FALSE(third.ok());
  EXPECT_EQ(third.message(), second.message());
}

}  // namespace
