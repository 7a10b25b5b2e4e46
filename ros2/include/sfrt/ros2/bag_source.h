// Replaying a rosbag2 bag (ROS 2) through the pipeline: a folder from `ros2 bag record` (its
// metadata.yaml and .mcap or .db3 files, split bags included), or one .mcap or .db3 file.
// Messages: sensor_msgs/msg/Image and sensor_msgs/msg/CompressedImage, CDR-encoded, on the two
// topics; replayed by the pipeline's bag replay (pipeline/bag_replay.h: pairing by header stamp,
// windows, bad frames, summary), so a rosbag2 bag gives the same flows and counters as a ROS 1
// bag of the same messages. Outputs are named by the left image's message number on its topic,
// counted across the bag's files.
//
// Errors name the file and the topic: a path that is no bag, a storage sfrt does not read, a
// topic the bag lacks (listing those it has) or one of another type, a corrupt or truncated file
// (naming the byte offset and record for MCAP), a message whose CDR does not decode.
#pragma once

#include <memory>
#include <string>

#include "sfrt/pipeline/bag_replay.h"
#include "sfrt/pipeline/pipeline.h"

namespace sfrt::ros2 {

using pipeline::BagProbe;
using pipeline::BagReplaySpec;

// Opens the bag and checks the topics before a run.
Result<BagProbe> ProbeBag(const BagReplaySpec& spec);

// The source opens the bag in FrameSource::Open().
std::unique_ptr<pipeline::FrameSource> MakeBagSource(const BagReplaySpec& spec);

}  // namespace sfrt::ros2
