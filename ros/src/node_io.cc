// C++17: see node_io.h.
#include "node_io.h"

#include <diagnostic_msgs/DiagnosticArray.h>
#include <image_transport/image_transport.h>
#include <image_transport/subscriber_filter.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/synchronizer.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/Header.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <optional>
#include <type_traits>

#include "ros_messages.h"

namespace sfrt::ros::detail {
namespace {

pipeline::ImageMessage View(const sensor_msgs::Image& m) {
  pipeline::ImageMessage v;
  v.stamp_ns = static_cast<int64_t>(m.header.stamp.toNSec());
  v.compressed = false;
  v.encoding = m.encoding;
  v.height = m.height;
  v.width = m.width;
  v.step = m.step;
  v.data = m.data.data();
  v.size = m.data.size();
  return v;
}

pipeline::ImageMessage View(const sensor_msgs::CompressedImage& m) {
  pipeline::ImageMessage v;
  v.stamp_ns = static_cast<int64_t>(m.header.stamp.toNSec());
  v.compressed = true;
  v.encoding = m.format;
  v.data = m.data.data();
  v.size = m.data.size();
  return v;
}

// The sibling camera_info topic of an image topic: "left/image_rect" -> "left/camera_info".
std::string InfoTopic(const std::string& image_topic) {
  const size_t slash = image_topic.rfind('/');
  return slash == std::string::npos ? std::string("camera_info")
                                    : image_topic.substr(0, slash + 1) + "camera_info";
}

// The subscriptions and the synchroniser of one message type.
template <typename Msg, typename Filter>
struct Pairing {
  using Policy = message_filters::sync_policies::ApproximateTime<Msg, Msg>;
  Filter left, right;
  std::optional<message_filters::Synchronizer<Policy>> sync;
};

}  // namespace

struct NodeIo::Impl {
  std::optional<::ros::NodeHandle> nh;        // the node's namespace
  std::optional<::ros::NodeHandle> private_;  // ~
  std::optional<image_transport::ImageTransport> it;
  std::optional<Pairing<sensor_msgs::Image, image_transport::SubscriberFilter>> raw;
  std::optional<Pairing<sensor_msgs::CompressedImage,
                        message_filters::Subscriber<sensor_msgs::CompressedImage>>>
      compressed;
  ::ros::Subscriber info[2];
  std::atomic<uint64_t> received[2] = {0, 0};
  PairCallback on_pair;
  InfoCallback on_info;
  ::ros::Publisher flow, t1, vis, diagnostics;
  std::string flow_name, t1_name, vis_name;
  std::optional<::ros::AsyncSpinner> spinner;
  // Reused messages: their buffers keep their capacity from window to window.
  sensor_msgs::Image image;      // flow: the output stage's thread
  sensor_msgs::Image vis_image;  // flow_vis: the picture queue's thread

