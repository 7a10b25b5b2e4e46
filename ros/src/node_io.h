// The sfrt_ros node's ROS 1 side (roscpp, image_transport, message_filters), behind a plain
// interface: node_io.cc is the node's only C++17 file (see message_io.h); the node itself
// (node_main.cc, topic_source.cc) is C++20 and never sees a ROS type. A ROS 2 port replaces this
// file and keeps the rest (docs/ros.md). Not installed.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "sfrt/pipeline/message_io.h"

namespace sfrt::ros::detail {

// The node's subscriptions (names relative to the node's namespace, so remapping works as usual).
struct SubscribeOptions {
  std::string left_topic = "left/image_rect";
  std::string right_topic = "right/image_rect";
  // "raw": sensor_msgs/Image through image_transport's raw transport. "compressed":
  // sensor_msgs/CompressedImage on "<topic>/compressed", the topics image_transport's compressed
  // publisher writes (Debian packages no compressed subscriber plugin, so the node decodes them
  // itself, with OpenCV).
  std::string transport = "raw";
  bool camera_info = true;  // also left/camera_info and right/camera_info (sibling topics)
  double slop_s = 0.008;    // ApproximateTime: the most a pair's stamps may differ
  int queue_size = 5;       // ApproximateTime's and each subscriber's queue
  // The least time between two frames of one camera (ApproximateTime's inter-message lower
  // bound): with it a pair is emitted as soon as no later frame could pair better; 0 (unknown):
  // only when the next frames arrive, a frame period later.
  double frame_interval_s = 0.016;
};

// What the node needs of a sensor_msgs/CameraInfo.
struct CameraInfoView {
  uint32_t width = 0;
  uint32_t height = 0;
  double p[12] = {};  // the projection matrix P, row-major (fx' = p[0], Tx = p[3] = -fx' * B)
  std::string frame_id;
};

enum class NodeLogLevel { kDebug, kInfo, kWarn, kError, kFatal };

class NodeIo final : public pipeline::MessageWriter {
 public:
  // ros::init (takes the remapping and __name arguments out of argc/argv) with roscpp's SIGINT
  // handler, which makes Ok() false. Call once, before anything else.
  static void Init(int* argc, char** argv, const std::string& name);

  NodeIo();  // the node handles (contacts the master: ROS_MASTER_URI must be reachable)
  ~NodeIo() override;

  // The node's private parameters (~name). False when not set; a wrong type is an error string.
  bool HasParam(const std::string& name) const;
  std::string GetParam(const std::string& name, std::string* value) const;
  std::string GetParam(const std::string& name, double* value) const;  // int accepted
  std::string GetParam(const std::string& name, int* value) const;
  std::string GetParam(const std::string& name, bool* value) const;
  // A name as the master knows it ("left/image_rect" -> "/left/image_rect").
  std::string Resolve(const std::string& topic) const;
  // A private parameter's full name ("model" -> "/sfrt_ros/model"), for messages.
  std::string ResolvePrivate(const std::string& name) const;

  using PairCallback =
      std::function<void(const pipeline::ImageMessage& left, const pipeline::ImageMessage& right,
                         const std::string& left_frame_id)>;
  using InfoCallback = std::function<void(int side, const CameraInfoView& info)>;
  // Subscribes and pairs left and right with message_filters' ApproximateTime. The callbacks run
  // on the spinner's thread (StartSpinner), one at a time. Returns "" or the error.
  std::string Subscribe(const SubscribeOptions& options, PairCallback on_pair,
                        InfoCallback on_info);
  // Messages received on each image topic (paired or not), for the diagnostics.
  uint64_t received(int side) const;

  // Advertises the outputs: `flow` (Image), `flow_t1` (Header), `flow_vis` (Image, when vis)
  // in the node's namespace, and /diagnostics.
  void Advertise(const std::string& flow, const std::string& t1, const std::string& vis,
                 bool with_vis);
  std::string WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                         const std::string& frame_id, const std::string& encoding, uint32_t height,
                         uint32_t width, uint32_t step, const uint8_t* data) override;
  std::string WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                          const std::string& frame_id) override;
  void PublishDiagnostics(const std::vector<pipeline::DiagnosticReport>& reports);

  void StartSpinner();     // one callback thread
  static bool Ok();        // false after SIGINT, ros::shutdown or a lost master
  static int64_t NowNs();  // ros::Time::now() (the wall clock, or /clock under use_sim_time)
  void Shutdown();

  // Through rosconsole: stderr (warnings and errors; info on stdout) and /rosout.
  static void Log(NodeLogLevel level, const std::string& text);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sfrt::ros::detail
