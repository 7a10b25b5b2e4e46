// sfrt as a ROS 2 participant on DDS, without rclcpp (issue #39): the adapter over Cyclone DDS
// 0.10 (Debian bookworm's cyclonedds-dev) and the only sfrt code that includes Cyclone's headers.
// Callers see sfrt's message types (messages.h), never a DDS type.
//
// What a ROS 2 peer sees is what rmw_cyclonedds (Humble, Jazzy) does on the wire:
//   * Topics: ROS topic /a/b is DDS topic rt/a/b (ros2/design, "Topic and Service name mapping
//     to DDS"); relative and private (~) names resolve against the node's namespace and name.
//   * Types: sensor_msgs/msg/Image is DDS type sensor_msgs::msg::dds_::Image_, final, keyless,
//     plain CDR (XCDR1) with the little-endian encapsulation header 00 01 00 00. Like
//     rmw_cyclonedds, no XTypes type information is sent (the topic descriptors are generated with
//     idlc -t from ros2/idl), so peers match by type name.
//   * QoS: keep last `depth`, reliable or best effort, volatile or transient local, automatic
//     liveliness, no autodispose, data representation XCDR1 only (a peer offering XCDR2 does
//     not match). Qos::SensorData() and Qos::Default() are rmw's profiles of those names. One
//     local difference: a reliable Publish waits at most 100 ms for slow subscribers'
//     acknowledgements (rmw_cyclonedds: forever), then fails and the message is dropped.
//   * Domain: the DDS domain id is ROS_DOMAIN_ID (DomainIdFromEnvironment).
//   * Graph: AnnounceNode() writes rmw_dds_common/msg/ParticipantEntitiesInfo on the DDS topic
//     ros_discovery_info (reliable, keep last 1, transient local), the node with the gids (DDS
//     GUIDs) of its readers and writers: how `ros2 node list` and `ros2 topic info` learn about
//     it. The participant's USER_DATA is "enclave=/;", as rmw_cyclonedds writes it.
//
// Serialisation: messages.h's Encode and Decode are the only codec. Publish encodes into the
// publisher's buffer and hands the bytes to Cyclone (dds_writecdr), which checks them against
// the topic's type and copies them into its own sample; a subscription takes the serialised
// samples (dds_takecdr) and decodes them with messages.h. The bytes on the wire are the ones
// messages_test.cc checks against an independent codec.
//
// Threads: Publish, Advertise*, Subscribe*, AnnounceNode, OnProblem and the Matched* queries
// may be called from any thread, concurrently. Subscription callbacks and problem reports run
// on Cyclone's threads: for a remote publisher its receive thread, for a publisher in the same
// process and domain synchronously inside that publisher's Publish call. Callbacks of one
// subscription never run concurrently with each other; callbacks of different subscriptions may.
// A callback must return quickly (it holds up delivery on its topic), may call Publish (but not
// on a topic it subscribes to itself in the same process: delivery would re-enter it), and must
// not destroy the Participant. Destroy the Participant when no other thread uses it. An exception
// that leaves a callback is caught and reported through OnProblem ("callback failed"), never passed
// into Cyclone.
//
// Allocation: creating entities allocates. Publish allocates nothing in sfrt's code once its
// publisher has sent a message of the same (or larger) size: the encoding buffer is reused.
// Cyclone itself allocates a serialised sample per message larger than 256 bytes
// (ddsi_serdata_default's pool threshold) with malloc. On the receiving side an ImageView
// points into Cyclone's sample (no copy, no allocation by sfrt); CompressedImage and CameraInfo
// are decoded into one object per subscription, reused (no allocation once the largest message
// has been seen).
//
// Errors: every failure is a Status whose one-line message names the ROS topic, the DDS topic
// and Cyclone's return code text where there is one. Incompatible QoS (requested by one of our
// subscriptions or offered by one of our publishers), undecodable samples and failed callbacks
// are reported to the OnProblem callback once per topic and kind, as text naming the topic and
// the reliability of both sides (Cyclone names only the first incompatible policy; when it is
// reliability, the peer's side follows: a reliable reader is incompatible only with a best-effort
// writer).
//
// Lifetime: ~Participant deletes the DDS participant and with it every topic, reader and
// writer; Cyclone waits for callbacks in progress to return first. Peers see the node leave.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "messages.h"
#include "sfrt/status.h"

namespace sfrt::ros2::dds {

// A ROS 2 QoS profile, the part of it sfrt uses.
struct Qos {
  enum class Reliability { kBestEffort, kReliable };
  Reliability reliability = Reliability::kReliable;
  uint32_t depth = 10;           // history: keep last `depth`, 1 or more
  bool transient_local = false;  // durability; false is volatile

