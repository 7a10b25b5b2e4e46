// mcap_tool: the C++ side of the MCAP cross-check against @mcap/core (mcap_oracle_check.mjs).
//
//   mcap_tool dump IN.mcap [CHANNEL_ID,...]
//     Reads IN.mcap with sfrt's Reader and prints JSON lines: one {"type":"message",...} per
//     message in file order (only the listed channels, when given), then "header", every
//     "schema", every "channel", "statistics" (when the file has one) and {"type":"end"}.
//     Integers above 2^53 do not survive JSON numbers, so times are decimal strings; bytes are
//     lowercase hex. On an error: {"type":"error","message":...} and exit status 1.
//   mcap_tool write OUT.mcap SPEC.txt
//     Writes OUT.mcap with sfrt's Writer from SPEC.txt, one command per line, fields separated
//     by single spaces, every string and byte field as lowercase hex ("-" for empty):
//       options <compression|-> <chunk_size> <chunk_crc 0|1> <profile> <library>   (first line)
//       schema <expected id> <name> <encoding> <data>
//       channel <expected id> <schema id> <topic> <message encoding> <n> [<key> <value>]*n
//       message <channel id> <sequence> <log_time> <publish_time> <data>
//       metadata <name> <n> [<key> <value>]*n
//     Exit status 1, with the reason on stderr, when the spec or the Writer fails.
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "mcap.h"

namespace {

namespace mcap = sfrt::ros2::mcap;

std::string Hex(const uint8_t* data, size_t size) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out(size * 2, '0');
  for (size_t i = 0; i < size; ++i) {
    out[2 * i] = kDigits[data[i] >> 4];
    out[2 * i + 1] = kDigits[data[i] & 15];
  }
  return out;
}

std::string Json(const std::string& text) {
  std::string out = "\"";
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\u%04x", c);
      out += escaped;
    } else {
      out += ch;  // UTF-8 passes through
    }
  }
  return out + "\"";
}

std::string JsonMap(const std::map<std::string, std::string>& map) {
  std::string out = "{";
  for (const auto& [key, value] : map) {
    if (out.size() > 1) out += ",";
    out += Json(key) + ":" + Json(value);
  }
  return out + "}";
}

std::string Quoted(uint64_t v) { return "\"" + std::to_string(v) + "\""; }

void PrintMessage(const mcap::MessageView& m) {
  std::printf(
      "{\"type\":\"message\",\"channel_id\":%u,\"sequence\":%u,\"log_time\":%s,"
      "\"publish_time\":%s,\"data\":\"%s\"}\n",
      unsigned{m.channel_id}, unsigned{m.sequence}, Quoted(m.log_time).c_str(),
      Quoted(m.publish_time).c_str(), Hex(m.data, m.size).c_str());
}

void PrintSummary(const mcap::Reader& reader) {
  std::printf("{\"type\":\"header\",\"profile\":%s,\"library\":%s}\n",
              Json(reader.profile()).c_str(), Json(reader.library()).c_str());
  for (const auto& [id, s] : reader.schemas()) {
    std::printf("{\"type\":\"schema\",\"id\":%u,\"name\":%s,\"encoding\":%s,\"data\":\"%s\"}\n",
                unsigned{id}, Json(s.name).c_str(), Json(s.encoding).c_str(),
                Hex(s.data.data(), s.data.size()).c_str());
  }
  for (const auto& [id, c] : reader.channels()) {
    std::printf(
        "{\"type\":\"channel\",\"id\":%u,\"schema_id\":%u,\"topic\":%s,"
        "\"message_encoding\":%s,\"metadata\":%s}\n",
        unsigned{id}, unsigned{c.schema_id}, Json(c.topic).c_str(),
        Json(c.message_encoding).c_str(), JsonMap(c.metadata).c_str());
  }
  if (const auto& s = reader.statistics()) {
    std::string counts = "{";
    for (const auto& [id, count] : s->channel_message_counts) {
      if (counts.size() > 1) counts += ",";
      counts += "\"" + std::to_string(id) + "\":" + Quoted(count);
    }
    std::printf(
        "{\"type\":\"statistics\",\"message_count\":%s,\"schema_count\":%u,"
        "\"channel_count\":%u,\"attachment_count\":%u,\"metadata_count\":%u,"
        "\"chunk_count\":%u,\"message_start_time\":%s,\"message_end_time\":%s,"
        "\"channel_message_counts\":%s}}\n",
        Quoted(s->message_count).c_str(), unsigned{s->schema_count}, unsigned{s->channel_count},
        unsigned{s->attachment_count}, unsigned{s->metadata_count}, unsigned{s->chunk_count},
        Quoted(s->message_start_time).c_str(), Quoted(s->message_end_time).c_str(), counts.c_str());
  }
}

int Fail(const std::string& message) {
  std::printf("{\"type\":\"error\",\"message\":%s}\n", Json(message).c_str());
  std::fprintf(stderr, "mcap_tool: %s\n", message.c_str());
  return 1;
}

