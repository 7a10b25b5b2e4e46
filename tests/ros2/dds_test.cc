// sfrt's DDS adapter (ros2/src/dds.h) against Cyclone DDS used directly: readers and writers of
// the idlc C types of ros2/idl in this process (Cyclone serialises those itself, from the topic
// descriptors, independently of sfrt's CDR), and the independent peer program
// tests/ros2/cyclone_peer in another process over the loopback network (its path from the
// environment variable SFRT_CYCLONE_PEER, else the build's SFRT_CYCLONE_PEER_PATH; without
// either those tests are skipped). Each test runs in a DDS domain derived from the process id, on a
// loopback-only Cyclone configuration without multicast.
//
// Its own program: it replaces the global operator new to count sfrt's allocations, and (without
// AddressSanitizer) glibc's malloc entry points to measure Cyclone's.
#include "dds.h"

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "diagnostic_msgs/msg/DiagnosticArray.h"
#include "rmw_dds_common/msg/ParticipantEntitiesInfo.h"
#include "sensor_msgs/msg/CameraInfo.h"
#include "sensor_msgs/msg/CompressedImage.h"
#include "sensor_msgs/msg/Image.h"
#include "std_msgs/msg/Header.h"

namespace {

std::atomic<size_t> g_news{0};
std::atomic<size_t> g_mallocs{0};

void* CountedNew(std::size_t size) {
  ++g_news;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}

}  // namespace

