// fastdds_peer: an independent ROS 2 participant on Fast DDS 2.9 (rmw_fastrtps's middleware, the
// default of ROS 2 Humble and Jazzy), for tests that sfrt's node interoperates across DDS vendors.
// Test-only. It speaks ROS 2's mapping onto DDS the way rmw_fastrtps does, without rclcpp:
//   - a ROS topic "/flow" is the DDS topic "rt/flow" (the caller passes the DDS name);
//   - a ROS type pkg/msg/Name is the DDS type "pkg::msg::dds_::Name_";
//   - samples are plain CDR (XCDR1) behind the 4-byte encapsulation header 00 01 00 00 (little
//     endian), with alignment counted from after that header;
//   - QoS: best_effort is ROS's sensor_data profile (keep last 5, volatile), reliable is ROS's
//     default profile (keep last 10, volatile).
// The two message types are written by hand over Fast-CDR (no fastddsgen, which needs Java).
//
//   fastdds_peer receive --domain D --topic T --type image|header --count N --out DIR
//                        [--reliability best_effort|reliable] [--timeout-s S] [--interface A]
//       writes message i (from 0) as DIR/<i>.json (its fields, "stamp_ns", "data_size" for an
//       image, "encapsulation": the sample's first 4 bytes in hex, "cdr_size"), DIR/<i>.cdr (the
//       serialized sample as it came off the wire, header and any padding included) and, for an
//       image, DIR/<i>.bin (its data); exit 0 after N messages, 3 on timeout (saying how many
//       came).
//   fastdds_peer publish-image --domain D --topic T --height H --width W --encoding E
//                        --data FILE --stamp-ns T --frame-id F [--step S] [--is-bigendian 0|1]
//                        [--reliability best_effort|reliable] [--match-timeout-s S]
//                        [--settle-ms M] [--repeat N] [--interface A]
//       waits for a matched reader, then M ms (default 1000) for that reader to match this
//       writer, publishes one Image (data = the bytes of FILE), waits for its acknowledgement
//       when reliable; exit 0 when sent, 3 when no reader matched in time or a reliable reader
//       did not acknowledge. --repeat N writes it N times, 200 ms apart (default 1).
//
// --interface A (e.g. 127.0.0.1) keeps the participant on that one IPv4 interface: UDPv4 only (no
// shared memory, which another vendor cannot use anyway), and A as the initial unicast discovery
// peer, so that discovery needs no multicast. Without it Fast DDS uses its defaults.
// Exit status: 0 done, 1 a DDS call failed, 2 usage, 3 timeout.
#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastcdr/exceptions/Exception.h>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>

#include <charconv>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <iterator>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace dds = eprosima::fastdds::dds;
using eprosima::fastcdr::Cdr;
using eprosima::fastcdr::FastBuffer;
using eprosima::fastrtps::rtps::InstanceHandle_t;
using eprosima::fastrtps::rtps::SerializedPayload_t;

constexpr int kExitOk = 0;
constexpr int kExitDdsFailed = 1;
constexpr int kExitUsage = 2;
constexpr int kExitTimeout = 3;

// ---------------------------------------------------------------------------------------------
// The messages, field for field as in their .msg files.

struct Time {  // builtin_interfaces/msg/Time
  int32_t sec = 0;
  uint32_t nanosec = 0;
};

struct Header {  // std_msgs/msg/Header
  Time stamp;
  std::string frame_id;
};

struct Image {  // sensor_msgs/msg/Image
  Header header;
  uint32_t height = 0;
  uint32_t width = 0;
  std::string encoding;
  uint8_t is_bigendian = 0;
  uint32_t step = 0;
  std::vector<uint8_t> data;
};

// ---------------------------------------------------------------------------------------------
// Their CDR, over Fast-CDR. Cdr aligns each primitive to its own size; a string is a uint32
// length that counts the terminating NUL, then the bytes and the NUL; uint8[] is a uint32 count,
// then the bytes.

void Write(Cdr& cdr, const Header& m) { cdr << m.stamp.sec << m.stamp.nanosec << m.frame_id; }

void Read(Cdr& cdr, Header& m, size_t /*payload_size*/) {
  cdr >> m.stamp.sec >> m.stamp.nanosec >> m.frame_id;
}