  void OnRawPair(const sensor_msgs::ImageConstPtr& l, const sensor_msgs::ImageConstPtr& r) {
    on_pair(View(*l), View(*r), l->header.frame_id);
  }
  void OnCompressedPair(const sensor_msgs::CompressedImageConstPtr& l,
                        const sensor_msgs::CompressedImageConstPtr& r) {
    on_pair(View(*l), View(*r), l->header.frame_id);
  }
};

void NodeIo::Init(int* argc, char** argv, const std::string& name) {
  ::ros::init(*argc, argv, name);
}

NodeIo::NodeIo() : impl_(std::make_unique<Impl>()) {
  impl_->nh.emplace();
  impl_->private_.emplace("~");
}

NodeIo::~NodeIo() {
  if (impl_->spinner) impl_->spinner->stop();
}

bool NodeIo::HasParam(const std::string& name) const { return impl_->private_->hasParam(name); }

namespace {

template <typename T>
std::string Get(const ::ros::NodeHandle& nh, const std::string& name, T* value, const char* type) {
  if (!nh.hasParam(name)) return "";
  if (!nh.getParam(name, *value)) {
    return "parameter '" + nh.resolveName(name) + "' must be " + type;
  }
  return "";
}

}  // namespace

std::string NodeIo::GetParam(const std::string& name, std::string* value) const {
  return Get(*impl_->private_, name, value, "a string");
}
std::string NodeIo::GetParam(const std::string& name, double* value) const {
  std::string e = Get(*impl_->private_, name, value, "a number");
  // As every sfrt number (config::ParseFiniteNumber): NaN or an infinity is no setting.
  if (e.empty() && !std::isfinite(*value)) {
    e = "parameter '" + impl_->private_->resolveName(name) + "' must be a finite number, got " +
        std::to_string(*value);
  }
  return e;
}
std::string NodeIo::GetParam(const std::string& name, int* value) const {
  return Get(*impl_->private_, name, value, "an integer");
}
std::string NodeIo::GetParam(const std::string& name, bool* value) const {
  return Get(*impl_->private_, name, value, "true or false");
}

std::string NodeIo::Resolve(const std::string& topic) const {
  return impl_->nh->resolveName(topic);
}

std::string NodeIo::Subscribe(const pipeline::NodeSubscription& options, PairCallback on_pair,
                              InfoCallback on_info) {
  Impl& s = *impl_;
  s.on_pair = std::move(on_pair);
  s.on_info = std::move(on_info);
  const auto queue = static_cast<uint32_t>(options.queue_size < 1 ? 1 : options.queue_size);
  try {
    if (options.transport == "raw") {
      s.it.emplace(*s.nh);
      auto& p = s.raw.emplace();
      const image_transport::TransportHints hints("raw");
      p.left.subscribe(*s.it, options.left_topic, queue, hints);
      p.right.subscribe(*s.it, options.right_topic, queue, hints);
      p.left.registerCallback([&s](const sensor_msgs::ImageConstPtr&) { ++s.received[0]; });
      p.right.registerCallback([&s](const sensor_msgs::ImageConstPtr&) { ++s.received[1]; });
      p.sync.emplace(typename std::remove_reference_t<decltype(p)>::Policy(queue), p.left, p.right);
      p.sync->getPolicy()->setMaxIntervalDuration(::ros::Duration(options.slop_s));
      if (options.frame_interval_s > 0) {
        p.sync->getPolicy()->setInterMessageLowerBound(::ros::Duration(options.frame_interval_s));
      }
      p.sync->registerCallback(&Impl::OnRawPair, &s);
    } else if (options.transport == "compressed") {
      auto& p = s.compressed.emplace();
      p.left.subscribe(*s.nh, options.left_topic + "/compressed", queue);
      p.right.subscribe(*s.nh, options.right_topic + "/compressed", queue);
      p.left.registerCallback(
          [&s](const sensor_msgs::CompressedImageConstPtr&) { ++s.received[0]; });
      p.right.registerCallback(
          [&s](const sensor_msgs::CompressedImageConstPtr&) { ++s.received[1]; });
      p.sync.emplace(typename std::remove_reference_t<decltype(p)>::Policy(queue), p.left, p.right);
      p.sync->getPolicy()->setMaxIntervalDuration(::ros::Duration(options.slop_s));
      if (options.frame_interval_s > 0) {
        p.sync->getPolicy()->setInterMessageLowerBound(::ros::Duration(options.frame_interval_s));
      }
      p.sync->registerCallback(&Impl::OnCompressedPair, &s);
    } else {
      return "parameter '" + s.private_->resolveName("transport") + "' is '" + options.transport +
             "', not raw or compressed";
    }
    if (options.camera_info) {
      const std::string topics[2] = {InfoTopic(options.left_topic), InfoTopic(options.right_topic)};
      for (int side = 0; side < 2; ++side) {
        s.info[side] = s.nh->subscribe<sensor_msgs::CameraInfo>(
            topics[side], 2, [&s, side](const sensor_msgs::CameraInfoConstPtr& m) {
              pipeline::CameraInfoView v;
              v.width = m->width;
              v.height = m->height;
              for (int i = 0; i < 12; ++i) v.p[i] = m->P[static_cast<size_t>(i)];
              v.frame_id = m->header.frame_id;
              s.on_info(side, v);
            });
      }
    }
  } catch (const std::exception& e) {  // image_transport's plugin loader, roscpp
    return std::string("cannot subscribe to the image topics: ") + e.what();
  }
  return "";
}

uint64_t NodeIo::received(int side) const { return impl_->received[side].load(); }

std::string NodeIo::Advertise(const std::string& flow, const std::string& t1,
                              const std::string& vis, bool with_vis) {
  Impl& s = *impl_;
  s.flow_name = flow;
  s.t1_name = t1;
  s.vis_name = vis;
  s.flow = s.nh->advertise<sensor_msgs::Image>(flow, 2);
  s.t1 = s.nh->advertise<std_msgs::Header>(t1, 2);
  if (with_vis) s.vis = s.nh->advertise<sensor_msgs::Image>(vis, 2);
  s.diagnostics = s.nh->advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 4);
  return "";
}