void* operator new(std::size_t size) { return CountedNew(size); }
void* operator new[](std::size_t size) { return CountedNew(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

// Counting malloc, calloc and realloc: glibc exports its implementations as __libc_*. Not under
// AddressSanitizer, which owns these symbols.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kMallocCounted = false;
#else
constexpr bool kMallocCounted = true;
extern "C" {
void* __libc_malloc(size_t size);
void* __libc_calloc(size_t count, size_t size);
void* __libc_realloc(void* p, size_t size);
void* malloc(size_t size) {
  ++g_mallocs;
  return __libc_malloc(size);
}
void* calloc(size_t count, size_t size) {
  ++g_mallocs;
  return __libc_calloc(count, size);
}
void* realloc(void* p, size_t size) {
  ++g_mallocs;
  return __libc_realloc(p, size);
}
}
#endif

namespace sfrt::ros2::dds {
namespace {

using std::chrono::milliseconds;

// Loopback only, unicast discovery through the participant indices on 127.0.0.1: tests and
// peers of this machine find each other and nothing else.
constexpr const char* kLoopbackConfig =
    "<CycloneDDS><Domain Id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/>"
    "</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery>"
    "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>50"
    "</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery>"
    "</Domain></CycloneDDS>";

// Polls `done` every few milliseconds until it holds or `timeout` passes.
bool WaitFor(const std::function<bool()>& done, milliseconds timeout = milliseconds(5000)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(milliseconds(5));
  }
  return true;
}

// Test messages.

msg::Image MakeImage(uint32_t height, uint32_t width, uint8_t seed) {
  msg::Image image;
  image.header.stamp = {1700000000 + seed, 123456789u + seed};
  image.header.frame_id = "left_camera";
  image.height = height;
  image.width = width;
  image.encoding = "bgr8";
  image.step = width * 3;
  image.data.resize(size_t{height} * width * 3);
  for (size_t i = 0; i < image.data.size(); ++i) image.data[i] = static_cast<uint8_t>(i * 7 + seed);
  return image;
}

msg::ImageView ViewOf(const msg::Image& image) {
  return {{image.header.stamp, image.header.frame_id},
          image.height,
          image.width,
          image.encoding,
          image.is_bigendian,
          image.step,
          image.data};
}

msg::Image CopyOf(const msg::ImageView& view) {
  return {{view.header.stamp, std::string(view.header.frame_id)},
          view.height,
          view.width,
          std::string(view.encoding),
          view.is_bigendian,
          view.step,
          std::vector<uint8_t>(view.data.begin(), view.data.end())};
}

msg::DiagnosticArray MakeDiagnostics() {
  msg::DiagnosticArray array;
  array.header = {{5, 6}, ""};
  msg::DiagnosticStatus status;
  status.level = msg::DiagnosticStatus::kWarn;
  status.name = "sfrt: scene flow";
  status.message = "deadline missed";
  status.hardware_id = "sceneednet";
  status.values = {{"fps", "29.9"}, {"p99_ms", "18.2"}};
  array.status = {status, msg::DiagnosticStatus{}};
  return array;
}

msg::CompressedImage MakeCompressedImage() {
  msg::CompressedImage image;
  image.header = {{3, 4}, "left_camera"};
  image.format = "jpeg";
  image.data = {0xff, 0xd8, 0xff, 0xd9};
  return image;
}

msg::CameraInfo MakeCameraInfo() {
  msg::CameraInfo info;
  info.header = {{7, 8}, "right_camera"};
  info.height = 480;
  info.width = 640;
  info.distortion_model = "plumb_bob";
  info.d = {0.1, -0.2, 0.001, 0.002, 0.0};
  for (size_t i = 0; i < 12; ++i) info.p[i] = 0.5 * static_cast<double>(i);
  for (size_t i = 0; i < 9; ++i) info.k[i] = static_cast<double>(i) - 4;
  info.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  info.binning_x = 2;
  info.roi = {1, 2, 3, 4, true};
  return info;
}

// Between msg:: and the idlc C types (which point into the msg:: object: no ownership).

std_msgs_msg_dds__Header_ ToC(const msg::Header& header) {
  return {{header.stamp.sec, header.stamp.nanosec}, const_cast<char*>(header.frame_id.c_str())};
}

msg::Header FromC(const std_msgs_msg_dds__Header_& header) {
  return {{header.stamp_.sec_, header.stamp_.nanosec_}, header.frame_id_};
}

template <typename Sequence, typename T>
Sequence SequenceOf(const std::vector<T>& values) {
  return {static_cast<uint32_t>(values.size()), static_cast<uint32_t>(values.size()),
          const_cast<T*>(values.data()), false};
}

sensor_msgs_msg_dds__Image_ ToC(const msg::Image& image) {
  return {ToC(image.header),
          image.height,
          image.width,
          const_cast<char*>(image.encoding.c_str()),
          image.is_bigendian,
          image.step,
          SequenceOf<dds_sequence_octet>(image.data)};
}

msg::Image FromC(const sensor_msgs_msg_dds__Image_& image) {
  return {FromC(image.header_),
          image.height_,
          image.width_,
          image.encoding_,
          image.is_bigendian_,
          image.step_,
          std::vector<uint8_t>(image.data_._buffer, image.data_._buffer + image.data_._length)};
}

sensor_msgs_msg_dds__CompressedImage_ ToC(const msg::CompressedImage& image) {
  return {ToC(image.header), const_cast<char*>(image.format.c_str()),
          SequenceOf<dds_sequence_octet>(image.data)};
}

sensor_msgs_msg_dds__CameraInfo_ ToC(const msg::CameraInfo& info) {
  sensor_msgs_msg_dds__CameraInfo_ c{};
  c.header_ = ToC(info.header);
  c.height_ = info.height;
  c.width_ = info.width;
  c.distortion_model_ = const_cast<char*>(info.distortion_model.c_str());
  c.d_ = SequenceOf<dds_sequence_double>(info.d);
  std::copy(info.k.begin(), info.k.end(), c.k_);
  std::copy(info.r.begin(), info.r.end(), c.r_);
  std::copy(info.p.begin(), info.p.end(), c.p_);
  c.binning_x_ = info.binning_x;
  c.binning_y_ = info.binning_y;
  c.roi_ = {info.roi.x_offset, info.roi.y_offset, info.roi.height, info.roi.width,
            info.roi.do_rectify};
  return c;
}

Guid GuidOf(const dds_guid_t& guid) {
  Guid out;
  std::memcpy(out.data(), guid.v, out.size());
  return out;
}

Guid GuidOf(const rmw_dds_common_msg_dds__Gid_& gid) {
  Guid out;
  std::memcpy(out.data(), gid.data_, out.size());
  return out;
}

// Cyclone used directly, as any other DDS application in the domain.
class CycloneSide {
 public:
  explicit CycloneSide(uint32_t domain)
      : participant_(dds_create_participant(domain, nullptr, nullptr)) {
    EXPECT_GT(participant_, 0) << dds_strretcode(participant_);
  }
  ~CycloneSide() { dds_delete(participant_); }
  CycloneSide(const CycloneSide&) = delete;
  CycloneSide& operator=(const CycloneSide&) = delete;

  dds_entity_t Reader(const dds_topic_descriptor_t* type, const std::string& topic, bool reliable,
                      int32_t depth = 10, bool transient_local = false) {
    dds_qos_t* qos = NewQos(reliable, depth, transient_local);
    const dds_entity_t reader = dds_create_reader(participant_, Topic(type, topic), qos, nullptr);
    dds_delete_qos(qos);
    EXPECT_GT(reader, 0) << dds_strretcode(reader);
    return reader;
  }

  dds_entity_t Writer(const dds_topic_descriptor_t* type, const std::string& topic, bool reliable) {
    dds_qos_t* qos = NewQos(reliable, 10, false);
    const dds_entity_t writer = dds_create_writer(participant_, Topic(type, topic), qos, nullptr);
    dds_delete_qos(qos);
    EXPECT_GT(writer, 0) << dds_strretcode(writer);
    return writer;
  }

 private:
  dds_entity_t Topic(const dds_topic_descriptor_t* type, const std::string& name) {
    const dds_entity_t topic = dds_create_topic(participant_, type, name.c_str(), nullptr, nullptr);
    EXPECT_GT(topic, 0) << dds_strretcode(topic);
    return topic;
  }

  static dds_qos_t* NewQos(bool reliable, int32_t depth, bool transient_local) {
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
                         DDS_SECS(1));
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, depth);
    dds_qset_durability(qos,
                        transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
    return qos;
  }

  dds_entity_t participant_;
};

// Takes one sample (loaned) within `timeout` and hands it to `use`; false when none came.
bool TakeOne(dds_entity_t reader, const std::function<void(const void*)>& use,
             milliseconds timeout = milliseconds(5000)) {
  bool taken = false;
  WaitFor(
      [&] {
        void* samples[1] = {nullptr};
        dds_sample_info_t info{};
        const dds_return_t n = dds_take(reader, samples, &info, 1, 1);
        if (n <= 0) return false;
        if (info.valid_data) {
          use(samples[0]);
          taken = true;
        }
        dds_return_loan(reader, samples, n);
        return taken;
      },
      timeout);
  return taken;
}

// Takes one serialised sample within `timeout`: its bytes as Cyclone holds them.
std::vector<uint8_t> TakeOneCdr(dds_entity_t reader) {
  std::vector<uint8_t> bytes;
  WaitFor([&] {
    ddsi_serdata* sample = nullptr;
    dds_sample_info_t info{};
    if (dds_takecdr(reader, &sample, 1, &info, DDS_ANY_STATE) <= 0) return false;
    if (info.valid_data) {
      bytes.resize(ddsi_serdata_size(sample));
      ddsi_serdata_to_ser(sample, 0, bytes.size(), bytes.data());
    }
    ddsi_serdata_unref(sample);
    return !bytes.empty();
  });
  return bytes;
}

int MatchedPublicationCount(dds_entity_t reader) {
  dds_subscription_matched_status_t status{};
  dds_get_subscription_matched_status(reader, &status);
  return static_cast<int>(status.current_count);
}

int MatchedSubscriptionCount(dds_entity_t writer) {
  dds_publication_matched_status_t status{};
  dds_get_publication_matched_status(writer, &status);
  return static_cast<int>(status.current_count);
}

// Problems reported by a Participant, collected thread-safely.
class Problems {
 public:
  std::function<void(const std::string&)> Sink() {
    return [this](const std::string& text) {
      std::lock_guard lock(mutex_);
      texts_.push_back(text);
    };
  }
  std::vector<std::string> Texts() const {
    std::lock_guard lock(mutex_);
    return texts_;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<std::string> texts_;
};

// Messages received by a subscription callback, collected thread-safely.
template <typename Message>
class Inbox {
 public:
  void Add(Message message) {
    std::lock_guard lock(mutex_);
    messages_.push_back(std::move(message));
  }
  std::vector<Message> Messages() const {
    std::lock_guard lock(mutex_);
    return messages_;
  }
  size_t Size() const { return Messages().size(); }

 private:
  mutable std::mutex mutex_;
  std::vector<Message> messages_;
};

class DdsTest : public ::testing::Test {
 protected:
  void SetUp() override { setenv("CYCLONEDDS_URI", kLoopbackConfig, 1); }

  // A domain of this process's own: parallel test processes do not see each other.
  static uint32_t Domain() { return 20 + static_cast<uint32_t>(getpid()) % 200; }

  static std::unique_ptr<Participant> NewParticipant(const std::string& name = "sfrt_test",
                                                     const std::string& ns = "/") {
    Result<std::unique_ptr<Participant>> participant = Participant::Create(Domain(), name, ns);
    EXPECT_TRUE(participant.ok()) << participant.message();
    return participant.ok() ? std::move(participant).value() : nullptr;
  }
};

// ---------------------------------------------------------------------------------------------
// Names, domain ids, QoS profiles.

TEST(RosTopicToDds, PrefixesRtToTheRosName) {
  EXPECT_EQ(RosTopicToDds("/left/image_rect"), "rt/left/image_rect");
  EXPECT_EQ(RosTopicToDds("/foo"), "rt/foo");
  EXPECT_EQ(RosTopicToDds("robot1/camera_left/image_raw"), "rt/robot1/camera_left/image_raw");
}

TEST(ResolveTopicName, ResolvesAbsoluteRelativeAndPrivateNamesAgainstTheNode) {
  EXPECT_EQ(*ResolveTopicName("/flow", "/stereo", "sfrt"), "/flow");
  EXPECT_EQ(*ResolveTopicName("left/image_rect", "/stereo", "sfrt"), "/stereo/left/image_rect");
  EXPECT_EQ(*ResolveTopicName("flow", "/", "sfrt"), "/flow");
  EXPECT_EQ(*ResolveTopicName("~/status", "/stereo", "sfrt"), "/stereo/sfrt/status");
  EXPECT_EQ(*ResolveTopicName("~", "/", "sfrt"), "/sfrt");
  EXPECT_EQ(*ResolveTopicName("rostopic:///foo/bar", "/", "sfrt"), "/foo/bar");
}

TEST(ResolveTopicName, RefusesNamesBreakingRosRulesNamingTheNameAndTheRule) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "must not be empty"},
      {"a//b", "'//'"},
      {"a/", "must not end with '/'"},
      {"1abc", "must not start with a digit"},
      {"/a/2b", "must not start with a digit"},
      {"a b", "alphanumerics"},
      {"~foo", "'~'"},
      {"{ns}/x", "substitutions"},
      {std::string(250, 'a'), "longer than 247"},
  };
  for (const auto& [name, rule] : cases) {
    Result<std::string> resolved = ResolveTopicName(name, "/", "sfrt");
    ASSERT_FALSE(resolved.ok()) << name;
    EXPECT_NE(resolved.message().find("\"" + name + "\""), std::string::npos) << resolved.message();
    EXPECT_NE(resolved.message().find(rule), std::string::npos) << resolved.message();
  }
}

