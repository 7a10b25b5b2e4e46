// An MCAP file as a rosbag2 storage file (storage.h), through mcap.h.
#include <map>
#include <set>
#include <utility>

#include "mcap.h"
#include "storage.h"

namespace sfrt::ros2 {
namespace {

class McapFile final : public StorageFile {
 public:
  Status Open(const std::string& path) override {
    path_ = path;
    if (Status s = reader_.Open(path); !s.ok()) return s;
    channels_ = reader_.channels();
    schemas_ = reader_.schemas();
    std::map<uint16_t, int64_t> counted;
    if (channels_.empty()) {  // no summary: the channels are met in the data section
      Result<std::map<uint16_t, int64_t>> scanned = ScanChannels();
      if (!scanned.ok()) return scanned.status();
      counted = std::move(scanned).value();
    }
    for (const auto& [id, channel] : channels_) {
      StoredTopic topic;
      topic.name = channel.topic;
      const auto schema = schemas_.find(channel.schema_id);
      topic.type = schema == schemas_.end() ? std::string() : schema->second.name;
      topic.serialization_format = channel.message_encoding;
      const std::optional<uint64_t> count = reader_.message_count(id);
      topic.messages = count ? static_cast<int64_t>(*count) : counted.count(id) ? counted[id] : -1;
      topic_of_channel_[id] = topics_.size();
      channel_of_topic_.push_back(id);
      topics_.push_back(std::move(topic));
    }
    return Status::Ok();
  }

  const std::vector<StoredTopic>& topics() const override { return topics_; }

  Status Select(const std::vector<size_t>& topics) override {
    std::set<uint16_t> channels;
    for (size_t t : topics) {
      if (t >= channel_of_topic_.size()) {
        return Status::Error("'" + path_ + "': no topic " + std::to_string(t));
      }
      channels.insert(channel_of_topic_[t]);
    }
    // From the file's start again: a reader keeps its filter across Open().
    reader_.SetChannelFilter(std::move(channels));
    return reader_.Open(path_);
  }

  Result<bool> Next(StoredMessage* out) override {
    mcap::MessageView m;
    Result<bool> more = reader_.Next(&m);
    if (!more.ok() || !*more) return more;
    const auto topic = topic_of_channel_.find(m.channel_id);
    if (topic == topic_of_channel_.end()) {  // a channel the summary did not list
      return Status::Error("'" + path_ + "': a message at offset " +
                           std::to_string(m.record_offset) + " on channel " +
                           std::to_string(m.channel_id) + ", which the file does not declare");
    }
    out->topic = topic->second;
    out->receive_ns = static_cast<int64_t>(m.log_time);
    out->file_offset = static_cast<int64_t>(m.record_offset);
    out->data = m.data;
    out->size = m.size;
    return true;
  }

 private:
  // Reads the whole file once, for a file without a summary section: its channels, and the
  // messages on each. Then from the start again.
  Result<std::map<uint16_t, int64_t>> ScanChannels() {
    std::map<uint16_t, int64_t> counts;
    mcap::MessageView m;
    while (true) {
      Result<bool> more = reader_.Next(&m);
      if (!more.ok()) return more.status();
      if (!*more) break;
      ++counts[m.channel_id];
    }
    channels_ = reader_.channels();  // as the scan met them
    schemas_ = reader_.schemas();
    if (Status s = reader_.Open(path_); !s.ok()) return s;
    return counts;
  }

  std::string path_;
  mcap::Reader reader_;
  std::map<uint16_t, mcap::Channel> channels_;
  std::map<uint16_t, mcap::Schema> schemas_;
  std::vector<StoredTopic> topics_;
  std::map<uint16_t, size_t> topic_of_channel_;
  std::vector<uint16_t> channel_of_topic_;
};

}  // namespace

std::unique_ptr<StorageFile> MakeMcapFile() { return std::make_unique<McapFile>(); }

}  // namespace sfrt::ros2
