#include "bag_writer.h"

#include <algorithm>

#include "messages.h"

namespace sfrt::ros2::detail {
namespace {

msg::Time TimeOf(int64_t stamp_ns) {
  msg::Time t;
  t.sec = static_cast<int32_t>(stamp_ns / 1'000'000'000);
  t.nanosec = static_cast<uint32_t>(stamp_ns % 1'000'000'000);
  return t;
}

}  // namespace

Status McapBagWriter::Open(const std::string& path) {
  path_ = path;
  mcap::WriterOptions options;
  options.profile = "ros2";
  options.compression = "zstd";
  return writer_.Open(path, options);
}

Result<size_t> McapBagWriter::TopicOf(const std::string& topic, const std::string& type) {
  if (auto t = topic_index_.find(topic); t != topic_index_.end()) return t->second;
  auto schema = schemas_.find(type);
  if (schema == schemas_.end()) {
    const msg::MessageNames* names = msg::FindMessageNames(type);
    if (names == nullptr) return Status::Error("no ROS 2 definition of " + type);
    const auto* text = reinterpret_cast<const uint8_t*>(names->definition.data());
    Result<uint16_t> id = writer_.AddSchema(
        type, "ros2msg", std::span<const uint8_t>(text, names->definition.size()));
    if (!id.ok()) return id.status();
    schema = schemas_.emplace(type, *id).first;
  }
  // rosbag2 records each publisher's QoS here; a bag sfrt writes had none to record, and an
  // empty list makes `ros2 bag play` publish with its defaults.
  Result<uint16_t> channel =
      writer_.AddChannel(schema->second, topic, "cdr", {{"offered_qos_profiles", ""}});
  if (!channel.ok()) return channel.status();
  topic_index_[topic] = topics_.size();
  topics_.push_back({topic, type, 0});
  channels_.push_back(*channel);
  return topics_.size() - 1;
}

std::string McapBagWriter::Put(size_t t, int64_t stamp_ns) {
  const auto time = static_cast<uint64_t>(stamp_ns);
  const auto sequence = static_cast<uint32_t>(topics_[t].messages);
  if (Status s = writer_.Write(channels_[t], sequence, time, time, buffer_); !s.ok()) {
    return s.message();
  }
  ++topics_[t].messages;
  first_ns_ = messages_ == 0 ? stamp_ns : std::min(first_ns_, stamp_ns);
  last_ns_ = messages_ == 0 ? stamp_ns : std::max(last_ns_, stamp_ns);
  ++messages_;
  return "";
}

std::string McapBagWriter::WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t /*seq*/,
                                      const std::string& frame_id, const std::string& encoding,
                                      uint32_t height, uint32_t width, uint32_t step,
                                      const uint8_t* data) {
  Result<size_t> t = TopicOf(topic, "sensor_msgs/msg/Image");
  if (!t.ok()) return "'" + path_ + "': " + t.message();
  msg::ImageView image;
  image.header.stamp = TimeOf(stamp_ns);
  image.header.frame_id = frame_id;
  image.height = height;
  image.width = width;
  image.encoding = encoding;
  image.is_bigendian = 0;
  image.step = step;
  image.data = std::span<const uint8_t>(data, static_cast<size_t>(step) * height);
  msg::Encode(image, &buffer_);
  return Put(*t, stamp_ns);
}

std::string McapBagWriter::WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t /*seq*/,
                                       const std::string& frame_id) {
  Result<size_t> t = TopicOf(topic, "std_msgs/msg/Header");
  if (!t.ok()) return "'" + path_ + "': " + t.message();
  msg::Header header;
  header.stamp = TimeOf(stamp_ns);
  header.frame_id = frame_id;
  msg::Encode(header, &buffer_);
  return Put(*t, stamp_ns);
}

Status McapBagWriter::Close() { return writer_.Close(); }

std::vector<RecordedTopic> McapBagWriter::topics() const { return topics_; }

}  // namespace sfrt::ros2::detail