TEST(ParseDomainId, AcceptsZeroTo232AndTakesEmptyAsZero) {
  EXPECT_EQ(*ParseDomainId(""), 0u);
  EXPECT_EQ(*ParseDomainId("0"), 0u);
  EXPECT_EQ(*ParseDomainId("42"), 42u);
  EXPECT_EQ(*ParseDomainId("232"), 232u);
}

TEST(DomainIdFromEnvironment, RefusesAbcMinusOneAnd233NamingTheValue) {
  for (const char* value : {"abc", "-1", "233", "99999999999999999999", " 1"}) {
    setenv("ROS_DOMAIN_ID", value, 1);
    Result<uint32_t> domain = DomainIdFromEnvironment();
    ASSERT_FALSE(domain.ok()) << value;
    EXPECT_NE(domain.message().find(std::string("ROS_DOMAIN_ID \"") + value + "\""),
              std::string::npos)
        << domain.message();
  }
  setenv("ROS_DOMAIN_ID", "17", 1);
  EXPECT_EQ(*DomainIdFromEnvironment(), 17u);
  unsetenv("ROS_DOMAIN_ID");
  EXPECT_EQ(*DomainIdFromEnvironment(), 0u);
}

TEST(Qos, ProfilesAreRmwsSensorDataAndDefault) {
  const Qos sensor = Qos::SensorData();
  EXPECT_EQ(sensor.reliability, Qos::Reliability::kBestEffort);
  EXPECT_EQ(sensor.depth, 5u);
  EXPECT_FALSE(sensor.transient_local);
  const Qos standard = Qos::Default();
  EXPECT_EQ(standard.reliability, Qos::Reliability::kReliable);
  EXPECT_EQ(standard.depth, 10u);
  EXPECT_FALSE(standard.transient_local);
  EXPECT_EQ(Describe(sensor), "best effort, keep last 5, volatile");
}