std::string NodeIo::WriteImage(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                               const std::string& frame_id, const std::string& encoding,
                               uint32_t height, uint32_t width, uint32_t step,
                               const uint8_t* data) {
  Impl& s = *impl_;
  ::ros::Publisher* pub = topic == s.flow_name ? &s.flow : topic == s.vis_name ? &s.vis : nullptr;
  if (pub == nullptr || !*pub) return "topic '" + topic + "' is not advertised";
  if (pub->getNumSubscribers() == 0) return "";  // nobody listens: skip the copy
  sensor_msgs::Image& message = pub == &s.vis ? s.vis_image : s.image;  // one per thread
  FillImage(&message, stamp_ns, seq, frame_id, encoding, height, width, step, data);
  pub->publish(message);
  return "";
}

std::string NodeIo::WriteHeader(const std::string& topic, int64_t stamp_ns, uint32_t seq,
                                const std::string& frame_id) {
  Impl& s = *impl_;
  if (topic != s.t1_name || !s.t1) return "topic '" + topic + "' is not advertised";
  std_msgs::Header h;
  FillHeader(&h, stamp_ns, seq, frame_id);
  s.t1.publish(h);
  return "";
}

void NodeIo::PublishDiagnostics(const std::vector<pipeline::DiagnosticReport>& reports) {
  if (!impl_->diagnostics) return;
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = ::ros::Time::now();
  for (const pipeline::DiagnosticReport& r : reports) {
    diagnostic_msgs::DiagnosticStatus st;
    st.level = static_cast<uint8_t>(r.level);
    st.name = r.name;
    st.message = r.message;
    st.hardware_id = r.hardware_id;
    for (const auto& [key, value] : r.values) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = value;
      st.values.push_back(kv);
    }
    array.status.push_back(st);
  }
  impl_->diagnostics.publish(array);
}

void NodeIo::StartSpinner() {
  impl_->spinner.emplace(1);
  impl_->spinner->start();
}

bool NodeIo::Ok() const { return ::ros::ok(); }

int64_t NodeIo::NowNs() const { return static_cast<int64_t>(::ros::Time::now().toNSec()); }

void NodeIo::Shutdown() {
  if (impl_->spinner) impl_->spinner->stop();
  ::ros::shutdown();
}

void NodeIo::Log(pipeline::NodeLogLevel level, const std::string& text) {
  if (!::ros::ok()) {  // rosconsole is shut down with the node: the same format, by hand
    static const char* const kNames[] = {"DEBUG", "INFO", "WARN", "ERROR", "FATAL"};
    const auto i = static_cast<int>(level);
    if (level == pipeline::NodeLogLevel::kDebug) return;
    const ::ros::WallTime now = ::ros::WallTime::now();
    std::fprintf(i >= 2 ? stderr : stdout, "[%5s] [%u.%09u]: %s\n", kNames[i], now.sec, now.nsec,
                 text.c_str());
    std::fflush(i >= 2 ? stderr : stdout);
    return;
  }
  switch (level) {
    case pipeline::NodeLogLevel::kDebug:
      ROS_DEBUG("%s", text.c_str());
      break;
    case pipeline::NodeLogLevel::kInfo:
      ROS_INFO("%s", text.c_str());
      break;
    case pipeline::NodeLogLevel::kWarn:
      ROS_WARN("%s", text.c_str());
      break;
    case pipeline::NodeLogLevel::kError:
      ROS_ERROR("%s", text.c_str());
      break;
    case pipeline::NodeLogLevel::kFatal:
      ROS_FATAL("%s", text.c_str());
      break;
  }
}

}  // namespace sfrt::ros::detail
