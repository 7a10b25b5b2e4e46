// Replaying a ROS 1 bag through the pipeline (issue #14): the robot's own recordings, read with
// librosbag (rosbag_storage), as a pipeline::FrameSource.
//
// Messages: sensor_msgs/Image (bgr8, rgb8, bgra8, rgba8, mono8) and sensor_msgs/CompressedImage
// (JPEG, PNG) on the two topics, in the bag's time order. Left and right are paired by their
// header stamps with the camera pair's rule: the newest frame of each side waits for its partner;
// two whose stamps differ by at most `pair_tolerance_ms` form a pair; otherwise the older one
// can never find a partner and is dropped, counted as unpaired (summary.json source.unpaired_*;
// FrameSource::drops()). A window is two consecutive pairs.
//
// Errors name the bag and the topic: a file that is not a bag, a bag that is not indexed (a
// recording cut short: `rosbag reindex` repairs it), a topic that is not in the bag or carries
// another type. A message that cannot be converted (another encoding, a corrupt JPEG) is a bad
// frame: BadFramePolicy::kStop ends the run naming the topic, the message's place and the
// encoding; kSkip records it and the next window starts after it.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "sfrt/camera/stereo_source.h"
#include "sfrt/pipeline/pipeline.h"

namespace sfrt::ros {

struct BagReplaySpec {
  std::string path;
  std::string left_topic;
  std::string right_topic;
  double pair_tolerance_ms = 8;
  camera::BadFramePolicy on_bad_frame = camera::BadFramePolicy::kStop;
};

// What a bag holds on the two topics, read from its index (no message is decoded).
struct BagProbe {
  int64_t left_messages = 0;
  int64_t right_messages = 0;
  std::string left_type;  // "sensor_msgs/Image" or "sensor_msgs/CompressedImage"
  std::string right_type;
};

// Opens the bag and checks the topics before a run. Errors as described above.
Result<BagProbe> ProbeBag(const BagReplaySpec& spec);

// The source opens the bag in FrameSource::Open().
std::unique_ptr<pipeline::FrameSource> MakeBagSource(const BagReplaySpec& spec);

}  // namespace sfrt::ros