TEST_F(DdsTest, CreateRefusesBadNodeNamesNamespacesAndDomainsNamingThem) {
  for (const auto& [name, ns, domain, needle] :
       std::vector<std::tuple<std::string, std::string, uint32_t, std::string>>{
           {"9lives", "/", Domain(), "\"9lives\""},
           {"my-node", "/", Domain(), "\"my-node\""},
           {"node", "relative", Domain(), "\"relative\""},
           {"node", "/a//b", Domain(), "\"/a//b\""},
           {"node", "/", 233, "233"}}) {
    Result<std::unique_ptr<Participant>> participant = Participant::Create(domain, name, ns);
    ASSERT_FALSE(participant.ok()) << name << " " << ns;
    EXPECT_NE(participant.message().find(needle), std::string::npos) << participant.message();
  }
}

// ---------------------------------------------------------------------------------------------
// Messages both ways.

TEST_F(DdsTest, ImagePublishedBySfrtArrivesEqualAtACycloneReaderOfTheIdlcType) {
  auto participant = NewParticipant();
  CycloneSide cyclone(Domain());
  const dds_entity_t reader =
      cyclone.Reader(&sensor_msgs_msg_dds__Image__desc, "rt/cam/image", true);
  Result<int> publisher = participant->AdvertiseImage("/cam/image", Qos::Default());
  ASSERT_TRUE(publisher.ok()) << publisher.message();
  ASSERT_TRUE(WaitFor([&] { return participant->MatchedSubscribers(*publisher) == 1; }));

  const msg::Image sent = MakeImage(4, 5, 3);
  ASSERT_TRUE(participant->Publish(*publisher, ViewOf(sent)).ok());
  msg::Image received;
  ASSERT_TRUE(TakeOne(reader, [&](const void* sample) {
    received = FromC(*static_cast<const sensor_msgs_msg_dds__Image_*>(sample));
  }));
  EXPECT_EQ(received, sent);
}

TEST_F(DdsTest, ImageWrittenByACycloneWriterArrivesEqualAtAnSfrtSubscription) {
  auto participant = NewParticipant("sfrt_test", "/stereo");
  Inbox<msg::Image> inbox;
  ASSERT_TRUE(participant
                  ->SubscribeImage("left/image_rect", Qos::SensorData(),
                                   [&](const msg::ImageView& view) { inbox.Add(CopyOf(view)); })
                  .ok());
  CycloneSide cyclone(Domain());
  const dds_entity_t writer =
      cyclone.Writer(&sensor_msgs_msg_dds__Image__desc, "rt/stereo/left/image_rect", true);
  ASSERT_TRUE(WaitFor([&] { return participant->MatchedPublishers("left/image_rect") == 1; }));

  const std::vector<msg::Image> sent = {MakeImage(3, 2, 1), MakeImage(6, 7, 2)};
  for (const msg::Image& image : sent) {
    const sensor_msgs_msg_dds__Image_ c = ToC(image);
    ASSERT_EQ(dds_write(writer, &c), DDS_RETCODE_OK);
  }
  ASSERT_TRUE(WaitFor([&] { return inbox.Size() == sent.size(); }));
  EXPECT_EQ(inbox.Messages(), sent);
}

TEST_F(DdsTest, CompressedImageAndCameraInfoFromCycloneArriveEqualAtSfrtSubscriptions) {
  auto participant = NewParticipant();
  Inbox<msg::CompressedImage> images;
  Inbox<msg::CameraInfo> infos;
  ASSERT_TRUE(participant
                  ->SubscribeCompressedImage("/left/image_rect/compressed", Qos::Default(),
                                             [&](const msg::CompressedImage& m) { images.Add(m); })
                  .ok());
  ASSERT_TRUE(participant
                  ->SubscribeCameraInfo("/left/camera_info", Qos::Default(),
                                        [&](const msg::CameraInfo& m) { infos.Add(m); })
                  .ok());
  CycloneSide cyclone(Domain());
  const dds_entity_t image_writer = cyclone.Writer(&sensor_msgs_msg_dds__CompressedImage__desc,
                                                   "rt/left/image_rect/compressed", true);
  const dds_entity_t info_writer =
      cyclone.Writer(&sensor_msgs_msg_dds__CameraInfo__desc, "rt/left/camera_info", true);
  ASSERT_TRUE(WaitFor([&] {
    return participant->MatchedPublishers("/left/image_rect/compressed") == 1 &&
           participant->MatchedPublishers("/left/camera_info") == 1;
  }));

  const msg::CompressedImage image = MakeCompressedImage();
  const msg::CameraInfo info = MakeCameraInfo();
  const sensor_msgs_msg_dds__CompressedImage_ c_image = ToC(image);
  const sensor_msgs_msg_dds__CameraInfo_ c_info = ToC(info);
  ASSERT_EQ(dds_write(image_writer, &c_image), DDS_RETCODE_OK);
  ASSERT_EQ(dds_write(info_writer, &c_info), DDS_RETCODE_OK);
  ASSERT_TRUE(WaitFor([&] { return images.Size() == 1 && infos.Size() == 1; }));
  EXPECT_EQ(images.Messages()[0], image);
  EXPECT_EQ(infos.Messages()[0], info);
}

