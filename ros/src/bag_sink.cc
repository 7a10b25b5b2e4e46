#include "sfrt/ros/bag_sink.h"

#include <unistd.h>

#include <ctime>
#include <filesystem>

#include "bag_reader.h"
#include "sfrt/pipeline/flow_messages.h"
#include "sfrt/pipeline/io/atomic_write.h"

namespace sfrt::ros {
FlowBagSink::FlowBagSink(pipeline::FlowRecordingOptions options) : recorder_(std::move(options)) {}
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
  Result<std::string> resolved = ResolveBagPath(recorder_.options().path);
  if (!resolved.ok()) return resolved.status();
  final_ = *resolved;
  tmp_ = final_ + ".tmp.bag";
  writer_ = std::make_unique<detail::BagWriter>();
  if (std::string e = writer_->Open(tmp_); !e.empty()) {
    writer_.reset();
    ::unlink(tmp_.c_str());
    return Status::Error(e);
  }
  recorder_.Start();
  return Status::Ok();
}

Status FlowBagSink::Write(const pipeline::FlowFrame& frame) {
  return recorder_.Write(frame, writer_.get());
}

Status FlowBagSink::RecordInputs(const pipeline::WindowItem& item) {
  if (!writer_) return Status::Error("the bag '" + recorder_.options().path + "' is not open");
  return recorder_.WriteInputs(item, writer_.get());
}

Status FlowBagSink::Stop() {
  if (!writer_) return Status::Ok();
  std::string e = writer_->Close();
  writer_.reset();
  if (recorder_.failed() || !e.empty()) {
    ::unlink(tmp_.c_str());
    return Status::Error("the bag '" + recorder_.options().path +
                         "' was not written (nothing replaced it)" +
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
