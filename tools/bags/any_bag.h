// Which reader replays a bag path: rosbag2 (a folder, its metadata.yaml, a .mcap or a .db3: ros2/)
// or a ROS 1 .bag (ros/, when this build has it). `sfrt run --replay-bag` and the Python package's
// sfrt.replay(bag=...) choose through it, so both read a path the same way. (Here, above both
// adapters: neither may use the other.)
#pragma once

#include <memory>
#include <string>

#include "sfrt/pipeline/bag_replay.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/status.h"

namespace sfrt::bags {

struct BagFormat {
  const char* name = "";  // "rosbag2" or "ROS 1"
  Result<pipeline::BagProbe> (*probe)(const pipeline::BagReplaySpec&) = nullptr;
  std::unique_ptr<pipeline::FrameSource> (*make)(const pipeline::BagReplaySpec&) = nullptr;
};

// The reader of `path` (not opened yet); an error when the path is a ROS 1 bag and this build
// has no ROS 1 reader, saying what to install.
Result<BagFormat> BagFormatOf(const std::string& path);

}  // namespace sfrt::bags
