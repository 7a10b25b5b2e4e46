// C++17: see bag_reader.h.
#include "bag_reader.h"

#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/Header.h>

#include <cstring>
#include <optional>

#include "ros_messages.h"

namespace sfrt::ros::detail {
namespace {

constexpr const char* kImageType = "sensor_msgs/Image";
constexpr const char* kCompressedType = "sensor_msgs/CompressedImage";

}  // namespace

struct BagReader::Impl {
  std::string path;
  std::string topics[2];
  rosbag::Bag bag;
  std::optional<rosbag::View> view;
  rosbag::View::iterator it;
  int64_t read[2] = {0, 0};
};

BagReader::BagReader() : impl_(std::make_unique<Impl>()) {}
BagReader::~BagReader() = default;

std::string BagReader::Open(const std::string& path, const std::string& left,
                            const std::string& right, BagTopics* topics) {
  Impl& s = *impl_;
  s.path = path;
  s.topics[0] = left;
  s.topics[1] = right;
  try {
    s.bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagUnindexedException&) {
    return "'" + path + "' is not indexed (a recording cut short?); `rosbag reindex` repairs it";
  } catch (const rosbag::BagException& e) {
    return "cannot read '" + path + "' as a ROS bag: " + e.what();
  }
  try {
    rosbag::View all(s.bag);
    std::string listed;
    std::string types[2];
    for (const rosbag::ConnectionInfo* c : all.getConnections()) {
      listed += (listed.empty() ? "" : ", ") + c->topic + " (" + c->datatype + ")";
      for (int side = 0; side < 2; ++side) {
        if (c->topic != s.topics[side]) continue;
        if (c->datatype != kImageType && c->datatype != kCompressedType) {
          return "'" + path + "': topic '" + c->topic + "' carries " + c->datatype + ", not " +
                 kImageType + " or " + kCompressedType;
        }
        types[side] = c->datatype;
      }
    }
    for (int side = 0; side < 2; ++side) {
      if (types[side].empty()) {
        return "'" + path + "' has no topic '" + s.topics[side] + "' (it has " +
               (listed.empty() ? std::string("no topic") : listed) + ")";
      }
    }
    topics->left_type = types[0];
    topics->right_type = types[1];
    topics->left_messages =
        static_cast<int64_t>(rosbag::View(s.bag, rosbag::TopicQuery(left)).size());
    topics->right_messages =
        static_cast<int64_t>(rosbag::View(s.bag, rosbag::TopicQuery(right)).size());
    s.view.emplace(s.bag, rosbag::TopicQuery(std::vector<std::string>{left, right}));
    s.it = s.view->begin();
  } catch (const rosbag::BagException& e) {
    return "'" + path + "': " + e.what();
  }
  return "";
}

bool BagReader::Next(BagImage* out, std::string* error) {
  Impl& s = *impl_;
  try {
    if (s.it == s.view->end()) return false;
    const rosbag::MessageInstance& msg = *s.it;
    out->side = msg.getTopic() == s.topics[0] ? 0 : 1;
    out->index = s.read[out->side]++;
    if (msg.getDataType() == kImageType) {
      boost::shared_ptr<sensor_msgs::Image> im = msg.instantiate<sensor_msgs::Image>();
      out->compressed = false;
      out->stamp_ns = static_cast<int64_t>(im->header.stamp.toNSec());
      out->encoding = im->encoding;
      out->height = im->height;
      out->width = im->width;
      out->step = im->step;
      out->data.swap(im->data);
    } else {
      boost::shared_ptr<sensor_msgs::CompressedImage> im =
          msg.instantiate<sensor_msgs::CompressedImage>();
      out->compressed = true;
      out->stamp_ns = static_cast<int64_t>(im->header.stamp.toNSec());
      out->encoding = im->format;
      out->height = out->width = out->step = 0;
      out->data.swap(im->data);
    }
    ++s.it;
    return true;
  } catch (const rosbag::BagException& e) {
    *error = "'" + s.path + "': " + e.what() + " (a truncated bag?)";
    return false;
  }
}

struct BagWriter::Impl {
  std::string path;
  rosbag::Bag bag;
  bool open = false;
};

BagWriter::BagWriter() : impl_(std::make_unique<Impl>()) {}
BagWriter::~BagWriter() { (void)Close(); }

std::string BagWriter::Open(const std::string& path) {
  impl_->path = path;
  try {
    impl_->bag.open(path, rosbag::bagmode::Write);
  } catch (const rosbag::BagException& e) {
    return "cannot create the bag '" + path + "': " + e.what();
  }
  impl_->open = true;
  return "";
}

std::string BagWriter::WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                                  const std::string& frame_id, const std::string& encoding,
                                  uint32_t height, uint32_t width, uint32_t step,
                                  const uint8_t* data) {
  sensor_msgs::Image im;
  FillImage(&im, stamp_ns, seq, frame_id, encoding, height, width, step, data);
  try {
    impl_->bag.write(topic, im.header.stamp, im);
  } catch (const rosbag::BagException& e) {
    return "cannot write to the bag '" + impl_->path + "': " + e.what();
  }
  return "";
}

std::string BagWriter::WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                                   const std::string& frame_id) {
  std_msgs::Header h;
  FillHeader(&h, stamp_ns, seq, frame_id);
  try {
    impl_->bag.write(topic, h.stamp, h);
  } catch (const rosbag::BagException& e) {
    return "cannot write to the bag '" + impl_->path + "': " + e.what();
  }
  return "";
}

std::string BagWriter::Close() {
  if (!impl_->open) return "";
  impl_->open = false;
  try {
    impl_->bag.close();
  } catch (const rosbag::BagException& e) {
    return "cannot finish the bag '" + impl_->path + "': " + e.what();
  }
  return "";
}

}  // namespace sfrt::ros::detail
