// `sfrt run --record-bag`: the flow as a ROS 1 bag, so results open in the tools robotics teams
// already use (rqt_bag, rosbag play, their own nodes).
//
// Topics (names from pipeline::FlowRecordingOptions):
//   flow      sensor_msgs/Image, encoding 32FC3: dX, dY, dZ per pixel of the left image at t, in
//             the model's output units (metres for the default model), little-endian floats,
//             row-major; header.stamp = the stamp of pair t (the frame the flow is defined on),
//             header.seq = the window number, header.frame_id = FlowRecordingOptions::frame_id.
//   flow_t1   std_msgs/Header with the same seq and frame_id and the stamp of pair t+1, the other
//             end of the motion.
//   flow_vis  (FlowRecordingOptions::vis) sensor_msgs/Image, bgr8: the picture `sfrt run` writes as
//   PNG.
//   left_topic, right_topic  (RecordInputs) sensor_msgs/Image, bgr8: the stereo pairs read,
//             header.seq = the frame number.
// Stamps: a bag's own header stamps (FrameMeta::stamp_ns) when the source has them; otherwise the
// capture time (CLOCK_MONOTONIC) moved to the wall clock (CLOCK_REALTIME) by the offset between
// the two clocks at Start(). The bag's record time of each message is its header stamp.
//
// Atomic like every output: the bag is written to "<path>.tmp.bag" and renamed onto the path at
// Stop() once closed; a bag that could not be written is removed and nothing is replaced. A
// message cannot be taken out of a bag, so Retract() does nothing (as for the video).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "sfrt/pipeline/flow_messages.h"
#include "sfrt/pipeline/output_sinks.h"
#include "sfrt/pipeline/sink.h"

namespace sfrt::ros {

// Where a bag can be recorded: the path a regular file (or a new one) would be written at after
// following links (a bag is finished by seeking back to its header, so a device or FIFO is
// refused, naming the path). FlowBagSink::Start() checks it; a tool checks it before a run.
Result<std::string> ResolveBagPath(const std::string& path);

namespace detail {
class BagWriter;
}

class FlowBagSink final : public pipeline::FlowSink, public pipeline::InputRecorder {
 public:
  explicit FlowBagSink(pipeline::FlowRecordingOptions options);
  ~FlowBagSink() override;
  std::string name() const override { return "bag"; }
  Status Start() override;
  Status Write(const pipeline::FlowFrame& frame) override;
  Status Stop() override;
  // The input pairs, when the run's source is a recording source (pipeline::MakeRecordingSource)
  // handing them here: between Start() and Stop().
  Status RecordInputs(const pipeline::WindowItem& item) override;
  int64_t messages() const { return recorder_.windows(); }
  int64_t input_pairs() const { return recorder_.input_pairs(); }

 private:
  pipeline::FlowRecorder recorder_;
  std::unique_ptr<detail::BagWriter> writer_;
  std::string final_;  // the path after following symbolic links
  std::string tmp_;
};

}  // namespace sfrt::ros