TEST_F(DdsTest, CdrTakenFromCycloneIsByteForByteMsgEncodeForImageHeaderAndDiagnostics) {
  auto participant = NewParticipant();
  CycloneSide cyclone(Domain());
  const dds_entity_t image_reader =
      cyclone.Reader(&sensor_msgs_msg_dds__Image__desc, "rt/flow", true);
  const dds_entity_t header_reader =
      cyclone.Reader(&std_msgs_msg_dds__Header__desc, "rt/flow_t1", true);
  const dds_entity_t diagnostics_reader =
      cyclone.Reader(&diagnostic_msgs_msg_dds__DiagnosticArray__desc, "rt/diagnostics", true);
  const int image = *participant->AdvertiseImage("/flow", Qos::Default());
  const int header = *participant->AdvertiseHeader("flow_t1", Qos::Default());
  const int diagnostics = *participant->AdvertiseDiagnosticArray("/diagnostics", Qos::Default());
  ASSERT_TRUE(WaitFor([&] {
    return participant->MatchedSubscribers(image) == 1 &&
           participant->MatchedSubscribers(header) == 1 &&
           participant->MatchedSubscribers(diagnostics) == 1;
  }));

  // 5 x 3 bytes of data: a message whose length is not a multiple of 4.
  msg::Image flow = MakeImage(1, 5, 9);
  const msg::Header stamp{{11, 12}, "left_camera"};
  const msg::DiagnosticArray array = MakeDiagnostics();
  ASSERT_TRUE(participant->Publish(image, ViewOf(flow)).ok());
  ASSERT_TRUE(participant->Publish(header, stamp).ok());
  ASSERT_TRUE(participant->Publish(diagnostics, array).ok());

  std::vector<uint8_t> expected;
  msg::Encode(flow, &expected);
  const std::vector<uint8_t> image_bytes = TakeOneCdr(image_reader);
  EXPECT_EQ(image_bytes, expected);
  ASSERT_GE(image_bytes.size(), 4u);
  EXPECT_EQ(std::vector<uint8_t>(image_bytes.begin(), image_bytes.begin() + 4),
            (std::vector<uint8_t>{0x00, 0x01, 0x00, 0x00}));
  msg::Encode(stamp, &expected);
  EXPECT_EQ(TakeOneCdr(header_reader), expected);
  msg::Encode(array, &expected);
  EXPECT_EQ(TakeOneCdr(diagnostics_reader), expected);
}

TEST_F(DdsTest, PublishingWithAHandleOfAnotherTypeOrNoneIsRefusedNamingTheTopic) {
  auto participant = NewParticipant();
  const int image = *participant->AdvertiseImage("/flow", Qos::Default());
  Status status = participant->Publish(image, msg::Header{});
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("/flow"), std::string::npos) << status.message();
  EXPECT_NE(status.message().find("std_msgs/msg/Header"), std::string::npos) << status.message();
  status = participant->Publish(image + 1, msg::Header{});
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("handle"), std::string::npos) << status.message();
}

// Undecodable samples cannot be made here: Cyclone checks what its writers serialise (dds_write
// refuses a bool of 2) and what its readers receive against the descriptor, so sfrt's decoder
// is a second line. The once-per-topic reporting is shared with failing callbacks:
TEST_F(DdsTest, ThrowingCallbackIsReportedOncePerTopicAndDeliveryGoesOn) {
  auto participant = NewParticipant();
  Problems problems;
  participant->OnProblem(problems.Sink());
  std::atomic<int> calls{0};
  ASSERT_TRUE(participant
                  ->SubscribeCameraInfo("/camera_info", Qos::Default(),
                                        [&](const msg::CameraInfo&) {
                                          ++calls;
                                          throw std::runtime_error("no calibration wanted");
                                        })
                  .ok());
  CycloneSide cyclone(Domain());
  const dds_entity_t writer =
      cyclone.Writer(&sensor_msgs_msg_dds__CameraInfo__desc, "rt/camera_info", true);
  ASSERT_TRUE(WaitFor([&] { return participant->MatchedPublishers("/camera_info") == 1; }));

  const msg::CameraInfo info = MakeCameraInfo();
  const sensor_msgs_msg_dds__CameraInfo_ c_info = ToC(info);  // points into `info`
  for (int i = 0; i < 3; ++i) ASSERT_EQ(dds_write(writer, &c_info), DDS_RETCODE_OK);
  ASSERT_TRUE(WaitFor([&] { return calls == 3; }));
  const std::vector<std::string> texts = problems.Texts();
  ASSERT_EQ(texts.size(), 1u);
  EXPECT_NE(texts[0].find("rt/camera_info"), std::string::npos) << texts[0];
  EXPECT_NE(texts[0].find("no calibration wanted"), std::string::npos) << texts[0];
}

// ---------------------------------------------------------------------------------------------
// QoS matching.

TEST_F(DdsTest, SensorDataSubscriptionMatchesADefaultPublisherAndReceives) {
  auto publisher_node = NewParticipant("camera");
  auto subscriber_node = NewParticipant("sfrt");
  Inbox<msg::Image> inbox;
  ASSERT_TRUE(subscriber_node
                  ->SubscribeImage("/left/image_rect", Qos::SensorData(),
                                   [&](const msg::ImageView& view) { inbox.Add(CopyOf(view)); })
                  .ok());
  const int publisher = *publisher_node->AdvertiseImage("/left/image_rect", Qos::Default());
  ASSERT_TRUE(WaitFor([&] { return subscriber_node->MatchedPublishers("/left/image_rect") == 1; }));
  EXPECT_EQ(publisher_node->MatchedSubscribers(publisher), 1);

  const msg::Image sent = MakeImage(2, 2, 4);
  ASSERT_TRUE(publisher_node->Publish(publisher, ViewOf(sent)).ok());
  ASSERT_TRUE(WaitFor([&] { return inbox.Size() == 1; }));
  EXPECT_EQ(inbox.Messages()[0], sent);
}

TEST_F(DdsTest, ReliableSubscriptionReportsBestEffortPublishersOnceNamingTopicAndReliabilities) {
  auto participant = NewParticipant();
  Problems problems;
  participant->OnProblem(problems.Sink());
  ASSERT_TRUE(
      participant->SubscribeImage("/cam/image", Qos::Default(), [](const msg::ImageView&) {}).ok());
  CycloneSide cyclone(Domain());
  const dds_entity_t first =
      cyclone.Writer(&sensor_msgs_msg_dds__Image__desc, "rt/cam/image", false);
  const dds_entity_t second =
      cyclone.Writer(&sensor_msgs_msg_dds__Image__desc, "rt/cam/image", false);

  ASSERT_TRUE(WaitFor([&] { return !problems.Texts().empty(); }));
  std::this_thread::sleep_for(milliseconds(200));  // room for a second (wrong) report
  const std::vector<std::string> texts = problems.Texts();
  ASSERT_EQ(texts.size(), 1u);
  EXPECT_NE(texts[0].find("ROS topic /cam/image"), std::string::npos) << texts[0];
  EXPECT_NE(texts[0].find("DDS rt/cam/image"), std::string::npos) << texts[0];
  EXPECT_NE(texts[0].find("incompatible QoS (reliability)"), std::string::npos) << texts[0];
  EXPECT_NE(texts[0].find("requests reliable"), std::string::npos) << texts[0];
  EXPECT_NE(texts[0].find("offers best effort"), std::string::npos) << texts[0];
  EXPECT_EQ(participant->MatchedPublishers("/cam/image"), 0);
  EXPECT_EQ(MatchedSubscriptionCount(first) + MatchedSubscriptionCount(second), 0);
}