int Dump(const std::string& path, const char* channels) {
  mcap::Reader reader;
  if (channels != nullptr) {
    std::set<uint16_t> ids;
    std::istringstream list(channels);
    for (std::string id; std::getline(list, id, ',');) ids.insert(std::stoi(id));
    reader.SetChannelFilter(ids);
  }
  if (sfrt::Status s = reader.Open(path); !s.ok()) return Fail(s.message());
  mcap::MessageView message;
  for (;;) {
    sfrt::Result<bool> next = reader.Next(&message);
    if (!next.ok()) return Fail(next.message());
    if (!*next) break;
    PrintMessage(message);
  }
  PrintSummary(reader);
  std::printf("{\"type\":\"end\"}\n");
  return 0;
}

// ---- write ----

std::optional<std::vector<uint8_t>> Unhex(const std::string& text) {
  if (text == "-") return std::vector<uint8_t>();
  if (text.size() % 2 != 0) return std::nullopt;
  std::vector<uint8_t> out;
  for (size_t i = 0; i < text.size(); i += 2) {
    const auto digit = [](char c) {
      return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
    };
    const int hi = digit(text[i]), lo = digit(text[i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    out.push_back(static_cast<uint8_t>(hi * 16 + lo));
  }
  return out;
}

// Reads the fields of one spec line, failing (by exception, caught in Write) on bad input.
class Fields {
 public:
  explicit Fields(const std::string& line) : in_(line) {}
  std::string Token() {
    std::string token;
    if (!(in_ >> token)) throw std::runtime_error("missing field");
    return token;
  }
  uint64_t Number() { return std::stoull(Token()); }
  std::vector<uint8_t> Bytes() {
    auto bytes = Unhex(Token());
    if (!bytes) throw std::runtime_error("bad hex field");
    return *bytes;
  }
  std::string Text() {
    const auto bytes = Bytes();
    return std::string(bytes.begin(), bytes.end());
  }
  std::map<std::string, std::string> Map() {
    std::map<std::string, std::string> map;
    for (uint64_t n = Number(); n > 0; --n) {
      std::string key = Text();
      map[key] = Text();
    }
    return map;
  }

 private:
  std::istringstream in_;
};

void Check(const sfrt::Status& s) {
  if (!s.ok()) throw std::runtime_error(s.message());
}

void Expect(uint64_t expected, const sfrt::Result<uint16_t>& got) {
  Check(got.status());
  if (*got != expected) {
    throw std::runtime_error("id " + std::to_string(*got) + ", expected " +
                             std::to_string(expected));
  }
}

void Apply(mcap::Writer* writer, const std::string& command, Fields* f) {
  if (command == "schema") {
    const uint64_t id = f->Number();
    const std::string name = f->Text(), encoding = f->Text();
    Expect(id, writer->AddSchema(name, encoding, f->Bytes()));
  } else if (command == "channel") {
    const uint64_t id = f->Number();
    const auto schema_id = static_cast<uint16_t>(f->Number());
    const std::string topic = f->Text(), encoding = f->Text();
    Expect(id, writer->AddChannel(schema_id, topic, encoding, f->Map()));
  } else if (command == "message") {
    const auto channel_id = static_cast<uint16_t>(f->Number());
    const auto sequence = static_cast<uint32_t>(f->Number());
    const uint64_t log_time = f->Number(), publish_time = f->Number();
    Check(writer->Write(channel_id, sequence, log_time, publish_time, f->Bytes()));
  } else if (command == "metadata") {
    const std::string name = f->Text();
    Check(writer->WriteMetadata(name, f->Map()));
  } else {
    throw std::runtime_error("unknown command '" + command + "'");
  }
}

int Write(const std::string& path, const std::string& spec_path) {
  std::ifstream spec(spec_path);
  if (!spec) return Fail("cannot read " + spec_path);
  mcap::Writer writer;
  std::string line;
  int line_number = 0;
  try {
    while (std::getline(spec, line)) {
      ++line_number;
      if (line.empty()) continue;
      Fields f(line);
      const std::string command = f.Token();
      if (command == "options") {
        mcap::WriterOptions options;
        options.compression = f.Text();
        options.chunk_size = f.Number();
        options.chunk_crc = f.Number() != 0;
        options.profile = f.Text();
        options.library = f.Text();
        Check(writer.Open(path, options));
      } else {
        Apply(&writer, command, &f);
      }
    }
    Check(writer.Close());
  } catch (const std::exception& e) {
    return Fail(spec_path + ":" + std::to_string(line_number) + ": " + e.what());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string command = argc > 1 ? argv[1] : "";
  if (command == "dump" && (argc == 3 || argc == 4)) {
    return Dump(argv[2], argc == 4 ? argv[3] : nullptr);
  }
  if (command == "write" && argc == 4) return Write(argv[2], argv[3]);
  std::fprintf(stderr,
               "usage: %s dump IN.mcap [CHANNEL_ID,...]\n"
               "       %s write OUT.mcap SPEC.txt\n",
               argv[0], argv[0]);
  return 2;
}