void Write(Cdr& cdr, const Image& m) {
  Write(cdr, m.header);
  cdr << m.height << m.width << m.encoding << m.is_bigendian << m.step;
  cdr << static_cast<uint32_t>(m.data.size());
  cdr.serializeArray(m.data.data(), m.data.size());
}

void Read(Cdr& cdr, Image& m, size_t payload_size) {
  Read(cdr, m.header, payload_size);
  cdr >> m.height >> m.width >> m.encoding >> m.is_bigendian >> m.step;
  uint32_t size = 0;
  cdr >> size;
  // Checked before resizing, so that a damaged count cannot ask for gigabytes.
  if (size > payload_size - cdr.getSerializedDataLength()) {
    throw eprosima::fastcdr::exception::NotEnoughMemoryException(
        "Image.data: the sequence length is longer than the rest of the sample");
  }
  m.data.resize(size);
  cdr.deserializeArray(m.data.data(), size);
}

// Exact serialized size, encapsulation included: what Fast DDS allocates for the payload.
class CdrSize {
 public:
  CdrSize& Primitive(size_t size) {
    at_ += (size - at_ % size) % size + size;
    return *this;
  }
  CdrSize& Bytes(size_t count) {  // string (count with its NUL) or uint8[]
    Primitive(4);
    at_ += count;
    return *this;
  }
  size_t Total() const { return 4 + at_; }  // the encapsulation header does not move `at_`

 private:
  size_t at_ = 0;  // offset from the end of the encapsulation header
};

void AddSize(CdrSize& size, const Header& m) {
  size.Primitive(4).Primitive(4).Bytes(m.frame_id.size() + 1);
}

void AddSize(CdrSize& size, const Image& m) {
  AddSize(size, m.header);
  size.Primitive(4).Primitive(4).Bytes(m.encoding.size() + 1).Primitive(1).Primitive(4);
  size.Bytes(m.data.size());
}

// ---------------------------------------------------------------------------------------------
// The TopicDataTypes: one template for the CDR plumbing, one small class per DDS type name.

// What the data types carry: the message and, once taken from a reader, the serialized sample
// it came as (encapsulation header included), so that tests can check the bytes on the wire.
template <typename Msg>
struct Sample {
  Msg msg;
  std::vector<uint8_t> wire;  // filled by deserialize; serialize ignores it
};

template <typename Msg>
class CdrPubSubType : public dds::TopicDataType {
 public:
  explicit CdrPubSubType(const char* dds_type_name) {
    setName(dds_type_name);
    // A first allocation only: the data writer and reader run with PREALLOCATED_WITH_REALLOC
    // (as rmw_fastrtps does), so payloads grow to what getSerializedSizeProvider says.
    m_typeSize = 256;
    m_isGetKeyDefined = false;  // ROS 2 messages have no key
    // As rmw_fastrtps: announce no XTypes type object or information; peers match on the name.
    auto_fill_type_object(false);
    auto_fill_type_information(false);
  }

  bool serialize(void* data, SerializedPayload_t* payload) override {
    FastBuffer buffer(reinterpret_cast<char*>(payload->data), payload->max_size);
    Cdr cdr(buffer, Cdr::LITTLE_ENDIANNESS, Cdr::DDS_CDR);
    try {
      cdr.serialize_encapsulation();  // 00 01 00 00, and the alignment restarts after it
      Write(cdr, static_cast<const Sample<Msg>*>(data)->msg);
    } catch (const eprosima::fastcdr::exception::Exception& e) {
      std::cerr << "fastdds_peer: cannot serialize a " << getName() << ": " << e.what() << "\n";
      return false;
    }
    payload->encapsulation = CDR_LE;
    payload->length = static_cast<uint32_t>(cdr.getSerializedDataLength());
    return true;
  }