TEST_F(DdsTest, BestEffortPublisherReportsAReliableSubscriptionOnceNamingBothReliabilities) {
  auto participant = NewParticipant();
  Problems problems;
  participant->OnProblem(problems.Sink());
  const int publisher = *participant->AdvertiseImage("/flow_vis", Qos::SensorData());
  CycloneSide cyclone(Domain());
  const dds_entity_t reader =
      cyclone.Reader(&sensor_msgs_msg_dds__Image__desc, "rt/flow_vis", true);

  ASSERT_TRUE(WaitFor([&] { return !problems.Texts().empty(); }));
  const std::vector<std::string> texts = problems.Texts();
  ASSERT_EQ(texts.size(), 1u);
  EXPECT_NE(texts[0].find("rt/flow_vis"), std::string::npos) << texts[0];
  EXPECT_NE(texts[0].find("offers best effort"), std::string::npos) << texts[0];
  EXPECT_NE(texts[0].find("requests reliable"), std::string::npos) << texts[0];
  EXPECT_EQ(participant->MatchedSubscribers(publisher), 0);
  EXPECT_EQ(MatchedPublicationCount(reader), 0);
}

// ---------------------------------------------------------------------------------------------
// Allocation.

TEST_F(DdsTest, PublishingASameSizedImageAgainAllocatesNothingInSfrt) {
  auto participant = NewParticipant();
  CycloneSide cyclone(Domain());
  const dds_entity_t reader =
      cyclone.Reader(&sensor_msgs_msg_dds__Image__desc, "rt/flow", false, 1);
  const int publisher = *participant->AdvertiseImage("/flow", Qos::SensorData());
  ASSERT_TRUE(WaitFor([&] { return participant->MatchedSubscribers(publisher) == 1; }));
  const msg::Image first = MakeImage(96, 128, 1);
  const msg::Image second = MakeImage(96, 128, 2);
  ASSERT_TRUE(participant->Publish(publisher, ViewOf(first)).ok());

  const size_t news_before = g_news.load();
  const size_t mallocs_before = g_mallocs.load();
  const Status status = participant->Publish(publisher, ViewOf(second));
  const size_t news = g_news.load() - news_before;
  const size_t mallocs = g_mallocs.load() - mallocs_before;
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(news, 0u) << "operator new calls in the second Publish";
  // Cyclone's own allocations (C, malloc) are measured, not asserted: they are Cyclone's.
  const std::string measured =
      kMallocCounted ? std::to_string(mallocs - news) : "not measured under AddressSanitizer";
  RecordProperty("cyclone_mallocs_per_publish", measured);
  std::printf(
      "Cyclone malloc/calloc/realloc calls in one Publish of a 36 KiB image to one "
      "local reader: %s\n",
      measured.c_str());
  msg::Image received;
  ASSERT_TRUE(TakeOne(reader, [&](const void* sample) {
    received = FromC(*static_cast<const sensor_msgs_msg_dds__Image_*>(sample));
  }));
  EXPECT_EQ(received, second);
}

TEST_F(DdsTest, ReceivingAnImageViewAllocatesNothingInSfrt) {
  auto participant = NewParticipant();
  std::atomic<int> calls{0};
  std::atomic<size_t> bytes{0};
  ASSERT_TRUE(participant
                  ->SubscribeImage("/left/image_rect", Qos::Default(),
                                   [&](const msg::ImageView& view) {
                                     bytes = view.data.size();
                                     ++calls;
                                   })
                  .ok());
  CycloneSide cyclone(Domain());
  const dds_entity_t writer =
      cyclone.Writer(&sensor_msgs_msg_dds__Image__desc, "rt/left/image_rect", true);
  ASSERT_TRUE(WaitFor([&] { return participant->MatchedPublishers("/left/image_rect") == 1; }));
  const msg::Image first = MakeImage(96, 128, 1);
  const msg::Image second = MakeImage(96, 128, 2);
  const sensor_msgs_msg_dds__Image_ c_first = ToC(first);
  const sensor_msgs_msg_dds__Image_ c_second = ToC(second);
  ASSERT_EQ(dds_write(writer, &c_first), DDS_RETCODE_OK);
  ASSERT_TRUE(WaitFor([&] { return calls == 1; }));

  // A local writer delivers on its own thread, inside dds_write: the callback has run on return.
  const size_t news_before = g_news.load();
  ASSERT_EQ(dds_write(writer, &c_second), DDS_RETCODE_OK);
  const size_t news = g_news.load() - news_before;
  ASSERT_EQ(calls, 2);
  EXPECT_EQ(bytes, second.data.size());
  EXPECT_EQ(news, 0u) << "operator new calls while delivering an ImageView";
}

// ---------------------------------------------------------------------------------------------
// ros_discovery_info.

