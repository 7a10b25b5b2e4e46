#include "node_io.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <span>

namespace sfrt::ros2 {
namespace {

std::atomic<bool> g_stop_requested{false};

const char* TypeName(ParamValue::Type t) {
  switch (t) {
    case ParamValue::Type::kString:
      return "a string";
    case ParamValue::Type::kInteger:
      return "an integer";
    case ParamValue::Type::kDouble:
      return "a double";
    case ParamValue::Type::kBool:
      return "a bool";
  }
  return "a value";
}

std::string WrongType(const std::string& name, const ParamValue& v, const char* wanted) {
  return "parameter '" + name + "' is " + TypeName(v.type) + " ('" + v.text + "', from " +
         v.origin + "); it takes " + wanted;
}

msg::Time TimeOf(int64_t ns) {
  msg::Time t;
  t.sec = static_cast<int32_t>(ns / 1'000'000'000);
  t.nanosec = static_cast<uint32_t>(ns % 1'000'000'000);
  return t;
}

int64_t NsOf(const msg::Time& t) {
  return static_cast<int64_t>(t.sec) * 1'000'000'000 + static_cast<int64_t>(t.nanosec);
}

}  // namespace

Ros2NodeIo::Ros2NodeIo(RosArgs args, uint32_t domain_id)
    : args_(std::move(args)), domain_id_(domain_id) {}

Ros2NodeIo::~Ros2NodeIo() = default;

void Ros2NodeIo::RequestStop() { g_stop_requested = true; }

bool Ros2NodeIo::HasParam(const std::string& name) const {
  asked_.insert(name);
  return args_.params.count(name) != 0;
}

std::string Ros2NodeIo::GetParam(const std::string& name, std::string* value) const {
  if (!HasParam(name)) return "";
  const ParamValue& v = args_.params.at(name);
  if (v.type != ParamValue::Type::kString) return WrongType(name, v, "a string");
  *value = v.text;
  return "";
}

std::string Ros2NodeIo::GetParam(const std::string& name, double* value) const {
  if (!HasParam(name)) return "";
  const ParamValue& v = args_.params.at(name);
  if (v.type == ParamValue::Type::kInteger) {
    *value = static_cast<double>(v.integer);
    return "";
  }
  if (v.type != ParamValue::Type::kDouble) return WrongType(name, v, "a number");
  if (!std::isfinite(v.real)) {
    return "parameter '" + name + "' is '" + v.text + "' (from " + v.origin +
           "): not a finite number";
  }
  *value = v.real;
  return "";
}

std::string Ros2NodeIo::GetParam(const std::string& name, int* value) const {
  if (!HasParam(name)) return "";
  const ParamValue& v = args_.params.at(name);
  if (v.type != ParamValue::Type::kInteger) return WrongType(name, v, "an integer");
  if (v.integer < std::numeric_limits<int>::min() || v.integer > std::numeric_limits<int>::max()) {
    return "parameter '" + name + "' is " + v.text + " (from " + v.origin + "): out of range";
  }
  *value = static_cast<int>(v.integer);
  return "";
}

std::string Ros2NodeIo::GetParam(const std::string& name, bool* value) const {
  if (!HasParam(name)) return "";
  const ParamValue& v = args_.params.at(name);
  if (v.type != ParamValue::Type::kBool) return WrongType(name, v, "a bool (true or false)");
  *value = v.boolean;
  return "";
}

std::string Ros2NodeIo::Resolve(const std::string& topic) const {
  Result<std::string> resolved = ResolveTopic(args_, topic);
  return resolved.ok() ? *resolved : topic;
}

std::string Ros2NodeIo::ReadQosParams() {
  dds::Qos* qos = &qos_;
  std::string profile = "sensor_data", reliability;
  int depth = 0;
  if (std::string e = GetParam("qos", &profile); !e.empty()) return e;
  if (std::string e = GetParam("reliability", &reliability); !e.empty()) return e;
  if (std::string e = GetParam("depth", &depth); !e.empty()) return e;
  if (profile == "sensor_data") {
    *qos = dds::Qos::SensorData();
  } else if (profile == "default") {
    *qos = dds::Qos::Default();
  } else {
    return "parameter 'qos' is '" + profile + "': it takes sensor_data or default";
  }
  if (reliability == "best_effort") {
    qos->reliability = dds::Qos::Reliability::kBestEffort;
  } else if (reliability == "reliable") {
    qos->reliability = dds::Qos::Reliability::kReliable;
  } else if (!reliability.empty()) {
    return "parameter 'reliability' is '" + reliability + "': it takes best_effort or reliable";
  }
  if (HasParam("depth")) {
    if (depth < 1 || depth > 1000) {
      return "parameter 'depth' is " + std::to_string(depth) + ": it takes 1..1000";
    }
    qos->depth = static_cast<uint32_t>(depth);
  }
  return "";
}

void Ros2NodeIo::ReportUnusedParams() {
  for (const auto& [name, value] : args_.params) {
    if (asked_.count(name) == 0) {
      Log(pipeline::NodeLogLevel::kWarn, "parameter '" + name + "' (from " + value.origin +
                                             ") is not one sfrt_ros2 takes; ignored (--help "
                                             "lists them)");
    }
  }
}

// The participant, made once every parameter has been read: a bad one never creates an entity.
std::string Ros2NodeIo::EnsureParticipant() {
  if (participant_) return "";
  ReportUnusedParams();
  Result<std::unique_ptr<dds::Participant>> p =
      dds::Participant::Create(domain_id_, args_.node_name, args_.node_namespace);
  if (!p.ok()) return p.message();
  participant_ = std::move(p).value();
  participant_->OnProblem(
      [this](const std::string& text) { Log(pipeline::NodeLogLevel::kWarn, text); });
  return "";
}

void Ros2NodeIo::OnImage(int side, const pipeline::ImageMessage& image,
                         const std::string& frame_id) {
  ++received_[side];
  // Under the lock, so that once Shutdown() has cleared spinning_ no callback is still inside
  // the node's source (which RunNode destroys when it returns).
  std::lock_guard<std::mutex> lock(pair_mutex_);
  if (!spinning_.load()) return;
  pairer_->Add(side, image, frame_id);
}

std::string Ros2NodeIo::Subscribe(const pipeline::NodeSubscription& options, PairCallback on_pair,
                                  InfoCallback on_info) {
  if (std::string e = EnsureParticipant(); !e.empty()) return e;
  on_pair_ = std::move(on_pair);
  pairer_.emplace(static_cast<int64_t>(options.slop_s * 1e9),
                  static_cast<int64_t>(options.frame_interval_s * 1e9),
                  static_cast<size_t>(options.queue_size), on_pair_);
  const std::string topics[2] = {Resolve(options.left_topic), Resolve(options.right_topic)};
  for (int side = 0; side < 2; ++side) {
    Status s = Status::Ok();
    if (options.transport == "compressed") {
      s = participant_->SubscribeCompressedImage(topics[side] + "/compressed", qos_,
                                                 [this, side](const msg::CompressedImage& m) {
                                                   pipeline::ImageMessage im;
                                                   im.stamp_ns = NsOf(m.header.stamp);
                                                   im.compressed = true;
                                                   im.encoding = m.format;
                                                   im.data = m.data.data();
                                                   im.size = m.data.size();
                                                   OnImage(side, im, m.header.frame_id);
                                                 });
    } else if (options.transport == "raw") {
      s = participant_->SubscribeImage(topics[side], qos_, [this, side](const msg::ImageView& m) {
        pipeline::ImageMessage im;
        im.stamp_ns = NsOf(m.header.stamp);
        im.encoding.assign(m.encoding);
        im.height = m.height;
        im.width = m.width;
        im.step = m.step;
        im.data = m.data.data();
        im.size = m.data.size();
        OnImage(side, im, std::string(m.header.frame_id));
      });
    } else {
      return "parameter 'transport' is '" + options.transport + "': it takes raw or compressed";
    }
    if (!s.ok()) return s.message();
    if (!options.camera_info) continue;
    const std::string info = topics[side].substr(0, topics[side].rfind('/')) + "/camera_info";
    s = participant_->SubscribeCameraInfo(
        info, qos_, [this, on_info, side](const msg::CameraInfo& m) {
          std::lock_guard<std::mutex> lock(pair_mutex_);  // as OnImage: nothing after Shutdown()
          if (!spinning_.load()) return;
          pipeline::CameraInfoView v;
          v.width = m.width;
          v.height = m.height;
          for (int i = 0; i < 12; ++i) v.p[i] = m.p[static_cast<size_t>(i)];
          v.frame_id = m.header.frame_id;
          on_info(side, v);
        });
    if (!s.ok()) return s.message();
  }
  return "";
}

std::string Ros2NodeIo::Advertise(const std::string& flow, const std::string& t1,
                                  const std::string& vis, bool with_vis) {
  if (std::string e = EnsureParticipant(); !e.empty()) return e;
  flow_topic_ = flow;
  t1_topic_ = t1;
  vis_topic_ = vis;
  Result<int> f = participant_->AdvertiseImage(flow, qos_);
  if (!f.ok()) return f.message();
  Result<int> h = participant_->AdvertiseHeader(t1, qos_);
  if (!h.ok()) return h.message();
  if (with_vis) {
    Result<int> v = participant_->AdvertiseImage(vis, qos_);
    if (!v.ok()) return v.message();
    vis_ = *v;
  }
  Result<int> d = participant_->AdvertiseDiagnosticArray("/diagnostics", dds::Qos::Default());
  if (!d.ok()) return d.message();
  flow_ = *f;
  t1_ = *h;
  diagnostics_ = *d;
  if (Status s = participant_->AnnounceNode(); !s.ok()) return s.message();
  return "";
}

int Ros2NodeIo::PublisherOf(const std::string& topic) const {
  if (topic == flow_topic_) return flow_;
  if (topic == vis_topic_) return vis_;
  if (topic == t1_topic_) return t1_;
  return -1;
}

std::string Ros2NodeIo::WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t /*seq*/,
                                   const std::string& frame_id, const std::string& encoding,
                                   uint32_t height, uint32_t width, uint32_t step,
                                   const uint8_t* data) {
  const int publisher = PublisherOf(topic);
  if (publisher < 0) return "no publisher of '" + topic + "'";
  msg::ImageView image;
  image.header.stamp = TimeOf(stamp_ns);
  image.header.frame_id = frame_id;
  image.height = height;
  image.width = width;
  image.encoding = encoding;
  image.step = step;
  image.data = std::span<const uint8_t>(data, static_cast<size_t>(step) * height);
  Status s = participant_->Publish(publisher, image);
  return s.ok() ? "" : s.message();
}

std::string Ros2NodeIo::WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t /*seq*/,
                                    const std::string& frame_id) {
  const int publisher = PublisherOf(topic);
  if (publisher < 0) return "no publisher of '" + topic + "'";
  msg::Header header;
  header.stamp = TimeOf(stamp_ns);
  header.frame_id = frame_id;
  Status s = participant_->Publish(publisher, header);
  return s.ok() ? "" : s.message();
}

void Ros2NodeIo::PublishDiagnostics(const std::vector<pipeline::DiagnosticReport>& reports) {
  if (diagnostics_ < 0) return;
  msg::DiagnosticArray array;
  array.header.stamp = TimeOf(NowNs());
  for (const pipeline::DiagnosticReport& r : reports) {
    msg::DiagnosticStatus st;
    st.level = static_cast<uint8_t>(r.level);
    st.name = r.name;
    st.message = r.message;
    st.hardware_id = r.hardware_id;
    for (const auto& [key, value] : r.values) st.values.push_back({key, value});
    array.status.push_back(std::move(st));
  }
  if (Status s = participant_->Publish(diagnostics_, array); !s.ok()) {
    Log(pipeline::NodeLogLevel::kWarn, "/diagnostics: " + s.message());
  }
}

bool Ros2NodeIo::Ok() const { return !shut_down_.load() && !g_stop_requested.load(); }

int64_t Ros2NodeIo::NowNs() const {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

void Ros2NodeIo::Shutdown() {
  shut_down_ = true;
  {
    std::lock_guard<std::mutex> lock(pair_mutex_);  // waits for a callback in progress
    spinning_ = false;
  }
  participant_.reset();  // peers see the node leave
}

// As rcutils' default console format: "[LEVEL] [seconds.nanoseconds] [node]: message", info on
// stdout and the rest on stderr.
void Ros2NodeIo::Log(pipeline::NodeLogLevel level, const std::string& text) {
  static const char* const kNames[] = {"DEBUG", "INFO", "WARN", "ERROR", "FATAL"};
  if (level == pipeline::NodeLogLevel::kDebug) return;
  const int i = static_cast<int>(level);
  const int64_t now = NowNs();
  FILE* out = i >= 2 ? stderr : stdout;
  std::fprintf(out, "[%s] [%lld.%09lld] [%s]: %s\n", kNames[i],
               static_cast<long long>(now / 1'000'000'000),
               static_cast<long long>(now % 1'000'000'000), args_.node_name.c_str(), text.c_str());
  std::fflush(out);
}

}  // namespace sfrt::ros2
