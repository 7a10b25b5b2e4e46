#include "sfrt/ros/bag_sink.h"

#include <unistd.h>

#include <ctime>
#include <filesystem>

#include "bag_reader.h"
#include "clock.h"
#include "sfrt/pipeline/flow_messages.h"
#include "sfrt/pipeline/io/atomic_write.h"

namespace sfrt::ros {
FlowBagSink::FlowBagSink(BagSinkOptions options) : options_(std::move(options)) {}
FlowBagSink::~FlowBagSink() {
  if (writer_) {
    (void)writer_->Close();
    ::unlink(tmp_.c_str());  // never finished by Stop(): nothing is replaced
  }
}

Result<std::string> ResolveBagPath(const std::string& path) {
  Result<io::OutputTarget> target = io::ResolveOutputTarget(path);
  if (!target.ok()) return Status::Error("--record-bag: " + target.message());
  if (target->kind != io::OutputTarget::Kind::kReplace) {
    return Status::Error("--record-bag '" + path + "' is " + target->what +
                         ": a bag is finished by seeking back to its header, so it is written "
                         "only as a regular file; give a file path");
  }
  return target->path;
}

Status FlowBagSink::Start() {
  Result<std::string> resolved = ResolveBagPath(options_.path);
  if (!resolved.ok()) return resolved.status();
  final_ = *resolved;
  tmp_ = final_ + ".tmp.bag";
  writer_ = std::make_unique<detail::BagWriter>();
  if (std::string e = writer_->Open(tmp_); !e.empty()) {
    writer_.reset();
    ::unlink(tmp_.c_str());
    return Status::Error(e);
  }
  realtime_minus_monotonic_ns_ = detail::ClockNs(CLOCK_REALTIME) - detail::ClockNs(CLOCK_MONOTONIC);
  if (options_.vis) renderer_.emplace(options_.vis_options);
  return Status::Ok();
}

int64_t FlowBagSink::WallStamp(const pipeline::FrameMeta& m, int pair) const {
  if (m.stamp_ns[pair] != 0) return m.stamp_ns[pair];
  return m.capture_ns[pair] + realtime_minus_monotonic_ns_;
}

Status FlowBagSink::Write(const pipeline::FlowFrame& frame) {
  if (failed_) return Status::Error("the bag '" + options_.path + "' failed earlier");
  const pipeline::FrameMeta& m = *frame.meta;
  const pipeline::FlowTopics topics{options_.flow_topic, options_.t1_topic, options_.vis_topic};
  const std::string e =
      pipeline::WriteFlowMessages(frame, WallStamp(m, 0), WallStamp(m, 1), options_.frame_id,
                                  topics, renderer_ ? &*renderer_ : nullptr, writer_.get());
  if (!e.empty()) {
    failed_ = true;
    return Status::Error(e);
  }
  ++windows_;
  return Status::Ok();
}

Status FlowBagSink::Stop() {
  if (!writer_) return Status::Ok();
  std::string e = writer_->Close();
  writer_.reset();
  if (failed_ || !e.empty()) {
    ::unlink(tmp_.c_str());
    return Status::Error("the bag '" + options_.path + "' was not written (nothing replaced it)" +
                         (e.empty() ? std::string() : ": " + e));
  }
  std::error_code ec;
  std::filesystem::rename(tmp_, final_, ec);
  if (ec) {
    ::unlink(tmp_.c_str());
    return Status::Error("cannot rename '" + tmp_ + "' to '" + final_ + "': " + ec.message());
  }
  return Status::Ok();
}

}  // namespace sfrt::ros