  bool deserialize(SerializedPayload_t* payload, void* data) override {
    FastBuffer buffer(reinterpret_cast<char*>(payload->data), payload->length);
    Cdr cdr(buffer, Cdr::DEFAULT_ENDIAN, Cdr::DDS_CDR);
    try {
      cdr.read_encapsulation();  // takes the byte order the writer chose
      auto* sample = static_cast<Sample<Msg>*>(data);
      Read(cdr, sample->msg, payload->length);
      sample->wire.assign(payload->data, payload->data + payload->length);
    } catch (const eprosima::fastcdr::exception::Exception& e) {
      std::cerr << "fastdds_peer: dropped a " << getName() << " of " << payload->length
                << " bytes that does not decode: " << e.what() << "\n";
      return false;
    }
    return true;
  }

  std::function<uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data]() {
      CdrSize size;
      AddSize(size, static_cast<const Sample<Msg>*>(data)->msg);
      return static_cast<uint32_t>(size.Total());
    };
  }

  void* createData() override { return new Sample<Msg>(); }
  void deleteData(void* data) override { delete static_cast<Sample<Msg>*>(data); }
  bool getKey(void*, InstanceHandle_t*, bool) override { return false; }
};

class HeaderPubSubType : public CdrPubSubType<Header> {
 public:
  HeaderPubSubType() : CdrPubSubType("std_msgs::msg::dds_::Header_") {}
};

class ImagePubSubType : public CdrPubSubType<Image> {
 public:
  ImagePubSubType() : CdrPubSubType("sensor_msgs::msg::dds_::Image_") {}
};

// ---------------------------------------------------------------------------------------------
// Command line: a subcommand, then "--name value" pairs.

class UsageError : public std::runtime_error {
  using std::runtime_error::runtime_error;
};

const char kUsage[] =
    "usage:\n"
    "  fastdds_peer receive --domain D --topic T --type image|header --count N --out DIR\n"
    "                       [--reliability best_effort|reliable] [--timeout-s S]\n"
    "                       [--interface A]\n"
    "  fastdds_peer publish-image --domain D --topic T --height H --width W --encoding E\n"
    "                       --data FILE --stamp-ns T --frame-id F [--step S]\n"
    "                       [--is-bigendian 0|1] [--reliability best_effort|reliable]\n"
    "                       [--match-timeout-s S] [--settle-ms M] [--repeat N]\n"
    "                       [--interface A]\n"
    "  fastdds_peer --help\n"
    "T is the DDS topic (ROS topic /flow is rt/flow). receive writes DIR/<i>.json (fields),\n"
    "DIR/<i>.cdr (the serialized sample) and DIR/<i>.bin (an image's data) for i from 0.\n"
    "--reliability: best_effort (ROS sensor_data: keep last 5) or reliable (ROS default: keep\n"
    "last 10), both volatile; the default is best_effort for receive (it matches either kind\n"
    "of writer) and reliable for publish-image. --timeout-s, --match-timeout-s and\n"
    "--settle-ms (the wait, once matched, for the reader to match the writer too) default to\n"
    "20, 10 and 1000. --interface A keeps discovery and data on the IPv4 interface A over UDP\n"
    "(e.g. 127.0.0.1). Exit: 0 done, 1 DDS failure, 2 usage, 3 timeout.\n";

struct Options {
  std::map<std::string, std::string> values;

  bool Has(const std::string& name) const { return values.count(name) != 0; }

  const std::string& Get(const std::string& name) const {
    auto it = values.find(name);
    if (it == values.end()) throw UsageError("missing required option --" + name);
    return it->second;
  }

  std::string GetOr(const std::string& name, const std::string& fallback) const {
    return Has(name) ? values.at(name) : fallback;
  }

  // An integer in [min, max]; the error names the option and the value.
  int64_t Integer(const std::string& name, int64_t min, int64_t max) const {
    const std::string& text = Get(name);
    int64_t value = 0;
    auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (error != std::errc() || end != text.data() + text.size() || value < min || value > max) {
      throw UsageError("--" + name + " '" + text + "': expected an integer from " +
                       std::to_string(min) + " to " + std::to_string(max));
    }
    return value;
  }

  int64_t IntegerOr(const std::string& name, int64_t min, int64_t max, int64_t fallback) const {
    return Has(name) ? Integer(name, min, max) : fallback;
  }

