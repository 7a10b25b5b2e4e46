// cyclone_peer: a ROS 2 stand-in made of nothing but Cyclone DDS and its own IDL
// (peer_idl/ros2_image.idl, compiled by idlc into C types): no sfrt code, so the tests of sfrt's
// DDS adapter and node check sfrt against an independent party on the real (loopback) network.
// It writes and reads C structs with dds_write/dds_take; Cyclone serialises them as plain CDR
// (XCDR1), as rmw_cyclonedds does.
//
//   cyclone_peer publish-stereo --domain D --left-topic rt/left/image_rect
//       --right-topic rt/right/image_rect --frames DIR [--reliability reliable|best-effort]
//       [--depth N] [--rate-hz R] [--wait-subscribers N] [--wait-ms T] [--linger-ms T]
//       [--left-frame-id S] [--right-frame-id S] [--transport raw|compressed] [--format S]
//       [--stamp index|now] [--loops N]
//       [--left-info-topic T --right-info-topic T --focal-px F --baseline-m B]
//     Publishes the pairs listed in DIR/index.txt, left then right with the same stamp, at R
//     pairs a second (default 30), once each writer has N matched readers (default 1; waits up
//     to T ms, default 10000). Index lines (blank lines and lines starting with '#' skipped):
//     "sec nanosec height width left right", file names relative to DIR. Transport raw (the
//     default): sensor_msgs/msg/Image bgr8, each file height * width * 3 bytes of B, G, R rows;
//     compressed: sensor_msgs/msg/CompressedImage, each file's bytes as they are (a PNG or JPEG
//     file) with format S (default "bgr8; png compressed bgr8", as compressed_image_transport
//     writes it). --stamp now stamps each pair with the wall clock as it goes out (a live camera;
//     for latency measurements) instead of the index's stamp; --loops N goes over the index N
//     times (default 1). With the info topics, one sensor_msgs/msg/CameraInfo per side goes out
//     before the first pair (the index's first size, focal length F px, principal point at the
//     centre, the right one's P[3] = -F * B as a rectified stereo pair has it). Reliable writers
//     then wait for acknowledgements; the peer lingers (default 500 ms) before leaving.
//
//   cyclone_peer receive --domain D --topic rt/flow --count N --out DIR [--type image|header]
//       [--reliability reliable|best-effort] [--depth N] [--timeout-ms T]
//     Takes N messages (default type image: sensor_msgs/msg/Image; header: std_msgs/msg/Header)
//     and writes each as DIR/<type>_<i>.txt ("key value" lines: sec, nanosec, frame_id, and for
//     images height, width, encoding, is_bigendian, step, data_size) plus, for images,
//     DIR/image_<i>.data (the data bytes); i counts from 000000. Fails after T ms (default 30000).
//     Prints "matched N writer(s)" once its reader has matched a writer.
//
// QoS: keep last N (default 10), the given reliability (default reliable: rmw's default
// profile), volatile, data representation XCDR1. Exit status: 0 done, 1 failure (message on
// stderr), 2 usage error.
#include <dds/dds.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ros2_image.h"

