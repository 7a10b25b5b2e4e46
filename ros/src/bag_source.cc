#include "sfrt/ros/bag_source.h"

#include <utility>

#include "bag_reader.h"

namespace sfrt::ros {
namespace {

// A ROS 1 bag as the pipeline's bag replay reads it (pipeline/bag_replay.h), through librosbag.
class Ros1Bag final : public pipeline::ImageBag {
 public:
  Result<pipeline::BagProbe> Open(const std::string& path, const std::string& left_topic,
                                  const std::string& right_topic) override {
    detail::BagTopics topics;
    if (std::string e = reader_.Open(path, left_topic, right_topic, &topics); !e.empty()) {
      return Status::Error(e);
    }
    pipeline::BagProbe probe;
    probe.left_type = topics.left_type;
    probe.right_type = topics.right_type;
    probe.left_messages = topics.left_messages;
    probe.right_messages = topics.right_messages;
    probe.format = "ROS 1 bag";
    return probe;
  }

  Result<bool> Next(pipeline::BagImage* out) override {
    std::string error;
    if (!reader_.Next(&message_, &error)) {
      if (!error.empty()) return Status::Error(error);
      return false;
    }
    out->side = message_.side;
    out->index = message_.index;
    out->message = message_.view();
    return true;
  }

 private:
  detail::BagReader reader_;
  detail::BagImage message_;  // the last message read (its buffer reused)
};

}  // namespace

Result<BagProbe> ProbeBag(const BagReplaySpec& spec) {
  Ros1Bag bag;
  return pipeline::ProbeBag(spec, &bag);
}

std::unique_ptr<pipeline::FrameSource> MakeBagSource(const BagReplaySpec& spec) {
  return pipeline::MakeBagReplaySource(spec, std::make_unique<Ros1Bag>());
}

}  // namespace sfrt::ros