TEST_F(DdsTest, AnnounceNodePublishesTheNodeWithItsReaderAndWriterGidsTransientLocal) {
  auto participant = NewParticipant("sfrt_node", "/stereo");
  ASSERT_TRUE(
      participant->SubscribeImage("left/image_rect", Qos::SensorData(), [](const auto&) {}).ok());
  const int publisher = *participant->AdvertiseImage("flow", Qos::Default());
  ASSERT_TRUE(participant->AnnounceNode().ok());

  // A late joiner, as `ros2 node list` is: transient local hands it the announcement.
  CycloneSide cyclone(Domain());
  const dds_entity_t info_reader = cyclone.Reader(
      &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc, "ros_discovery_info", true, 1, true);
  const dds_entity_t flow_reader =
      cyclone.Reader(&sensor_msgs_msg_dds__Image__desc, "rt/stereo/flow", true);
  const dds_entity_t left_writer =
      cyclone.Writer(&sensor_msgs_msg_dds__Image__desc, "rt/stereo/left/image_rect", true);
  ASSERT_TRUE(WaitFor([&] {
    return participant->MatchedSubscribers(publisher) == 1 &&
           MatchedSubscriptionCount(left_writer) == 1;
  }));

  Guid participant_gid{}, reader_gid{}, writer_gid{};
  std::string name, ns;
  size_t nodes = 0, readers = 0, writers = 0;
  ASSERT_TRUE(TakeOne(info_reader, [&](const void* sample) {
    const auto& info =
        *static_cast<const rmw_dds_common_msg_dds__ParticipantEntitiesInfo_*>(sample);
    participant_gid = GuidOf(info.gid_);
    nodes = info.node_entities_info_seq_._length;
    if (nodes != 1) return;
    const auto& node = info.node_entities_info_seq_._buffer[0];
    name = node.node_name_;
    ns = node.node_namespace_;
    readers = node.reader_gid_seq_._length;
    writers = node.writer_gid_seq_._length;
    if (readers == 1) reader_gid = GuidOf(node.reader_gid_seq_._buffer[0]);
    if (writers == 1) writer_gid = GuidOf(node.writer_gid_seq_._buffer[0]);
  }));
  EXPECT_EQ(participant_gid, participant->ParticipantGuid());
  ASSERT_EQ(nodes, 1u);
  EXPECT_EQ(name, "sfrt_node");
  EXPECT_EQ(ns, "/stereo");
  ASSERT_EQ(readers, 1u);
  ASSERT_EQ(writers, 1u);

  // The gids are the GUIDs DDS discovery shows for the node's reader and writer.
  dds_instance_handle_t handle = 0;
  ASSERT_EQ(dds_get_matched_publications(flow_reader, &handle, 1), 1);
  dds_builtintopic_endpoint_t* remote_writer =
      dds_get_matched_publication_data(flow_reader, handle);
  ASSERT_NE(remote_writer, nullptr);
  EXPECT_EQ(writer_gid, GuidOf(remote_writer->key));
  dds_builtintopic_free_endpoint(remote_writer);
  ASSERT_EQ(dds_get_matched_subscriptions(left_writer, &handle, 1), 1);
  dds_builtintopic_endpoint_t* remote_reader =
      dds_get_matched_subscription_data(left_writer, handle);
  ASSERT_NE(remote_reader, nullptr);
  EXPECT_EQ(reader_gid, GuidOf(remote_reader->key));
  dds_builtintopic_free_endpoint(remote_reader);
}

TEST(EncodeParticipantEntitiesInfo, HumbleLayoutWrites24ByteGidsOfTheGuidThenEightZeros) {
  Guid participant, reader;
  for (size_t i = 0; i < 16; ++i) {
    participant[i] = static_cast<uint8_t>(i + 1);
    reader[i] = static_cast<uint8_t>(0x40 + i);
  }
  std::vector<uint8_t> bytes;
  EncodeParticipantEntitiesInfo(participant, {{"/ns", "n", {reader}, {}}}, GidLayout::k24Bytes,
                                &bytes);
  std::vector<uint8_t> expected = {0x00, 0x01, 0x00, 0x00};
  auto append = [&](std::initializer_list<uint8_t> more) { expected.insert(expected.end(), more); };
  auto append_gid = [&](const Guid& guid) {
    expected.insert(expected.end(), guid.begin(), guid.end());
    expected.insert(expected.end(), 8, 0);
  };
  append_gid(participant);                 // gid: char[24], offset 0
  append({1, 0, 0, 0});                    // one node, offset 24
  append({4, 0, 0, 0, '/', 'n', 's', 0});  // node_namespace, offset 28
  append({2, 0, 0, 0, 'n', 0});            // node_name, offset 36
  append({0, 0});                          // padding to 44
  append({1, 0, 0, 0});                    // one reader gid
  append_gid(reader);                      // offset 48
  append({0, 0, 0, 0});                    // no writer gids, offset 72
  EXPECT_EQ(bytes, expected);
}

TEST(EncodeParticipantEntitiesInfo, JazzyLayoutWrites16ByteGids) {
  Guid participant{};
  participant[0] = 0xaa;
  std::vector<uint8_t> bytes;
  EncodeParticipantEntitiesInfo(participant, {{"/", "n", {}, {participant}}}, GidLayout::k16Bytes,
                                &bytes);
  std::vector<uint8_t> expected = {0x00, 0x01, 0x00, 0x00};
  auto append = [&](std::initializer_list<uint8_t> more) { expected.insert(expected.end(), more); };
  append({0xaa, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0});  // gid: char[16], offset 0
  append({1, 0, 0, 0});                                         // one node, offset 16
  append({2, 0, 0, 0, '/', 0});                                 // node_namespace, offset 20
  append({0, 0});                                               // padding to 28
  append({2, 0, 0, 0, 'n', 0});                                 // node_name, offset 28
  append({0, 0});                                               // padding to 36
  append({0, 0, 0, 0});                                         // no reader gids
  append({1, 0, 0, 0});                                         // one writer gid, offset 40
  append({0xaa, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0});  // offset 44
  EXPECT_EQ(bytes, expected);
}

// ---------------------------------------------------------------------------------------------
// Against the independent peer program, in another process, over the loopback network.