  // One of `choices`, or `fallback` when absent (an empty `fallback`: required).
  std::string Choice(const std::string& name, const std::set<std::string>& choices,
                     const std::string& fallback) const {
    std::string value = fallback.empty() ? Get(name) : GetOr(name, fallback);
    if (choices.count(value) == 0) {
      std::string list;
      for (const auto& c : choices) list += (list.empty() ? "" : "|") + c;
      throw UsageError("--" + name + " '" + value + "': expected " + list);
    }
    return value;
  }
};

Options ParseOptions(int argc, char** argv, const std::set<std::string>& known) {
  Options options;
  for (int i = 2; i < argc; i += 2) {
    std::string arg = argv[i];
    if (arg.rfind("--", 0) != 0) throw UsageError("expected an option, got '" + arg + "'");
    std::string name = arg.substr(2);
    if (known.count(name) == 0) {
      throw UsageError("unknown option " + arg + " for " + argv[1]);
    }
    if (i + 1 >= argc) throw UsageError("option " + arg + " needs a value");
    if (!options.values.emplace(name, argv[i + 1]).second) {
      throw UsageError("option " + arg + " given twice");
    }
  }
  return options;
}

// ---------------------------------------------------------------------------------------------
// DDS entities.

// Fast DDS's default port mapping (7400 + 250 * domain + offsets) leaves room for domains 0..232.
constexpr int64_t kMaxDomain = 232;

// Owns the participant and, through delete_contained_entities, everything made from it.
class Participant {
 public:
  Participant(int domain, const std::string& interface) {
    dds::DomainParticipantQos qos;
    qos.name("sfrt_fastdds_peer");
    if (!interface.empty()) KeepOnInterface(qos, interface);
    participant_ = dds::DomainParticipantFactory::get_instance()->create_participant(domain, qos);
    if (participant_ == nullptr) {
      throw std::runtime_error("cannot create a participant on domain " + std::to_string(domain));
    }
  }

  ~Participant() {
    participant_->delete_contained_entities();
    dds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
  }

  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  // `type` owns its TopicDataType; the participant keeps a reference once it is registered.
  dds::Topic* MakeTopic(const std::string& name, dds::TypeSupport type) {
    if (type.register_type(participant_) != ReturnCode_t::RETCODE_OK) {
      throw std::runtime_error("cannot register type " + type.get_type_name());
    }
    dds::Topic* topic =
        participant_->create_topic(name, type.get_type_name(), dds::TOPIC_QOS_DEFAULT);
    if (topic == nullptr) throw std::runtime_error("cannot create topic " + name);
    return topic;
  }

  dds::DomainParticipant* get() { return participant_; }

 private:
  using ReturnCode_t = eprosima::fastrtps::types::ReturnCode_t;

  static void KeepOnInterface(dds::DomainParticipantQos& qos, const std::string& address) {
    eprosima::fastrtps::rtps::Locator_t peer;
    if (!eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, address) ||
        !eprosima::fastrtps::rtps::IPLocator::isIPv4(address)) {
      throw UsageError("--interface '" + address + "': expected an IPv4 address");
    }
    auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
    udp->interfaceWhiteList.push_back(address);
    qos.transport().use_builtin_transports = false;  // no shared memory
    qos.transport().user_transports.push_back(udp);
    // Unicast discovery to the ports of participant ids 0..maxInitialPeersRange on `address`,
    // where other participants on that interface listen (Cyclone: with a participant index).
    qos.wire_protocol().builtin.initialPeersList.push_back(peer);
  }

  dds::DomainParticipant* participant_ = nullptr;
};

// ROS 2's profiles: sensor_data (best effort, keep last 5) and default (reliable, keep last 10),
// both volatile.
template <typename EntityQos>
void ApplyRosProfile(EntityQos& qos, const std::string& reliability) {
  bool reliable = reliability == "reliable";
  qos.reliability().kind =
      reliable ? dds::RELIABLE_RELIABILITY_QOS : dds::BEST_EFFORT_RELIABILITY_QOS;
  qos.history().kind = dds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = reliable ? 10 : 5;
  qos.durability().kind = dds::VOLATILE_DURABILITY_QOS;
  // The messages are unbounded: payloads must be able to grow (as in rmw_fastrtps).
  qos.endpoint().history_memory_policy =
      eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
}

// ---------------------------------------------------------------------------------------------
// receive

