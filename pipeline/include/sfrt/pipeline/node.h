// A scene-flow node, whatever its middleware: the parameters, the model and the pipeline, the
// stereo topics in (TopicSource), the flow and /diagnostics out (FlowTopicSink, VisTopicSink),
// the camera_info check, the stop on a signal and the summary. sfrt_ros (ROS 1, ros/) and
// sfrt_ros2 (ROS 2 over DDS, ros2/) are this plus a NodeIo for their middleware, so both take
// the same parameters, publish the same messages and report the same figures.
//
// Plain C++17 on purpose (as message_io.h): ROS 1's NodeIo is compiled as C++17.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "sfrt/pipeline/message_io.h"

namespace sfrt::pipeline {

// The node's image subscriptions (names relative to the node's namespace, so remapping works).
struct NodeSubscription {
  std::string left_topic = "left/image_rect";
  std::string right_topic = "right/image_rect";
  // "raw": sensor_msgs Image. "compressed": sensor_msgs CompressedImage on "<topic>/compressed",
  // the topics image_transport's compressed publisher writes (decoded by the node, with OpenCV).
  std::string transport = "raw";
  bool camera_info = true;  // also left/camera_info and right/camera_info (sibling topics)
  double slop_s = 0.008;    // the most a pair's stamps may differ
  int queue_size = 5;       // each subscription's queue, and the pairing's
  // The least time between two frames of one camera: with it a pair is emitted as soon as no
  // later frame could pair better; 0 (unknown): only when the next frames arrive.
  double frame_interval_s = 0.016;
};

// What the node needs of a sensor_msgs CameraInfo.
struct CameraInfoView {
  uint32_t width = 0;
  uint32_t height = 0;
  double p[12] = {};  // the projection matrix P, row-major (fx' = p[0], Tx = p[3] = -fx' * B)
  std::string frame_id;
};

enum class NodeLogLevel { kDebug, kInfo, kWarn, kError, kFatal };

// The middleware, as the node uses it. Publishing is the MessageWriter part (flow, flow_t1,
// flow_vis); Subscribe's callbacks may run on the middleware's threads, one at a time.
class NodeIo : public MessageWriter {
 public:
  using PairCallback = std::function<void(const ImageMessage& left, const ImageMessage& right,
                                          const std::string& left_frame_id)>;
  using InfoCallback = std::function<void(int side, const CameraInfoView& info)>;

  // The node's parameters: false when not set; a value of the wrong type is an error string
  // naming the parameter.
  virtual bool HasParam(const std::string& name) const = 0;
  virtual std::string GetParam(const std::string& name, std::string* value) const = 0;
  virtual std::string GetParam(const std::string& name, double* value) const = 0;
  virtual std::string GetParam(const std::string& name, int* value) const = 0;
  virtual std::string GetParam(const std::string& name, bool* value) const = 0;
  // A parameter as the user sets it, for messages ("~model" in ROS 1, "model" in ROS 2).
  virtual std::string ParamName(const std::string& name) const = 0;
  // A topic name as the graph knows it, after the namespace and remappings ("flow" ->
  // "/robot1/flow").
  virtual std::string Resolve(const std::string& topic) const = 0;

  // Subscribes both image topics and pairs them by stamp; "" or the error.
  virtual std::string Subscribe(const NodeSubscription& options, PairCallback on_pair,
                                InfoCallback on_info) = 0;
  virtual uint64_t received(int side) const = 0;  // image messages received per side
  // Advertises flow (Image), flow_t1 (Header), flow_vis (Image, when with_vis) and
  // /diagnostics.
  virtual std::string Advertise(const std::string& flow, const std::string& t1,
                                const std::string& vis, bool with_vis) = 0;
  virtual void PublishDiagnostics(const std::vector<DiagnosticReport>& reports) = 0;

  virtual void StartSpinner() = 0;    // from here on the callbacks run
  virtual bool Ok() const = 0;        // false once the middleware asks the node to stop
  virtual int64_t NowNs() const = 0;  // the middleware's "now" (its clock for stamps)
  virtual void Shutdown() = 0;
  virtual void Log(NodeLogLevel level, const std::string& text) = 0;
};

// Who the node is, for its messages.
struct NodeIdentity {
  std::string name;  // "sfrt_ros", "sfrt_ros2"
};

// Runs the node until the middleware or a signal (SIGINT, SIGTERM) stops it: reads and checks the
// parameters, loads the model, subscribes, publishes, writes the summary (parameter out). Returns
// the exit code: 0 after a stop, 1 on a failure (a bad model, a failed stage), 2 on a bad
// parameter or profile, each logged through io.
int RunNode(NodeIo& io, const NodeIdentity& identity);

}  // namespace sfrt::pipeline
