// One file of a rosbag2 bag, as its storage plugin laid it out: rosbag2's sqlite3 storage (.db3)
// or MCAP (.mcap). A bag is a folder of such files (split by size or duration) with a
// metadata.yaml beside them (bag_folder.h). Both storages hold each message as its serialised
// bytes (CDR for ROS 2), the topic it is on and its receive time. Not installed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::ros2 {

// A topic as the file declares it.
struct StoredTopic {
  std::string name;                  // "/left/image_rect"
  std::string type;                  // "sensor_msgs/msg/Image"
  std::string serialization_format;  // "cdr"
  int64_t messages = -1;             // in this file; -1 where the file does not say
};

// One message. A view: `data` stays valid until the next StorageFile::Next().
struct StoredMessage {
  size_t topic = 0;          // index into StorageFile::topics()
  int64_t receive_ns = 0;    // rosbag2's "timestamp" / MCAP log_time: when it was recorded
  int64_t file_offset = -1;  // where the message's record starts (MCAP), for error messages
  const uint8_t* data = nullptr;
  size_t size = 0;
};

// One storage file read front to back. Not thread-safe.
class StorageFile {
 public:
  virtual ~StorageFile() = default;
  // Opens `path` and reads its topics. Errors name the file and what is wrong with it.
  virtual Status Open(const std::string& path) = 0;
  virtual const std::vector<StoredTopic>& topics() const = 0;
  // Restricts Next() to the topics at these indices (into topics()), from the file's start.
  virtual Status Select(const std::vector<size_t>& topics) = 0;
  // The next selected message in the file's order (receive time for .db3; the order recorded for
  // MCAP): true, false at the end, or an error naming the file and where in it.
  virtual Result<bool> Next(StoredMessage* out) = 0;
};

// rosbag2's sqlite3 storage: tables `topics` (id, name, type, serialization_format, ...) and
// `messages` (id, topic_id, timestamp, data), read in (timestamp, id) order as rosbag2 plays them.
// Opened read-only; bags of every schema version since Foxy (older `topics` tables lack the QoS
// and type-hash columns, which are not read).
std::unique_ptr<StorageFile> MakeDb3File();

// MCAP (mcap.dev/spec), through mcap.h: channels are the topics (topic name, schema name as the
// type, message_encoding as the serialization format).
std::unique_ptr<StorageFile> MakeMcapFile();

}  // namespace sfrt::ros2