  // rmw_qos_profile_sensor_data: best effort, keep last 5, volatile.
  static Qos SensorData();
  // rmw_qos_profile_default: reliable, keep last 10, volatile.
  static Qos Default();
};

// "reliable, keep last 10, volatile": for messages.
std::string Describe(const Qos& qos);

// The DDS topic of a fully qualified ROS topic name: "/a/b" -> "rt/a/b". A name without the
// leading '/' is taken from the root ("a/b" -> "rt/a/b"). Does not validate; see
// ResolveTopicName.
std::string RosTopicToDds(std::string_view ros_topic);

// The fully qualified name of a ROS topic name used by node `node_name` in `node_namespace`
// ("/" or "/a/b"): "/x" stays, "x" becomes "<ns>/x", "~/x" becomes "<ns>/<node>/x", a
// "rostopic://" prefix is dropped. Refused, with a message naming the name and the rule: empty
// names, characters other than alphanumerics, '_' and '/', a token starting with a digit, "//",
// a trailing '/', "~" not followed by '/', substitutions ({}), and results longer than rmw's 247
// characters.
Result<std::string> ResolveTopicName(std::string_view name, std::string_view node_namespace,
                                     std::string_view node_name);

// A ROS_DOMAIN_ID value: "" is 0 (as rcl treats an empty variable); otherwise decimal digits
// only, 0 to 232 (the largest domain whose ports fit DDSI's default port mapping). The error
// names the value.
Result<uint32_t> ParseDomainId(std::string_view text);
// ParseDomainId of the environment variable ROS_DOMAIN_ID; 0 when it is not set.
Result<uint32_t> DomainIdFromEnvironment();

// Which rmw_dds_common/msg/Gid the graph uses: its DDS type name is the same in every
// distribution, its size is not, so a node announces itself in the layout of the distribution
// it joins.
enum class GidLayout {
  k16Bytes,  // Iron, Jazzy and later: char[16], the DDS GUID
  k24Bytes,  // Humble: char[24], the DDS GUID then 8 zero bytes
};

// A DDS GUID (prefix and entity id) as rmw_cyclonedds copies it into a gid.
using Guid = std::array<uint8_t, 16>;

// One node of a ParticipantEntitiesInfo.
struct NodeEntities {
  std::string node_namespace;
  std::string node_name;
  std::vector<Guid> readers;
  std::vector<Guid> writers;
};

// Encodes rmw_dds_common/msg/ParticipantEntitiesInfo {Gid gid; NodeEntitiesInfo[] nodes} in
// plain CDR (with the encapsulation header), each Gid in `layout`. Replaces *out's contents.
void EncodeParticipantEntitiesInfo(const Guid& participant, const std::vector<NodeEntities>& nodes,
                                   GidLayout layout, std::vector<uint8_t>* out);

struct ParticipantOptions {
  GidLayout gid_layout = GidLayout::k16Bytes;
};

// One ROS 2 node: a DDS participant with its readers and writers.
class Participant {
 public:
  // Joins DDS domain `domain_id` (0..232) as node `node_name` ([A-Za-z_][A-Za-z0-9_]*) in
  // `node_namespace` ("/" or an absolute name). Cyclone reads its configuration from
  // CYCLONEDDS_URI as usual. Errors name the node and Cyclone's return code.
  static Result<std::unique_ptr<Participant>> Create(uint32_t domain_id,
                                                     const std::string& node_name,
                                                     const std::string& node_namespace,
                                                     const ParticipantOptions& options = {});
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  // Subscriptions. `ros_topic` is resolved with ResolveTopicName. The callback gets each
  // message, valid only during the call, on a Cyclone thread (see the header comment).
  Status SubscribeImage(const std::string& ros_topic, const Qos& qos,
                        std::function<void(const msg::ImageView&)> callback);
  Status SubscribeCompressedImage(const std::string& ros_topic, const Qos& qos,
                                  std::function<void(const msg::CompressedImage&)> callback);
  Status SubscribeCameraInfo(const std::string& ros_topic, const Qos& qos,
                             std::function<void(const msg::CameraInfo&)> callback);

  // Publishers; each returns the handle that Publish takes.
  Result<int> AdvertiseImage(const std::string& ros_topic, const Qos& qos);
  Result<int> AdvertiseHeader(const std::string& ros_topic, const Qos& qos);
  Result<int> AdvertiseDiagnosticArray(const std::string& ros_topic, const Qos& qos);

  // Sends one message; the handle must come from the Advertise of that message type. With no
  // matched subscription the message is dropped by Cyclone (or, transient local, kept for late
  // joiners).
  Status Publish(int publisher, const msg::ImageView& message);
  Status Publish(int publisher, const msg::Header& message);
  Status Publish(int publisher, const msg::DiagnosticArray& message);

  // Where problems found on Cyclone's threads go (see "Errors"); until set, they are written to
  // stderr. Each (topic, kind) is reported once per Participant.
  void OnProblem(std::function<void(const std::string&)> callback);

  // Publishes ros_discovery_info for this node and its current readers and writers, replacing
  // the last announcement (transient local: late-joining tools get it too). Call after creating
  // the subscriptions and publishers, and again whenever they change.
  Status AnnounceNode();

  // Matched peers (remote and local) of a publisher, or of the subscriptions on `ros_topic`
  // (summed); -1 for an unknown handle or topic.
  int MatchedSubscribers(int publisher) const;
  int MatchedPublishers(const std::string& ros_topic) const;

  // The participant's DDS GUID, the gid ros_discovery_info carries.
  Guid ParticipantGuid() const;

  class Impl;

 private:
  explicit Participant(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sfrt::ros2::dds
