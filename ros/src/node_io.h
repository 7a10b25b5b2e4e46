// The sfrt_ros node's ROS 1 side (roscpp, image_transport, message_filters), behind the node's
// interface (pipeline/node.h): node_io.cc is the node's only C++17 file (see message_io.h); the
// node itself (pipeline/node.cc) is C++20 and never sees a ROS type. Not installed.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "sfrt/pipeline/message_io.h"
#include "sfrt/pipeline/node.h"

namespace sfrt::ros::detail {

// The ROS 1 side of the node (pipeline/node.h): roscpp parameters and names, image_transport and
// message_filters' ApproximateTime for the pairs, publishers, rosconsole.
class NodeIo final : public pipeline::NodeIo {
 public:
  // ros::init (takes the remapping and __name arguments out of argc/argv) with roscpp's SIGINT
  // handler, which makes Ok() false. Call once, before anything else.
  static void Init(int* argc, char** argv, const std::string& name);

  NodeIo();  // the node handles (contacts the master: ROS_MASTER_URI must be reachable)
  ~NodeIo() override;

  // The node's private parameters (~name).
  bool HasParam(const std::string& name) const override;
  std::string GetParam(const std::string& name, std::string* value) const override;
  std::string GetParam(const std::string& name, double* value) const override;  // int accepted
  std::string GetParam(const std::string& name, int* value) const override;
  std::string GetParam(const std::string& name, bool* value) const override;
  std::string ParamName(const std::string& name) const override { return "~" + name; }
  // A name as the master knows it ("left/image_rect" -> "/left/image_rect").
  std::string Resolve(const std::string& topic) const override;

  // Subscribes through image_transport and pairs left and right with message_filters'
  // ApproximateTime. The callbacks run on the spinner's thread (StartSpinner), one at a time.
  std::string Subscribe(const pipeline::NodeSubscription& options, PairCallback on_pair,
                        InfoCallback on_info) override;
  uint64_t received(int side) const override;

  std::string Advertise(const std::string& flow, const std::string& t1, const std::string& vis,
                        bool with_vis) override;
  std::string WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                         const std::string& frame_id, const std::string& encoding, uint32_t height,
                         uint32_t width, uint32_t step, const uint8_t* data) override;
  std::string WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                          const std::string& frame_id) override;
  void PublishDiagnostics(const std::vector<pipeline::DiagnosticReport>& reports) override;

  void StartSpinner() override;  // one callback thread
  bool Ok() const override;      // false after SIGINT, ros::shutdown or a lost master
  int64_t NowNs()
      const override;  // ros::Time::now() (the wall clock, or /clock under use_sim_time)
  void Shutdown() override;
  // Through rosconsole: stderr (warnings and errors; info on stdout) and /rosout.
  void Log(pipeline::NodeLogLevel level, const std::string& text) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sfrt::ros::detail
