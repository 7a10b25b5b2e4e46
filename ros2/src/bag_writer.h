// The flow's messages (pipeline/flow_messages.h) into one MCAP file as rosbag2 stores them:
// ROS 2 types, CDR, a schema and a channel per topic. Not installed.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "mcap.h"
#include "sfrt/pipeline/message_io.h"

namespace sfrt::ros2::detail {

// What a bag recorded on one topic, for metadata.yaml.
struct RecordedTopic {
  std::string name;
  std::string type;
  int64_t messages = 0;
};

class McapBagWriter final : public pipeline::MessageWriter {
 public:
  Status Open(const std::string& path);
  std::string WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                         const std::string& frame_id, const std::string& encoding, uint32_t height,
                         uint32_t width, uint32_t step, const uint8_t* data) override;
  std::string WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                          const std::string& frame_id) override;
  Status Close();

  // In the order of their first message.
  std::vector<RecordedTopic> topics() const;
  int64_t first_stamp_ns() const { return first_ns_; }
  int64_t last_stamp_ns() const { return last_ns_; }
  int64_t messages() const { return messages_; }

 private:
  // The index of `topic` in topics_ (its channel made at its first message, with the schema of
  // `type`).
  Result<size_t> TopicOf(const std::string& topic, const std::string& type);
  std::string Put(size_t topic, int64_t stamp_ns);  // buffer_ as the topic's next message

  mcap::Writer writer_;
  std::string path_;
  std::map<std::string, uint16_t> schemas_;    // by type
  std::map<std::string, size_t> topic_index_;  // into topics_
  std::vector<RecordedTopic> topics_;
  std::vector<uint16_t> channels_;  // each topic's channel
  std::vector<uint8_t> buffer_;     // the CDR of the message being written
  int64_t first_ns_ = 0;
  int64_t last_ns_ = 0;
  int64_t messages_ = 0;
};

}  // namespace sfrt::ros2::detail
