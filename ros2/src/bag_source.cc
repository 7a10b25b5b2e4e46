#include "sfrt/ros2/bag_source.h"

#include <set>
#include <utility>
#include <vector>

#include "bag_folder.h"
#include "messages.h"
#include "storage.h"

namespace sfrt::ros2 {
namespace {

constexpr const char* kImageType = "sensor_msgs/msg/Image";
constexpr const char* kCompressedType = "sensor_msgs/msg/CompressedImage";

int64_t StampNs(const msg::Time& t) {
  return static_cast<int64_t>(t.sec) * 1'000'000'000 + static_cast<int64_t>(t.nanosec);
}

// One storage file of the bag, open, and where the two topics are in it (-1: not in this file).
struct OpenFile {
  std::unique_ptr<StorageFile> file;
  std::string path;
  int topic[2] = {-1, -1};
};

// A rosbag2 bag as the pipeline's bag replay reads it: its files one after the other.
class Rosbag2Bag final : public pipeline::ImageBag {
 public:
  Result<BagProbe> Open(const std::string& path, const std::string& left,
                        const std::string& right) override {
    topics_[0] = left;
    topics_[1] = right;
    Result<BagLayout> layout = ResolveBagLayout(path);
    if (!layout.ok()) return layout.status();
    BagProbe probe;
    probe.format =
        layout->files.front().storage == Storage::kMcap ? "rosbag2 MCAP" : "rosbag2 sqlite3";
    for (const BagFile& f : layout->files) {
      if (Status s = OpenOne(f, &probe); !s.ok()) return s;
    }
    if (Status s = CheckTopicsFound(path, probe); !s.ok()) return s;
    return probe;
  }

  Result<bool> Next(pipeline::BagImage* out) override {
    while (current_ < files_.size()) {
      OpenFile& f = files_[current_];
      StoredMessage m;
      Result<bool> more = f.file->Next(&m);
      if (!more.ok()) return more.status();
      if (*more) return Decode(f, m, out);
      ++current_;
    }
    return false;
  }

 private:
  // Opens one file, finds the two topics in it, checks their types, adds up their counts.
  Status OpenOne(const BagFile& f, BagProbe* probe) {
    OpenFile open;
    open.path = f.path;
    open.file = f.storage == Storage::kMcap ? MakeMcapFile() : MakeDb3File();
    if (Status s = open.file->Open(f.path); !s.ok()) return s;
    const std::vector<StoredTopic>& topics = open.file->topics();
    std::vector<size_t> selected;
    for (size_t t = 0; t < topics.size(); ++t) {
      listed_.insert(topics[t].name + " (" + topics[t].type + ")");
      for (int side = 0; side < 2; ++side) {
        if (topics[t].name != topics_[side]) continue;
        if (Status s = CheckType(f.path, topics[t]); !s.ok()) return s;
        open.topic[side] = static_cast<int>(t);
        selected.push_back(t);
        std::string& type = side == 0 ? probe->left_type : probe->right_type;
        type = topics[t].type;
        int64_t& count = side == 0 ? probe->left_messages : probe->right_messages;
        count = (count < 0 || topics[t].messages < 0) ? -1 : count + topics[t].messages;
      }
    }
    if (Status s = open.file->Select(selected); !s.ok()) return s;
    files_.push_back(std::move(open));
    return Status::Ok();
  }

  static Status CheckType(const std::string& path, const StoredTopic& topic) {
    if (topic.type != kImageType && topic.type != kCompressedType) {
      return Status::Error("'" + path + "': topic '" + topic.name + "' carries " + topic.type +
                           ", not " + kImageType + " or " + kCompressedType);
    }
    if (topic.serialization_format != "cdr") {
      return Status::Error("'" + path + "': topic '" + topic.name + "' is serialised as '" +
                           topic.serialization_format + "', not cdr");
    }
    return Status::Ok();
  }

  Status CheckTopicsFound(const std::string& path, const BagProbe& probe) const {
    for (int side = 0; side < 2; ++side) {
      const std::string& type = side == 0 ? probe.left_type : probe.right_type;
      if (type.empty()) {
        std::string has;
        for (const std::string& t : listed_) has += (has.empty() ? "" : ", ") + t;
        return Status::Error("'" + path + "' has no topic '" + topics_[side] + "' (it has " +
                             (has.empty() ? std::string("no topic") : has) + ")");
      }
    }
    return Status::Ok();
  }

  Result<bool> Decode(const OpenFile& f, const StoredMessage& m, pipeline::BagImage* out) {
    const int side = static_cast<int>(m.topic) == f.topic[0] ? 0 : 1;
    const std::string type = f.file->topics()[m.topic].type;
    const std::span<const uint8_t> bytes(m.data, m.size);
    Status decoded = Status::Ok();
    pipeline::ImageMessage& im = out->message;
    if (type == kImageType) {
      decoded = msg::DecodeImageView(bytes, &image_);
      im.compressed = false;
      im.stamp_ns = StampNs(image_.header.stamp);
      im.encoding.assign(image_.encoding);
      im.height = image_.height;
      im.width = image_.width;
      im.step = image_.step;
      im.data = image_.data.data();
      im.size = image_.data.size();
    } else {
      decoded = msg::Decode(bytes, &compressed_);
      im.compressed = true;
      im.stamp_ns = StampNs(compressed_.header.stamp);
      im.encoding = compressed_.format;
      im.height = im.width = im.step = 0;
      im.data = compressed_.data.data();
      im.size = compressed_.data.size();
    }
    if (!decoded.ok()) {
      return Status::Error(
          "'" + f.path + "': " + topics_[side] + " message " + std::to_string(read_[side]) +
          (m.file_offset >= 0 ? " at offset " + std::to_string(m.file_offset) : std::string()) +
          " does not decode: " + decoded.message());
    }
    out->side = side;
    out->index = read_[side]++;
    return true;
  }

  std::string topics_[2];
  std::set<std::string> listed_;  // every topic the bag has, for the error that one is missing
  std::vector<OpenFile> files_;
  size_t current_ = 0;
  int64_t read_[2] = {0, 0};
  msg::ImageView image_;             // the last raw image: views into the file's buffers
  msg::CompressedImage compressed_;  // the last compressed image (its buffers reused)
};

}  // namespace

Result<BagProbe> ProbeBag(const BagReplaySpec& spec) {
  Rosbag2Bag bag;
  return pipeline::ProbeBag(spec, &bag);
}

std::unique_ptr<pipeline::FrameSource> MakeBagSource(const BagReplaySpec& spec) {
  return pipeline::MakeBagReplaySource(spec, std::make_unique<Rosbag2Bag>());
}

}  // namespace sfrt::ros2
