// The sfrt_ros2 node's ROS 2 side (pipeline/node.h's NodeIo) over the DDS adapter (dds.h): the
// parameters and names of the command line (ros_args.h), the image subscriptions paired by stamp
// (stamp_pairer.h), the publishers, the clock and the log. Not installed.
//
// The DDS participant is made at the first Subscribe or Advertise, after the node has read and
// checked every parameter and loaded the model: a bad parameter exits before any DDS entity
// exists. Parameters no one asked for are reported once then (a misspelt "-p modle:=...").
//
// QoS (parameters, ROS 2 only): `qos` sensor_data (default: best effort, keep last 5, which
// matches both kinds of publisher) or default (reliable, keep last 10), for the subscriptions
// and the publications; `reliability` (best_effort|reliable) and `depth` override its parts.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "dds.h"
#include "ros_args.h"
#include "sfrt/pipeline/node.h"
#include "stamp_pairer.h"

namespace sfrt::ros2 {

class Ros2NodeIo final : public pipeline::NodeIo {
 public:
  Ros2NodeIo(RosArgs args, uint32_t domain_id);
  ~Ros2NodeIo() override;

  // Reads and checks the parameters only this side takes (qos, reliability, depth): "" or the
  // error. Before RunNode, so a bad one is a usage error like any other parameter's.
  std::string ReadQosParams();

  bool HasParam(const std::string& name) const override;
  std::string GetParam(const std::string& name, std::string* value) const override;
  std::string GetParam(const std::string& name, double* value) const override;
  std::string GetParam(const std::string& name, int* value) const override;
  std::string GetParam(const std::string& name, bool* value) const override;
  std::string ParamName(const std::string& name) const override { return name; }
  std::string Resolve(const std::string& topic) const override;

  std::string Subscribe(const pipeline::NodeSubscription& options, PairCallback on_pair,
                        InfoCallback on_info) override;
  uint64_t received(int side) const override { return received_[side].load(); }
  std::string Advertise(const std::string& flow, const std::string& t1, const std::string& vis,
                        bool with_vis) override;
  std::string WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                         const std::string& frame_id, const std::string& encoding, uint32_t height,
                         uint32_t width, uint32_t step, const uint8_t* data) override;
  std::string WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                          const std::string& frame_id) override;
  void PublishDiagnostics(const std::vector<pipeline::DiagnosticReport>& reports) override;

  void StartSpinner() override { spinning_ = true; }
  bool Ok() const override;
  int64_t NowNs() const override;
  void Shutdown() override;
  void Log(pipeline::NodeLogLevel level, const std::string& text) override;

  // SIGINT's handler (the program's) calls this: Ok() turns false.
  static void RequestStop();

 private:
  std::string EnsureParticipant();
  void ReportUnusedParams();
  void OnImage(int side, const pipeline::ImageMessage& image, const std::string& frame_id);
  int PublisherOf(const std::string& topic) const;

  RosArgs args_;
  uint32_t domain_id_;
  mutable std::set<std::string> asked_;  // parameters the node read
  std::unique_ptr<dds::Participant> participant_;
  dds::Qos qos_;
  // The subscriptions may call back on different threads; held while a callback feeds the node,
  // so Shutdown() (which clears spinning_ under it) knows none is still running.
  std::mutex pair_mutex_;
  std::optional<StampPairer> pairer_;
  PairCallback on_pair_;
  std::atomic<uint64_t> received_[2] = {0, 0};
  std::atomic<bool> spinning_{false};
  std::atomic<bool> shut_down_{false};
  std::string flow_topic_, t1_topic_, vis_topic_;
  int flow_ = -1, t1_ = -1, vis_ = -1, diagnostics_ = -1;
};

}  // namespace sfrt::ros2