namespace {

constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

// A failure that ends the program with its message and exit status.
struct Failure {
  int exit_code;
  std::string message;
};

[[noreturn]] void Fail(const std::string& message) { throw Failure{kExitFailure, message}; }
[[noreturn]] void Usage(const std::string& message) { throw Failure{kExitUsage, message}; }

void Check(dds_return_t rc, const std::string& what) {
  if (rc < 0) Fail(what + ": " + dds_strretcode(rc));
}

// --name value pairs after the command word.
class Flags {
 public:
  Flags(int argc, char** argv) {
    for (int i = 2; i < argc; i += 2) {
      const std::string name = argv[i];
      if (name.rfind("--", 0) != 0 || i + 1 >= argc) Usage("expected --flag value at " + name);
      values_[name.substr(2)] = argv[i + 1];
    }
  }
  bool Has(const std::string& name) const { return values_.count(name) != 0; }
  std::string Get(const std::string& name, const std::string& fallback = "") {
    used_.push_back(name);
    auto it = values_.find(name);
    if (it != values_.end()) return it->second;
    if (fallback.empty()) Usage("missing --" + name);
    return fallback;
  }
  long Number(const std::string& name, const std::string& fallback = "") {
    const std::string text = Get(name, fallback);
    char* end = nullptr;
    const long value = std::strtol(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0' || value < 0)
      Usage("--" + name + " " + text + ": not a number");
    return value;
  }
  double Real(const std::string& name) {
    const std::string text = Get(name);
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    if (text.empty() || *end != '\0') Usage("--" + name + " " + text + ": not a number");
    return value;
  }
  // Refuses flags that no Get asked for (typos would otherwise pass silently).
  void CheckAllUsed() const {
    for (const auto& [name, value] : values_) {
      bool used = false;
      for (const auto& u : used_) used = used || u == name;
      if (!used) Usage("unknown flag --" + name);
    }
  }

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> used_;
};

struct Endpoints {
  dds_entity_t participant = 0;
  ~Endpoints() {
    if (participant > 0) dds_delete(participant);
  }
};

dds_qos_t* NewQos(Flags& flags) {
  const std::string reliability = flags.Get("reliability", "reliable");
  if (reliability != "reliable" && reliability != "best-effort") {
    Usage("--reliability " + reliability + ": reliable or best-effort");
  }
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(
      qos, reliability == "reliable" ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
      DDS_SECS(1));
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, static_cast<int32_t>(flags.Number("depth", "10")));
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  return qos;
}

dds_entity_t NewEndpoint(dds_entity_t participant, const dds_topic_descriptor_t* type,
                         const std::string& topic_name, const dds_qos_t* qos, bool writer) {
  const dds_entity_t topic =
      dds_create_topic(participant, type, topic_name.c_str(), nullptr, nullptr);
  Check(topic, "topic " + topic_name);
  const dds_entity_t entity = writer ? dds_create_writer(participant, topic, qos, nullptr)
                                     : dds_create_reader(participant, topic, qos, nullptr);
  Check(entity, (writer ? "writer of " : "reader of ") + topic_name);
  return entity;
}

// ---------------------------------------------------------------------------------------------
// publish-stereo

struct Frame {
  int32_t sec;
  uint32_t nanosec;
  uint32_t height;
  uint32_t width;
  std::vector<uint8_t> left;
  std::vector<uint8_t> right;
};

// The file's bytes; `expected` of them unless it is 0 (a compressed image: any size).
std::vector<uint8_t> ReadPixels(const std::string& path, size_t expected) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(path + ": cannot open");
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
  if (expected != 0 && bytes.size() != expected) {
    Fail(path + ": " + std::to_string(bytes.size()) + " bytes, expected " +
         std::to_string(expected) + " (height * width * 3)");
  }
  return bytes;
}

std::vector<Frame> ReadFrames(const std::string& dir, bool compressed) {
  const std::string index = dir + "/index.txt";
  std::ifstream in(index);
  if (!in) Fail(index + ": cannot open");
  std::vector<Frame> frames;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    Frame frame{};
    std::string left, right;
    if (!(fields >> frame.sec >> frame.nanosec >> frame.height >> frame.width >> left >> right)) {
      Fail(index + ":" + std::to_string(number) +
           ": expected \"sec nanosec height width left right\"");
    }
    const size_t size = compressed ? 0 : size_t{frame.height} * frame.width * 3;
    frame.left = ReadPixels(dir + "/" + left, size);
    frame.right = ReadPixels(dir + "/" + right, size);
    frames.push_back(std::move(frame));
  }
  if (frames.empty()) Fail(index + ": no frames");
  return frames;
}