class PeerProcessTest : public DdsTest {
 protected:
  void SetUp() override {
    DdsTest::SetUp();
    const char* peer = std::getenv("SFRT_CYCLONE_PEER");
#ifdef SFRT_CYCLONE_PEER_PATH
    if (peer == nullptr || *peer == '\0') peer = SFRT_CYCLONE_PEER_PATH;
#endif
    if (peer == nullptr || *peer == '\0') GTEST_SKIP() << "no cyclone_peer: set SFRT_CYCLONE_PEER";
    peer_ = peer;
    char dir[] = "/tmp/sfrt_dds_test_XXXXXX";
    ASSERT_NE(mkdtemp(dir), nullptr);
    dir_ = dir;
  }
  void TearDown() override {
    if (!dir_.empty()) std::system(("rm -rf '" + dir_ + "'").c_str());
  }

  // Starts the peer with `args`; its environment is ours (CYCLONEDDS_URI included).
  pid_t Spawn(const std::vector<std::string>& args) {
    std::vector<char*> argv = {peer_.data()};
    for (const std::string& arg : args) argv.push_back(const_cast<char*>(arg.c_str()));
    argv.push_back(nullptr);
    pid_t pid = 0;
    EXPECT_EQ(posix_spawn(&pid, peer_.c_str(), nullptr, nullptr, argv.data(), environ), 0);
    return pid;
  }

  // The peer's exit status, or -1 when it is still running after `timeout` (then killed).
  static int Wait(pid_t pid, milliseconds timeout = milliseconds(30000)) {
    int status = 0;
    if (!WaitFor([&] { return waitpid(pid, &status, WNOHANG) == pid; }, timeout)) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return -1;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  static std::string ReadFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }

  static void WriteFile(const std::string& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary) << bytes;
  }

  std::string peer_;
  std::string dir_;
};

TEST_F(PeerProcessTest, ImagesPublishedBySfrtReachThePeerProcessEqual) {
  const std::string domain = std::to_string(Domain());
  const pid_t pid = Spawn({"receive", "--domain", domain, "--topic", "rt/flow", "--count", "2",
                           "--out", dir_, "--timeout-ms", "20000"});
  auto participant = NewParticipant();
  const int publisher = *participant->AdvertiseImage("/flow", Qos::Default());
  ASSERT_TRUE(WaitFor([&] { return participant->MatchedSubscribers(publisher) == 1; },
                      milliseconds(15000)));
  std::vector<msg::Image> sent = {MakeImage(2, 3, 1), MakeImage(3, 1, 2)};
  sent[0].encoding = "32FC3";
  sent[0].step = 3 * 12;
  sent[0].data.resize(2 * 3 * 12);
  for (const msg::Image& image : sent)
    ASSERT_TRUE(participant->Publish(publisher, ViewOf(image)).ok());
  ASSERT_EQ(Wait(pid), 0);

  for (size_t i = 0; i < sent.size(); ++i) {
    const std::string base = dir_ + "/image_00000" + std::to_string(i);
    const msg::Image& image = sent[i];
    EXPECT_EQ(ReadFile(base + ".txt"),
              "sec " + std::to_string(image.header.stamp.sec) + "\nnanosec " +
                  std::to_string(image.header.stamp.nanosec) + "\nframe_id left_camera\nheight " +
                  std::to_string(image.height) + "\nwidth " + std::to_string(image.width) +
                  "\nencoding " + image.encoding + "\nis_bigendian 0\nstep " +
                  std::to_string(image.step) + "\ndata_size " + std::to_string(image.data.size()) +
                  "\n");
    EXPECT_EQ(ReadFile(base + ".data"), std::string(image.data.begin(), image.data.end()));
  }
}

TEST_F(PeerProcessTest, StereoPairsFromThePeerProcessReachSfrtSubscriptionsEqual) {
  std::string index;
  std::vector<msg::Image> left, right;
  for (int i = 0; i < 3; ++i) {
    left.push_back(MakeImage(4, 6, static_cast<uint8_t>(i)));
    right.push_back(MakeImage(4, 6, static_cast<uint8_t>(100 + i)));
    right.back().header = left.back().header;
    right.back().header.frame_id = "right_camera";
    const std::string n = std::to_string(i);
    WriteFile(dir_ + "/l" + n + ".bgr", std::string(left[i].data.begin(), left[i].data.end()));
    WriteFile(dir_ + "/r" + n + ".bgr", std::string(right[i].data.begin(), right[i].data.end()));
    index += std::to_string(left[i].header.stamp.sec) + " " +
             std::to_string(left[i].header.stamp.nanosec) + " 4 6 l" + n + ".bgr r" + n + ".bgr\n";
  }
  WriteFile(dir_ + "/index.txt", "# sec nanosec height width left right\n" + index);

  auto participant = NewParticipant("sfrt", "/stereo");
  Inbox<msg::Image> left_inbox, right_inbox;
  // Reliable, as the peer's writers are: the peer writes once its writers have matched these
  // readers, and a best-effort reader that has not yet matched the writer in turn drops what
  // arrives (discovery is slow under ASan: CI lost the first pairs once); reliable ones get them
  // again from the writer's history. SensorData subscriptions are DdsTest's.
  ASSERT_TRUE(participant
                  ->SubscribeImage("left/image_rect", Qos::Default(),
                                   [&](const msg::ImageView& v) { left_inbox.Add(CopyOf(v)); })
                  .ok());
  ASSERT_TRUE(participant
                  ->SubscribeImage("right/image_rect", Qos::Default(),
                                   [&](const msg::ImageView& v) { right_inbox.Add(CopyOf(v)); })
                  .ok());
  const pid_t pid = Spawn({"publish-stereo", "--domain", std::to_string(Domain()), "--left-topic",
                           "rt/stereo/left/image_rect", "--right-topic",
                           "rt/stereo/right/image_rect", "--frames", dir_, "--wait-ms", "15000"});
  ASSERT_EQ(Wait(pid), 0);
  ASSERT_TRUE(WaitFor([&] { return left_inbox.Size() == 3 && right_inbox.Size() == 3; }));
  EXPECT_EQ(left_inbox.Messages(), left);
  EXPECT_EQ(right_inbox.Messages(), right);
}

}  // namespace
}  // namespace sfrt::ros2::dds
