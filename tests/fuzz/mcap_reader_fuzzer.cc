// Fuzz target: the MCAP reader (ros2/src/mcap.h), which takes paths, so the input is written to
// a file in a private scratch directory and read to its end. A file the reader accepts whole
// must survive sfrt's Writer: its schemas, channels and messages, written again (compression
// and chunking picked by the input's size) and read back, come out unchanged.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string_view>
#include <vector>

#include "fuzz/scratch_dir.h"
#include "mcap.h"

namespace {

namespace mcap = sfrt::ros2::mcap;

struct Message {
  uint16_t channel_id;
  uint32_t sequence;
  uint64_t log_time, publish_time;
  std::vector<uint8_t> data;
  bool operator==(const Message&) const = default;
};

// Every message of `path`; false when the reader refuses the file.
bool ReadMessages(const std::filesystem::path& path, mcap::Reader* reader,
                  std::vector<Message>* out) {
  if (!reader->Open(path).ok()) return false;
  mcap::MessageView m;
  for (;;) {
    const sfrt::Result<bool> next = reader->Next(&m);
    if (!next.ok()) return false;
    if (!*next) return true;
    out->push_back({m.channel_id, m.sequence, m.log_time, m.publish_time,
                    std::vector<uint8_t>(m.data, m.data + m.size)});
  }
}

[[noreturn]] void Die(const char* what) {
  std::fprintf(stderr, "MCAP rewrite: %s\n", what);
  std::abort();
}

// Writes what `reader` read to `path`; the ids it assigns go into the two maps. False when the
// Writer cannot take it (65536 channels, say), which is not the reader's fault.
bool Rewrite(const mcap::Reader& reader, const std::vector<Message>& messages,
             const std::filesystem::path& path, size_t size,
             std::map<uint16_t, uint16_t>* schema_ids, std::map<uint16_t, uint16_t>* channel_ids) {
  mcap::Writer writer;
  mcap::WriterOptions options;
  options.compression = size % 3 == 0 ? "" : size % 3 == 1 ? "zstd" : "lz4";
  options.chunk_size = size % 2 == 0 ? 0 : 512;
  if (!writer.Open(path, options).ok()) Die("cannot open the output");
  for (const auto& [id, s] : reader.schemas()) {
    const auto new_id = writer.AddSchema(s.name, s.encoding, s.data);
    if (!new_id.ok()) return false;
    (*schema_ids)[id] = *new_id;
  }
  (*schema_ids)[0] = 0;
  for (const auto& [id, c] : reader.channels()) {
    const auto schema = schema_ids->find(c.schema_id);
    if (schema == schema_ids->end()) Die("a channel's schema is unknown after a clean read");
    const auto new_id = writer.AddChannel(schema->second, c.topic, c.message_encoding, c.metadata);
    if (!new_id.ok()) return false;
    (*channel_ids)[id] = *new_id;
  }
  for (const Message& m : messages) {
    if (!writer.Write(channel_ids->at(m.channel_id), m.sequence, m.log_time, m.publish_time, m.data)
             .ok()) {
      Die("cannot write a message");
    }
  }
  if (!writer.Close().ok()) Die("cannot close the output");
  return true;
}

void CheckRewrite(const mcap::Reader& first, const std::vector<Message>& messages, size_t size) {
  const std::filesystem::path out = sfrt::fuzz::ScratchDir("sfrt-fuzz-mcap") / "out.mcap";
  std::map<uint16_t, uint16_t> schema_ids, channel_ids;
  if (!Rewrite(first, messages, out, size, &schema_ids, &channel_ids)) return;
  mcap::Reader second;
  std::vector<Message> again;
  if (!ReadMessages(out, &second, &again)) Die("the rewritten file does not read");
  if (again.size() != messages.size()) Die("message count changed");
  for (size_t i = 0; i < messages.size(); ++i) {
    Message expected = messages[i];
    expected.channel_id = channel_ids.at(expected.channel_id);
    if (!(again[i] == expected)) Die("a message changed");
  }
  for (const auto& [id, s] : first.schemas()) {
    mcap::Schema expected = s;
    expected.id = schema_ids.at(id);
    if (second.schemas().at(expected.id) != expected) Die("a schema changed");
  }
  for (const auto& [id, c] : first.channels()) {
    mcap::Channel expected = c;
    expected.id = channel_ids.at(id);
    expected.schema_id = schema_ids.at(c.schema_id);
    if (second.channels().at(expected.id) != expected) Die("a channel changed");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path in = sfrt::fuzz::ScratchDir("sfrt-fuzz-mcap") / "in.mcap";
  sfrt::fuzz::WriteFileOrDie(in, std::string_view(reinterpret_cast<const char*>(data), size));
  mcap::Reader reader;
  std::vector<Message> messages;
  if (!ReadMessages(in, &reader, &messages)) return 0;
  size_t bytes = 0;
  for (const Message& m : messages) bytes += m.data.size();
  if (bytes <= (size_t{4} << 20)) CheckRewrite(reader, messages, size);  // keep runs fast
  return 0;
}