std::string JsonString(const std::string& text) {
  std::string out = "\"";
  for (unsigned char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", c);
      out += escaped;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out + "\"";
}

std::string HeaderJson(const Header& m) {
  std::ostringstream json;
  int64_t stamp_ns = int64_t{m.stamp.sec} * 1000000000 + m.stamp.nanosec;
  json << "\"stamp\": {\"sec\": " << m.stamp.sec << ", \"nanosec\": " << m.stamp.nanosec
       << "}, \"stamp_ns\": " << stamp_ns << ", \"frame_id\": " << JsonString(m.frame_id);
  return json.str();
}

void WriteFile(const std::filesystem::path& path, const char* bytes, size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes, static_cast<std::streamsize>(size));
  out.close();
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

// The message's fields as JSON members; an image's data goes to `bin` (its size to the JSON).
std::string FieldsJson(const Header& m, const std::filesystem::path& /*bin*/) {
  return HeaderJson(m);
}

std::string FieldsJson(const Image& m, const std::filesystem::path& bin) {
  WriteFile(bin, reinterpret_cast<const char*>(m.data.data()), m.data.size());
  std::ostringstream json;
  json << HeaderJson(m.header) << ", \"height\": " << m.height << ", \"width\": " << m.width
       << ", \"encoding\": " << JsonString(m.encoding)
       << ", \"is_bigendian\": " << int{m.is_bigendian} << ", \"step\": " << m.step
       << ", \"data_size\": " << m.data.size();
  return json.str();
}

// DIR/<i>.json (fields, the encapsulation header in hex, the serialized size), DIR/<i>.cdr (the
// serialized sample as it came) and, for an image, DIR/<i>.bin (its data).
template <typename Msg>
void Save(const std::filesystem::path& dir, int index, const Sample<Msg>& sample) {
  const std::string name = std::to_string(index);
  WriteFile(dir / (name + ".cdr"), reinterpret_cast<const char*>(sample.wire.data()),
            sample.wire.size());
  char encapsulation[9] = "";
  for (size_t i = 0; i < 4 && i < sample.wire.size(); ++i) {
    std::snprintf(encapsulation + 2 * i, 3, "%02x", sample.wire[i]);
  }
  std::string json = "{" + FieldsJson(sample.msg, dir / (name + ".bin")) +
                     ", \"encapsulation\": \"" + encapsulation +
                     "\", \"cdr_size\": " + std::to_string(sample.wire.size()) + "}\n";
  WriteFile(dir / (name + ".json"), json.data(), json.size());
}

// Saves the first `wanted` valid samples; the main thread waits on Wait.
template <typename Msg>
class SavingListener : public dds::DataReaderListener {
 public:
  SavingListener(std::filesystem::path dir, int wanted) : dir_(std::move(dir)), wanted_(wanted) {}

  void on_data_available(dds::DataReader* reader) override {
    Sample<Msg> sample;
    dds::SampleInfo info;
    while (reader->take_next_sample(&sample, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;  // a dispose or unregister, not a message
      std::lock_guard<std::mutex> lock(mutex_);
      if (saved_ >= wanted_ || !error_.empty()) continue;
      try {
        Save(dir_, saved_, sample);
      } catch (const std::exception& e) {
        error_ = e.what();
      }
      ++saved_;
      std::cout << "fastdds_peer: received " << saved_ << "/" << wanted_ << std::endl;
      done_.notify_all();
    }
  }

  // Says on stdout when a writer matches (a test starts publishing once its readers are
  // matched: a best-effort sample sent before that is lost).
  void on_subscription_matched(dds::DataReader* /*reader*/,
                               const dds::SubscriptionMatchedStatus& status) override {
    if (status.current_count_change > 0) {
      std::cout << "fastdds_peer: matched " << status.current_count << " writer(s)" << std::endl;
    }
  }

  // How many were saved when all were, an error came, or `timeout` passed.
  int Wait(std::chrono::seconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait_for(lock, timeout, [this] { return saved_ >= wanted_ || !error_.empty(); });
    if (!error_.empty()) throw std::runtime_error(error_);
    return saved_;
  }

 private:
  using ReturnCode_t = eprosima::fastrtps::types::ReturnCode_t;

  const std::filesystem::path dir_;
  const int wanted_;
  std::mutex mutex_;
  std::condition_variable done_;
  int saved_ = 0;
  std::string error_;
};

template <typename Msg>
int ReceiveAs(Participant& participant, dds::TypeSupport type, const Options& options) {
  const std::string topic_name = options.Get("topic");
  const int count = static_cast<int>(options.Integer("count", 1, 1000000));
  const auto timeout = std::chrono::seconds(options.IntegerOr("timeout-s", 1, 86400, 20));
  const std::string reliability =
      options.Choice("reliability", {"best_effort", "reliable"}, "best_effort");
  const std::filesystem::path dir = options.Get("out");
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) throw UsageError("--out '" + dir.string() + "': " + error.message());

  // Declared before the reader is made, so it outlives the reader (deleted with the participant).
  SavingListener<Msg> listener(dir, count);
  dds::Topic* topic = participant.MakeTopic(topic_name, type);
  dds::Subscriber* subscriber =
      participant.get()->create_subscriber(dds::SUBSCRIBER_QOS_DEFAULT, nullptr);
  if (subscriber == nullptr) throw std::runtime_error("cannot create a subscriber");
  dds::DataReaderQos qos = dds::DATAREADER_QOS_DEFAULT;
  ApplyRosProfile(qos, reliability);
  dds::DataReader* reader = subscriber->create_datareader(topic, qos, &listener);
  if (reader == nullptr) throw std::runtime_error("cannot create a reader on " + topic_name);
  std::cout << "fastdds_peer: reading " << topic_name << " (" << type.get_type_name() << ", "
            << reliability << ")" << std::endl;

  int got = listener.Wait(timeout);
  participant.get()->delete_contained_entities();  // no more callbacks into `listener`
  if (got < count) {
    std::cerr << "fastdds_peer: timeout after " << timeout.count() << " s: received " << got
              << " of " << count << " messages on " << topic_name << "\n";
    return kExitTimeout;
  }
  return kExitOk;
}

int Receive(const Options& options) {
  const std::string type = options.Choice("type", {"image", "header"}, "");
  Participant participant(static_cast<int>(options.Integer("domain", 0, kMaxDomain)),
                          options.GetOr("interface", ""));
  if (type == "image") {
    return ReceiveAs<Image>(participant, dds::TypeSupport(new ImagePubSubType()), options);
  }
  return ReceiveAs<Header>(participant, dds::TypeSupport(new HeaderPubSubType()), options);
}

// ---------------------------------------------------------------------------------------------
// publish-image

std::vector<uint8_t> ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw UsageError("--data '" + path + "': cannot open it");
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

Image ImageFromOptions(const Options& options) {
  Image image;
  int64_t stamp_ns = options.Integer("stamp-ns", 0, int64_t{INT32_MAX} * 1000000000 + 999999999);
  image.header.stamp.sec = static_cast<int32_t>(stamp_ns / 1000000000);
  image.header.stamp.nanosec = static_cast<uint32_t>(stamp_ns % 1000000000);
  image.header.frame_id = options.Get("frame-id");
  image.height = static_cast<uint32_t>(options.Integer("height", 0, UINT32_MAX));
  image.width = static_cast<uint32_t>(options.Integer("width", 0, UINT32_MAX));
  image.encoding = options.Get("encoding");
  image.is_bigendian = static_cast<uint8_t>(options.IntegerOr("is-bigendian", 0, 1, 0));
  image.data = ReadFileBytes(options.Get("data"));
  if (options.Has("step")) {
    image.step = static_cast<uint32_t>(options.Integer("step", 0, UINT32_MAX));
  } else if (image.height == 0 || image.data.size() % image.height != 0) {
    throw UsageError("--data '" + options.Get("data") + "' has " +
                     std::to_string(image.data.size()) + " bytes, not a multiple of --height " +
                     std::to_string(image.height) + ": give --step");
  } else {
    image.step = static_cast<uint32_t>(image.data.size() / image.height);
  }
  return image;
}

bool WaitForReader(dds::DataWriter* writer, std::chrono::seconds timeout) {
  auto deadline = std::chrono::steady_clock::now() + timeout;
  dds::PublicationMatchedStatus status;
  while (std::chrono::steady_clock::now() < deadline) {
    writer->get_publication_matched_status(status);
    if (status.current_count > 0) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

int PublishImage(const Options& options) {
  using ReturnCode_t = eprosima::fastrtps::types::ReturnCode_t;
  const std::string topic_name = options.Get("topic");
  const std::string reliability =
      options.Choice("reliability", {"best_effort", "reliable"}, "reliable");
  const auto match_timeout =
      std::chrono::seconds(options.IntegerOr("match-timeout-s", 1, 3600, 10));
  const auto settle = std::chrono::milliseconds(options.IntegerOr("settle-ms", 0, 60000, 1000));
  Sample<Image> sample{ImageFromOptions(options), {}};
  Participant participant(static_cast<int>(options.Integer("domain", 0, kMaxDomain)),
                          options.GetOr("interface", ""));

  dds::Topic* topic = participant.MakeTopic(topic_name, dds::TypeSupport(new ImagePubSubType()));
  dds::Publisher* publisher =
      participant.get()->create_publisher(dds::PUBLISHER_QOS_DEFAULT, nullptr);
  if (publisher == nullptr) throw std::runtime_error("cannot create a publisher");
  dds::DataWriterQos qos = dds::DATAWRITER_QOS_DEFAULT;
  ApplyRosProfile(qos, reliability);
  // Fast DDS piggybacks a heartbeat on large writes only; a small sample's reader acknowledges
  // at the next periodic heartbeat, 3 s by default. 100 ms makes the wait for it short (timing
  // only: the protocol is the same).
  qos.reliable_writer_qos().times.heartbeatPeriod = eprosima::fastrtps::Duration_t(0, 100000000);
  dds::DataWriter* writer = publisher->create_datawriter(topic, qos, nullptr);
  if (writer == nullptr) throw std::runtime_error("cannot create a writer on " + topic_name);

  if (!WaitForReader(writer, match_timeout)) {
    std::cerr << "fastdds_peer: timeout after " << match_timeout.count()
              << " s: no reader matched on " << topic_name << " (" << reliability << ")\n";
    return kExitTimeout;
  }
  // Our writer matching the reader does not mean the reader has matched our writer yet. A
  // sample that reaches a best-effort reader before then is dropped for good, whichever kind
  // this writer is (a reliable reader would have it resent); DDS lets the writer see no sign of
  // it, so wait a while.
  std::this_thread::sleep_for(settle);
  // --repeat: the same sample again every 200 ms, for a best-effort reader that may match this
  // writer only later (its reader takes the first one that arrives).
  const int64_t repeat = options.IntegerOr("repeat", 1, 1000, 1);
  for (int64_t i = 0; i < repeat; ++i) {
    if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(200));
    if (!writer->write(&sample)) throw std::runtime_error("write on " + topic_name + " failed");
  }
  if (reliability == "reliable" && writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(
                                       10, 0)) != ReturnCode_t::RETCODE_OK) {
    std::cerr << "fastdds_peer: timeout after 10 s: the image on " << topic_name
              << " was not acknowledged\n";
    return kExitTimeout;
  }
  std::cout << "fastdds_peer: published " << sample.msg.data.size() << " data bytes on "
            << topic_name << " (" << reliability << ")" << std::endl;
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  std::string command = argc > 1 ? argv[1] : "";
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h") {
      std::cout << kUsage;
      return kExitOk;
    }
  }
  try {
    if (command == "receive") {
      return Receive(ParseOptions(
          argc, argv,
          {"domain", "topic", "type", "count", "out", "reliability", "timeout-s", "interface"}));
    }
    if (command == "publish-image") {
      return PublishImage(ParseOptions(
          argc, argv,
          {"domain", "topic", "height", "width", "encoding", "data", "stamp-ns", "frame-id", "step",
           "is-bigendian", "reliability", "match-timeout-s", "settle-ms", "repeat", "interface"}));
    }
    throw UsageError(command.empty() ? "no subcommand" : "unknown subcommand '" + command + "'");
  } catch (const UsageError& e) {
    std::cerr << "fastdds_peer: " << e.what() << " (see fastdds_peer --help)\n";
    return kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "fastdds_peer: " << e.what() << "\n";
    return kExitDdsFailed;
  }
}
