// Replaying a recorded bag of stereo images through the pipeline: the robot's own recordings, as
// a FrameSource. The bag's format is an adapter's business (ros/: ROS 1 bags; ros2/: rosbag2's
// MCAP and sqlite3); this is what every format shares, so each replays the same way.
//
// Messages: raw images (bgr8, rgb8, bgra8, rgba8, mono8) and compressed ones (JPEG, PNG) on two
// topics, in the bag's order. Left and right are paired by their header stamps with the camera
// pair's rule: the newest frame of each side waits for its partner; two whose stamps differ by
// at most `pair_tolerance_ms` form a pair; otherwise the older one can never find a partner and is
// dropped, counted as unpaired (summary.json source.unpaired_*; FrameSource::drops()). A window
// is two consecutive pairs of one chain (camera/window_chain.h): a lost frame, a stamp gap or a
// stamp going back starts the next window after it. Outputs are named by the left image's
// message number on its topic.
//
// Errors name the bag and the topic. A message that cannot be converted (another encoding, a
// corrupt JPEG, a size that differs from the first image's) is a bad frame:
// BadFramePolicy::kStop ends the run naming the topic, the message's number and why;
// kSkip records it and the next window starts after it.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "sfrt/camera/stereo_source.h"
#include "sfrt/pipeline/message_io.h"
#include "sfrt/pipeline/pipeline.h"

namespace sfrt::pipeline {

struct BagReplaySpec {
  std::string path;
  std::string left_topic;  // "left/image_rect" means "/left/image_rect"
  std::string right_topic;
  double pair_tolerance_ms = 8;
  camera::BadFramePolicy on_bad_frame = camera::BadFramePolicy::kStop;
};

// What a bag holds on the two topics, read from its index or summary (no message is decoded).
struct BagProbe {
  int64_t left_messages = 0;  // -1 where the bag does not say
  int64_t right_messages = 0;
  std::string left_type;  // as the bag names it: "sensor_msgs/Image", "sensor_msgs/msg/Image", ...
  std::string right_type;
  std::string format;  // "ROS 1 bag", "rosbag2 MCAP", ...
};

// One image message of a bag: the topic it is on and its number there (0, 1, ... in the bag's
// order). The message's data stays valid until the next ImageBag::Next().
struct BagImage {
  int side = 0;  // 0: the left topic, 1: the right topic
  int64_t index = 0;
  ImageMessage message;
};

// A bag of image messages, as an adapter reads it. One reader per bag; not thread-safe.
class ImageBag {
 public:
  virtual ~ImageBag() = default;
  // Opens `path` and checks both topics (absolute names: "/left/image_rect"): each must be in
  // the bag and carry images. Then Next() starts at the bag's first message on either topic.
  // Errors name the file and the topic, and list the topics the bag has when one is missing.
  virtual Result<BagProbe> Open(const std::string& path, const std::string& left_topic,
                                const std::string& right_topic) = 0;
  // The next message on either topic, in the bag's order: true, or false at the end. Errors (a
  // truncated or corrupt bag) name the file and where in it.
  virtual Result<bool> Next(BagImage* out) = 0;
};

// "left/image_rect" -> "/left/image_rect": bags store topics with their leading slash.
std::string AbsoluteTopic(const std::string& topic);

// Opens the bag through `bag` and checks the topics before a run. Errors as described above.
Result<BagProbe> ProbeBag(const BagReplaySpec& spec, ImageBag* bag);

// The source opens the bag in FrameSource::Open(); its kind() is "replay-bag".
std::unique_ptr<FrameSource> MakeBagReplaySource(const BagReplaySpec& spec,
                                                 std::unique_ptr<ImageBag> bag);

}  // namespace sfrt::pipeline
