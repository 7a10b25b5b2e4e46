// Replaying a ROS 1 bag through the pipeline (issue #14): the robot's own recordings, read with
// librosbag (rosbag_storage), replayed by the pipeline's bag replay (pipeline/bag_replay.h: the
// messages it reads, how left and right pair, windows, bad frames, errors). Types:
// sensor_msgs/Image and sensor_msgs/CompressedImage. A bag that is not indexed (a recording cut
// short) is refused: `rosbag reindex` repairs it.
#pragma once

#include <memory>

#include "sfrt/pipeline/bag_replay.h"
#include "sfrt/pipeline/pipeline.h"

namespace sfrt::ros {

using pipeline::BagProbe;
using pipeline::BagReplaySpec;

// Opens the bag and checks the topics before a run.
Result<BagProbe> ProbeBag(const BagReplaySpec& spec);

// The source opens the bag in FrameSource::Open().
std::unique_ptr<pipeline::FrameSource> MakeBagSource(const BagReplaySpec& spec);

}  // namespace sfrt::ros