void WaitForReaders(dds_entity_t writer, long wanted, long wait_ms, const std::string& topic) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(wait_ms);
  for (;;) {
    dds_publication_matched_status_t status{};
    Check(dds_get_publication_matched_status(writer, &status), "matched status of " + topic);
    if (static_cast<long>(status.current_count) >= wanted) return;
    if (std::chrono::steady_clock::now() > deadline) {
      Fail(topic + ": " + std::to_string(status.current_count) + " of " + std::to_string(wanted) +
           " readers matched after " + std::to_string(wait_ms) + " ms");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

// The frame's stamp and `frame_id` (which must outlive the message) as a std_msgs Header.
std_msgs_msg_dds__Header_ HeaderOf(const Frame& frame, const std::string& frame_id) {
  std_msgs_msg_dds__Header_ header{};
  header.stamp_.sec_ = frame.sec;
  header.stamp_.nanosec_ = frame.nanosec;
  header.frame_id_ = const_cast<char*>(frame_id.c_str());
  return header;
}

void WriteImage(dds_entity_t writer, const Frame& frame, const std::string& frame_id,
                const std::vector<uint8_t>& pixels) {
  sensor_msgs_msg_dds__Image_ image{};
  image.header_ = HeaderOf(frame, frame_id);
  image.height_ = frame.height;
  image.width_ = frame.width;
  image.encoding_ = const_cast<char*>("bgr8");
  image.is_bigendian_ = 0;
  image.step_ = frame.width * 3;
  image.data_._length = image.data_._maximum = static_cast<uint32_t>(pixels.size());
  image.data_._buffer = const_cast<uint8_t*>(pixels.data());
  image.data_._release = false;
  Check(dds_write(writer, &image), "write");
}

void WriteCompressed(dds_entity_t writer, const Frame& frame, const std::string& frame_id,
                     const std::string& format, const std::vector<uint8_t>& bytes) {
  sensor_msgs_msg_dds__CompressedImage_ image{};
  image.header_ = HeaderOf(frame, frame_id);
  image.format_ = const_cast<char*>(format.c_str());
  image.data_._length = image.data_._maximum = static_cast<uint32_t>(bytes.size());
  image.data_._buffer = const_cast<uint8_t*>(bytes.data());
  image.data_._release = false;
  Check(dds_write(writer, &image), "write");
}

// A rectified camera of a stereo pair: no distortion, identity R, P = K [I | t] with
// P[3] = tx = -focal * baseline for the right camera (0 for the left).
void WriteCameraInfo(dds_entity_t writer, const Frame& frame, const std::string& frame_id,
                     double focal_px, double tx) {
  sensor_msgs_msg_dds__CameraInfo_ info{};
  info.header_ = HeaderOf(frame, frame_id);
  info.height_ = frame.height;
  info.width_ = frame.width;
  info.distortion_model_ = const_cast<char*>("plumb_bob");
  const double cx = frame.width / 2.0, cy = frame.height / 2.0;
  const double k[9] = {focal_px, 0, cx, 0, focal_px, cy, 0, 0, 1};
  const double p[12] = {focal_px, 0, cx, tx, 0, focal_px, cy, 0, 0, 0, 1, 0};
  for (int i = 0; i < 9; ++i) info.k_[i] = k[i];
  for (int i = 0; i < 9; ++i) info.r_[i] = i % 4 == 0 ? 1.0 : 0.0;
  for (int i = 0; i < 12; ++i) info.p_[i] = p[i];
  Check(dds_write(writer, &info), "write camera_info");
}

Frame StampedNow(const Frame& frame) {
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
  Frame stamped{};
  stamped.sec = static_cast<int32_t>(ns / 1000000000);
  stamped.nanosec = static_cast<uint32_t>(ns % 1000000000);
  stamped.height = frame.height;
  stamped.width = frame.width;
  return stamped;
}

int PublishStereo(Flags& flags) {
  const auto domain = static_cast<dds_domainid_t>(flags.Number("domain"));
  const std::string left_topic = flags.Get("left-topic");
  const std::string right_topic = flags.Get("right-topic");
  const std::string transport = flags.Get("transport", "raw");
  if (transport != "raw" && transport != "compressed") {
    Usage("--transport " + transport + ": raw or compressed");
  }
  const bool compressed = transport == "compressed";
  const std::vector<Frame> frames = ReadFrames(flags.Get("frames"), compressed);
  const std::string format = flags.Get("format", "bgr8; png compressed bgr8");
  const long rate_hz = flags.Number("rate-hz", "30");
  const long wanted = flags.Number("wait-subscribers", "1");
  const long wait_ms = flags.Number("wait-ms", "10000");
  const long linger_ms = flags.Number("linger-ms", "500");
  const long loops = flags.Number("loops", "1");
  const std::string stamp = flags.Get("stamp", "index");
  if (stamp != "index" && stamp != "now") Usage("--stamp " + stamp + ": index or now");
  const std::string left_id = flags.Get("left-frame-id", "left_camera");
  const std::string right_id = flags.Get("right-frame-id", "right_camera");
  const bool with_info = flags.Has("left-info-topic");
  const std::string info_topics[2] = {with_info ? flags.Get("left-info-topic") : "",
                                      with_info ? flags.Get("right-info-topic") : ""};
  const double focal_px = with_info ? flags.Real("focal-px") : 0;
  const double baseline_m = with_info ? flags.Real("baseline-m") : 0;
  dds_qos_t* qos = NewQos(flags);
  flags.CheckAllUsed();

  Endpoints endpoints;
  endpoints.participant = dds_create_participant(domain, nullptr, nullptr);
  Check(endpoints.participant, "participant in domain " + std::to_string(domain));
  const auto* type =
      compressed ? &sensor_msgs_msg_dds__CompressedImage__desc : &sensor_msgs_msg_dds__Image__desc;
  const dds_entity_t left = NewEndpoint(endpoints.participant, type, left_topic, qos, true);
  const dds_entity_t right = NewEndpoint(endpoints.participant, type, right_topic, qos, true);
  dds_entity_t info[2] = {0, 0};
  for (int side = 0; with_info && side < 2; ++side) {
    info[side] = NewEndpoint(endpoints.participant, &sensor_msgs_msg_dds__CameraInfo__desc,
                             info_topics[side], qos, true);
  }
  dds_delete_qos(qos);
  WaitForReaders(left, wanted, wait_ms, left_topic);
  WaitForReaders(right, wanted, wait_ms, right_topic);
  if (with_info) {
    for (int side = 0; side < 2; ++side) {
      WaitForReaders(info[side], wanted, wait_ms, info_topics[side]);
    }
    WriteCameraInfo(info[0], frames.front(), left_id, focal_px, 0.0);
    WriteCameraInfo(info[1], frames.front(), right_id, focal_px, -focal_px * baseline_m);
  }

  const auto period = std::chrono::microseconds(1000000 / (rate_hz > 0 ? rate_hz : 1));
  auto next = std::chrono::steady_clock::now();
  for (long loop = 0; loop < loops; ++loop) {
    for (const Frame& frame : frames) {
      std::this_thread::sleep_until(next);
      const Frame now = stamp == "now" ? StampedNow(frame) : Frame{};
      const Frame& stamped = stamp == "now" ? now : frame;
      if (compressed) {
        WriteCompressed(left, stamped, left_id, format, frame.left);
        WriteCompressed(right, stamped, right_id, format, frame.right);
      } else {
        WriteImage(left, stamped, left_id, frame.left);
        WriteImage(right, stamped, right_id, frame.right);
      }
      next += period;
    }
  }
  // Best-effort writers answer "unsupported" here; reliable ones wait for every reader.
  for (dds_entity_t writer : {left, right, info[0], info[1]}) {
    if (writer > 0) dds_wait_for_acks(writer, DDS_SECS(5));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(linger_ms));
  std::printf("published %zu stereo pairs\n", frames.size() * static_cast<size_t>(loops));
  return 0;
}

// ---------------------------------------------------------------------------------------------
// receive

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  if (!out) Fail(path + ": cannot write");
}

std::string StampLines(const std_msgs_msg_dds__Header_& header) {
  return "sec " + std::to_string(header.stamp_.sec_) + "\nnanosec " +
         std::to_string(header.stamp_.nanosec_) + "\nframe_id " + header.frame_id_ + "\n";
}

void SaveImage(const sensor_msgs_msg_dds__Image_& image, const std::string& base) {
  std::ostringstream text;
  text << StampLines(image.header_) << "height " << image.height_ << "\nwidth " << image.width_
       << "\nencoding " << image.encoding_ << "\nis_bigendian " << int{image.is_bigendian_}
       << "\nstep " << image.step_ << "\ndata_size " << image.data_._length << "\n";
  WriteText(base + ".txt", text.str());
  std::ofstream data(base + ".data", std::ios::binary);
  data.write(reinterpret_cast<const char*>(image.data_._buffer), image.data_._length);
  if (!data) Fail(base + ".data: cannot write");
}

// Takes what the reader holds, saving each valid sample; returns how many were saved.
long TakeAndSave(dds_entity_t reader, bool images, const std::string& out, long saved, long count) {
  void* samples[1] = {nullptr};
  dds_sample_info_t info{};
  while (saved < count) {
    const dds_return_t n = dds_take(reader, samples, &info, 1, 1);
    Check(n, "take");
    if (n == 0) break;
    if (info.valid_data) {
      char name[32];
      std::snprintf(name, sizeof(name), "/%s_%06ld", images ? "image" : "header", saved);
      if (images) {
        SaveImage(*static_cast<const sensor_msgs_msg_dds__Image_*>(samples[0]), out + name);
      } else {
        WriteText(out + name + ".txt",
                  StampLines(*static_cast<const std_msgs_msg_dds__Header_*>(samples[0])));
      }
      ++saved;
    }
    dds_return_loan(reader, samples, n);
  }
  return saved;
}

int Receive(Flags& flags) {
  const auto domain = static_cast<dds_domainid_t>(flags.Number("domain"));
  const std::string topic = flags.Get("topic");
  const long count = flags.Number("count");
  const std::string out = flags.Get("out");
  const std::string type = flags.Get("type", "image");
  const long timeout_ms = flags.Number("timeout-ms", "30000");
  if (type != "image" && type != "header") Usage("--type " + type + ": image or header");
  dds_qos_t* qos = NewQos(flags);
  flags.CheckAllUsed();

  Endpoints endpoints;
  endpoints.participant = dds_create_participant(domain, nullptr, nullptr);
  Check(endpoints.participant, "participant in domain " + std::to_string(domain));
  const bool images = type == "image";
  const dds_entity_t reader =
      NewEndpoint(endpoints.participant,
                  images ? &sensor_msgs_msg_dds__Image__desc : &std_msgs_msg_dds__Header__desc,
                  topic, qos, false);
  dds_delete_qos(qos);
  const dds_entity_t waitset = dds_create_waitset(endpoints.participant);
  Check(dds_set_status_mask(reader, DDS_DATA_AVAILABLE_STATUS | DDS_SUBSCRIPTION_MATCHED_STATUS),
        "status mask");
  Check(dds_waitset_attach(waitset, reader, reader), "waitset");
  const dds_time_t deadline = dds_time() + DDS_MSECS(timeout_ms);
  long saved = 0;
  bool matched = false;
  while (saved < count) {
    // Said once on stdout: a test starts publishing once its readers are matched (a best-effort
    // sample sent before that is lost).
    dds_subscription_matched_status_t status;
    if (!matched && dds_get_subscription_matched_status(reader, &status) == DDS_RETCODE_OK &&
        status.current_count > 0) {
      std::printf("matched %u writer(s)\n", status.current_count);
      std::fflush(stdout);
      matched = true;
    }
    saved = TakeAndSave(reader, images, out, saved, count);
    if (saved >= count) break;
    if (dds_time() > deadline) {
      Fail(topic + ": received " + std::to_string(saved) + " of " + std::to_string(count) +
           " messages in " + std::to_string(timeout_ms) + " ms");
    }
    dds_waitset_wait_until(waitset, nullptr, 0, deadline);
  }
  std::printf("received %ld messages\n", saved);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string command = argc > 1 ? argv[1] : "";
    Flags flags(argc, argv);
    if (command == "publish-stereo") return PublishStereo(flags);
    if (command == "receive") return Receive(flags);
    Usage("usage: cyclone_peer publish-stereo|receive --domain D ... (see the source's header)");
  } catch (const Failure& failure) {
    std::fprintf(stderr, "cyclone_peer: %s\n", failure.message.c_str());
    return failure.exit_code;
  }
}
