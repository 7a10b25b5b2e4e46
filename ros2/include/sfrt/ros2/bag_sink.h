// `sfrt run --record-bag` for ROS 2: the flow as a rosbag2 bag that `ros2 bag info`, `ros2 bag
// play` and Foxglove open. The same messages as the ROS 1 bag (pipeline/flow_messages.h), in
// ROS 2's types:
//   flow      sensor_msgs/msg/Image, encoding 32FC3: dX, dY, dZ per pixel of the left image at
//             t, in the model's output units, little-endian floats, row-major;
//             header.stamp = the stamp of pair t, header.frame_id = FlowRecordingOptions::frame_id
//   flow_t1   std_msgs/msg/Header: the stamp of pair t+1, the other end of the motion
//   flow_vis  (FlowRecordingOptions::vis) sensor_msgs/msg/Image, bgr8: the picture of the window
//   left_topic, right_topic  (RecordInputs) sensor_msgs/msg/Image, bgr8: the stereo pairs read
// Each message is CDR, in MCAP (profile "ros2", schema encoding "ros2msg", message encoding
// "cdr"), chunked and compressed with zstd, with the summary and indexes; its log and publish
// times are its header stamp. Stamps as the ROS 1 bag's: the source's header stamps when it has
// them, else the capture time on the wall clock.
//
// Where it goes (the path as given):
//   <path>.mcap   one MCAP file, as Foxglove and the mcap CLI write them;
//   anything else a bag folder as `ros2 bag record` writes it: <path>/<name>_0.mcap and
//                 <path>/metadata.yaml (name: the folder's). The folder must not exist yet
//                 (ros2 bag record refuses too).
// Atomic like every output: written under a temporary name beside the path ("<path>.tmp.mcap",
// or the folder "<path>.partial-<pid>") and renamed onto it at Stop() once complete; a bag that
// could not be written is removed and nothing is replaced. Retract() does nothing.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "sfrt/pipeline/flow_messages.h"
#include "sfrt/pipeline/output_sinks.h"
#include "sfrt/pipeline/sink.h"

namespace sfrt::ros2 {

namespace detail {
class McapBagWriter;
}

// Checks that a bag can be recorded at `path` (before a run): a .mcap path must be a regular
// file or a new one (after following links); a folder path must not exist and its parent must.
// Errors name the path.
Status CheckBag2Path(const std::string& path);

class FlowBag2Sink final : public pipeline::FlowSink, public pipeline::InputRecorder {
 public:
  explicit FlowBag2Sink(pipeline::FlowRecordingOptions options);
  ~FlowBag2Sink() override;
  std::string name() const override { return "rosbag2"; }
  Status Start() override;
  Status Write(const pipeline::FlowFrame& frame) override;
  Status Stop() override;
  // The input pairs, when the run's source is a recording source (pipeline::MakeRecordingSource)
  // handing them here: between Start() and Stop().
  Status RecordInputs(const pipeline::WindowItem& item) override;
  int64_t messages() const { return recorder_.windows(); }
  int64_t input_pairs() const { return recorder_.input_pairs(); }

 private:
  void Discard();  // removes what was written under the temporary name

  pipeline::FlowRecorder recorder_;
  std::unique_ptr<detail::McapBagWriter> writer_;
  bool folder_ = false;
  std::string final_;  // the path after following symbolic links (a file) or as given (a folder)
  std::string tmp_;    // the temporary file or folder
  std::string mcap_;   // the MCAP file being written
};

}  // namespace sfrt::ros2
