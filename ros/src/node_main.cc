// sfrt_ros: the scene-flow node (issue #14; docs/ros.md). It subscribes to a stereo pair's
// rectified image topics, runs each (t, t+1) window through the pipeline library (deadline
// policy, newest-wins queues) and publishes the flow, a picture of it and /diagnostics.
//
// The node is the pipeline's (pipeline/node.h: parameters, TopicSource, FlowTopicSink, the
// summary) over NodeIo, the one C++17 file that sees roscpp.
#include <cstring>
#include <iostream>

#include "node_io.h"
#include "sfrt/pipeline/node.h"

namespace sfrt::ros {
namespace {

using detail::NodeIo;

constexpr const char* kHelp = R"(sfrt_ros: scene flow from a stereo camera's ROS topics (ROS 1 node)

usage: sfrt_ros [__name:=NAME] [__ns:=NS] [TOPIC:=REMAPPED ...] [_param:=value ...]

Subscribes (relative to the node's namespace; remap as usual):
  left/image_rect, right/image_rect      sensor_msgs/Image (bgr8, rgb8, bgra8, rgba8, mono8), or
                                         with ~transport compressed, sensor_msgs/CompressedImage
                                         (JPEG, PNG) on left/image_rect/compressed, ...
  left/camera_info, right/camera_info    optional: checked once against the model's camera
Publishes:
  flow        sensor_msgs/Image 32FC3: dX, dY, dZ per pixel of the left image at t, in the
              model's units (metres for the default model); header.stamp = pair t's left stamp,
              header.seq = the window number, frame_id = the left image's (or ~frame_id)
  flow_t1     std_msgs/Header: the same seq, stamped with pair t+1 (the other end of the motion)
  flow_vis    sensor_msgs/Image bgr8 (with ~publish_vis): the picture `sfrt run` writes
  /diagnostics  diagnostic_msgs/DiagnosticArray: latency p50/p99 per stage, stamp to publish,
              drops, deadline misses, ISA and precision, every ~diagnostics_period s
Parameters (private, e.g. _model:=m.sfrt):
  ~model        the .sfrt model file (required unless ~config names one)
  ~config       a deployment profile (firmware-cfg/), checked as `sfrt config check` checks it;
                its model, input size, threads, stage CPUs and priorities, memory settings,
                latency budget and on_miss apply unless a parameter above sets them
  ~threads      inference threads, 0..256 (default 1; 0: one per CPU)
  ~isa          auto|ref|avx2|avx512|avx512amx|neon (default auto: the best this CPU runs)
  ~budget_ms    end-to-end deadline, ms (default: none)
  ~on_miss      count-only|drop-next|smaller-input (default count-only)
  ~fallback_size  HxW, with smaller-input                ~recover_after  windows (default 30)
  ~size         model input size HxW (default: the size a trained model records, else the
                images')
  ~allow_aspect_change  take a ~size of the images' inverse aspect (default false: refused as
                a likely WxH)
  ~transport    raw|compressed (default raw)
  ~slop_ms      most a pair's stamps may differ (default 8)
  ~queue_size   subscriber and ApproximateTime queue (default 5)
  ~frame_interval_ms  the least time between two frames of one camera (default 16, cameras
                up to 60 fps): a pair goes out as soon as no later frame could pair better;
                0 = unknown, each pair waits for the next frames (a frame period more latency)
  ~input_queue  pairs waiting for the pipeline (default 1: the newest wins)
  ~queue_policy newest-wins|block: the pipeline's queues (default newest-wins)
  ~publish_vis  publish flow_vis (default false)        ~frame_id  override the flow's frame_id
  ~camera_info  check camera_info against the model (default true)
  ~diagnostics_period  seconds (default 1)
  ~out          a directory for summary.json when the node stops (default: none); made and
                checked before the first frame
Exit: 0 after SIGINT or a shutdown request, 1 on a failure (a bad model, a failed stage),
2 on a bad parameter or profile.
)";

int Run(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      std::cout << kHelp;
      return 0;
    }
  }
  NodeIo::Init(&argc, argv, "sfrt_ros");
  NodeIo io;
  return pipeline::RunNode(io, {"sfrt_ros"});
}

}  // namespace
}  // namespace sfrt::ros

int main(int argc, char** argv) { return sfrt::ros::Run(argc, argv); }
