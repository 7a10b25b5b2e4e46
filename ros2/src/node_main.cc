// sfrt_ros2: the scene-flow node for ROS 2, over DDS without rclcpp (issue #39; docs/ros.md).
// The node is the pipeline's (pipeline/node.h) over Ros2NodeIo (node_io.h), whose DDS side is
// the Cyclone adapter (dds.h): it joins ROS 2 robots on Cyclone DDS or Fast DDS alike.
#include <csignal>
#include <cstdlib>
#include <iostream>

#include "dds.h"
#include "node_io.h"
#include "ros_args.h"
#include "sfrt/pipeline/node.h"

namespace sfrt::ros2 {
namespace {

constexpr const char* kHelp =
    R"(sfrt_ros2: scene flow from a stereo camera's ROS 2 topics (ROS 2 node, DDS)

usage: sfrt_ros2 [--ros-args [-p NAME:=VALUE]... [-r FROM:=TO]... [--params-file FILE]...]
  e.g. sfrt_ros2 --ros-args -p model:=m.sfrt -p size:=96x128 -r __ns:=/robot1 \
         -r left/image_rect:=/cam/left/image_rect --params-file params.yaml
  params.yaml in ROS 2's form: sfrt_ros2: ros__parameters: {model: m.sfrt, ...} (the key is the
  node's name, its /namespace/name, or /**). ROS_DOMAIN_ID (0..232) is the DDS domain;
  CYCLONEDDS_URI configures Cyclone DDS as for any ROS 2 node on rmw_cyclonedds.

Subscribes (relative to the node's namespace; remap with -r):
  left/image_rect, right/image_rect      sensor_msgs/msg/Image (bgr8, rgb8, bgra8, rgba8, mono8),
                                         or with transport compressed,
                                         sensor_msgs/msg/CompressedImage (JPEG, PNG) on
                                         left/image_rect/compressed, ...; paired by header stamp
  left/camera_info, right/camera_info    optional: checked once against the model's camera
Publishes:
  flow        sensor_msgs/msg/Image 32FC3: dX, dY, dZ per pixel of the left image at t, in the
              model's units (metres for the default model); header.stamp = pair t's left stamp,
              frame_id = the left image's (or frame_id)
  flow_t1     std_msgs/msg/Header stamped with pair t+1 (the other end of the motion)
  flow_vis    sensor_msgs/msg/Image bgr8 (with publish_vis): the picture `sfrt run` writes
  /diagnostics  diagnostic_msgs/msg/DiagnosticArray: latency p50/p99 per stage, drops,
              deadline misses, ISA and precision, every diagnostics_period s
  ros_discovery_info, so `ros2 node list` and `ros2 topic info` show the node
Parameters (-p NAME:=VALUE or a params file):
  model         the .sfrt model file (required unless config names one)
  config        a deployment profile (firmware-cfg/), checked as `sfrt config check` checks it
  threads       inference threads, 0..256 (default 1; 0: one per CPU)
  isa           auto|ref|avx2|avx512|avx512amx|neon (default auto)
  budget_ms     end-to-end deadline, ms (default: none)
  on_miss       count-only|drop-next|smaller-input (default count-only)
  fallback_size HxW, with smaller-input              recover_after  windows (default 30)
  size          model input size HxW (default: the size a trained model records, else the
                images')
  allow_aspect_change  take a size of the images' inverse aspect (default false)
  transport     raw|compressed (default raw)
  slop_ms       most a pair's stamps may differ (default 8)
  queue_size    each side's pairing queue (default 5)
  frame_interval_ms  the least time between two frames of one camera (default 16); 0 = unknown
  input_queue   pairs waiting for the pipeline (default 1: the newest wins)
  queue_policy  newest-wins|block (default newest-wins)
  publish_vis   publish flow_vis (default false)     frame_id  override the flow's frame_id
  camera_info   check camera_info against the model (default true)
  diagnostics_period  seconds (default 1)
  out           a directory for summary.json when the node stops (default: none)
  qos           sensor_data|default (default sensor_data: best effort, keep last 5), for the
                image subscriptions and the flow publications; /diagnostics is reliable
  reliability   best_effort|reliable, overrides qos's      depth  keep last N, overrides qos's
Exit: 0 after SIGINT or SIGTERM, 1 on a failure (a bad model, a failed stage, DDS),
2 on a bad argument, parameter or profile (before any DDS entity exists).
)";

extern "C" void OnSigint(int) { Ros2NodeIo::RequestStop(); }

int Run(int argc, char** argv) {
  Result<RosArgs> args = ParseRosArgs(argc, argv, "sfrt_ros2");
  if (!args.ok()) {
    std::cerr << "sfrt_ros2: " << args.message() << "\n";
    return 2;
  }
  if (args->help) {
    std::cout << kHelp;
    return 0;
  }
  if (!args->program_args.empty()) {
    std::cerr << "sfrt_ros2: '" << args->program_args.front()
              << "' is not an argument it takes; parameters go after --ros-args (--help)\n";
    return 2;
  }
  Result<uint32_t> domain = dds::DomainIdFromEnvironment();
  if (!domain.ok()) {
    std::cerr << "sfrt_ros2: " << domain.message() << "\n";
    return 2;
  }
  std::signal(SIGINT, OnSigint);
  Ros2NodeIo io(std::move(args).value(), *domain);
  if (std::string e = io.ReadQosParams(); !e.empty()) {
    std::cerr << "sfrt_ros2: " << e << "\n";
    return 2;
  }
  const int code = pipeline::RunNode(io, {"sfrt_ros2"});
  io.Shutdown();
  return code;
}

}  // namespace
}  // namespace sfrt::ros2

int main(int argc, char** argv) { return sfrt::ros2::Run(argc, argv); }
