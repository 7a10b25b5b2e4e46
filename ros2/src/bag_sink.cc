#include "sfrt/ros2/bag_sink.h"

#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <ctime>
#include <filesystem>
#include <system_error>

#include "bag_writer.h"
#include "sfrt/pipeline/flow_messages.h"
#include "sfrt/pipeline/io/atomic_write.h"

namespace sfrt::ros2 {
namespace {

namespace fs = std::filesystem;

bool IsMcapPath(const std::string& path) { return fs::path(path).extension() == ".mcap"; }

// metadata.yaml as rosbag2 (Jazzy, version 9) writes it for a bag of one MCAP file.
std::string MetadataYaml(const std::string& file, const detail::McapBagWriter& w) {
  const int64_t duration = w.last_stamp_ns() - w.first_stamp_ns();
  YAML::Emitter y;
  y << YAML::BeginMap << YAML::Key << "rosbag2_bagfile_information" << YAML::Value
    << YAML::BeginMap;
  y << YAML::Key << "version" << YAML::Value << 9;
  y << YAML::Key << "storage_identifier" << YAML::Value << "mcap";
  y << YAML::Key << "duration" << YAML::Value << YAML::BeginMap << YAML::Key << "nanoseconds"
    << YAML::Value << duration << YAML::EndMap;
  y << YAML::Key << "starting_time" << YAML::Value << YAML::BeginMap << YAML::Key
    << "nanoseconds_since_epoch" << YAML::Value << w.first_stamp_ns() << YAML::EndMap;
  y << YAML::Key << "message_count" << YAML::Value << w.messages();
  y << YAML::Key << "topics_with_message_count" << YAML::Value << YAML::BeginSeq;
  for (const detail::RecordedTopic& t : w.topics()) {
    y << YAML::BeginMap << YAML::Key << "topic_metadata" << YAML::Value << YAML::BeginMap;
    y << YAML::Key << "name" << YAML::Value << t.name;
    y << YAML::Key << "type" << YAML::Value << t.type;
    y << YAML::Key << "serialization_format" << YAML::Value << "cdr";
    y << YAML::Key << "offered_qos_profiles" << YAML::Value << YAML::BeginSeq << YAML::EndSeq;
    y << YAML::Key << "type_description_hash" << YAML::Value << "";
    y << YAML::EndMap << YAML::Key << "message_count" << YAML::Value << t.messages << YAML::EndMap;
  }
  y << YAML::EndSeq;
  y << YAML::Key << "compression_format" << YAML::Value << "";
  y << YAML::Key << "compression_mode" << YAML::Value << "";
  y << YAML::Key << "relative_file_paths" << YAML::Value << YAML::BeginSeq << file << YAML::EndSeq;
  y << YAML::Key << "files" << YAML::Value << YAML::BeginSeq << YAML::BeginMap;
  y << YAML::Key << "path" << YAML::Value << file;
  y << YAML::Key << "starting_time" << YAML::Value << YAML::BeginMap << YAML::Key
    << "nanoseconds_since_epoch" << YAML::Value << w.first_stamp_ns() << YAML::EndMap;
  y << YAML::Key << "duration" << YAML::Value << YAML::BeginMap << YAML::Key << "nanoseconds"
    << YAML::Value << duration << YAML::EndMap;
  y << YAML::Key << "message_count" << YAML::Value << w.messages();
  y << YAML::EndMap << YAML::EndSeq;
  y << YAML::Key << "custom_data" << YAML::Value << YAML::Null;
  y << YAML::Key << "ros_distro" << YAML::Value << "";
  y << YAML::EndMap << YAML::EndMap;
  return std::string(y.c_str()) + "\n";
}

}  // namespace

Status CheckBag2Path(const std::string& path) {
  if (IsMcapPath(path)) {
    Result<io::OutputTarget> target = io::ResolveOutputTarget(path);
    if (!target.ok()) return Status::Error("--record-bag: " + target.message());
    if (target->kind != io::OutputTarget::Kind::kReplace) {
      return Status::Error("--record-bag '" + path + "' is " + target->what +
                           ": an MCAP file is finished by its summary and indexes, so it is "
                           "written only as a regular file; give a file path");
    }
    return Status::Ok();
  }
  std::error_code ec;
  if (fs::exists(fs::symlink_status(path, ec))) {
    Result<io::OutputTarget> target = io::ResolveOutputTarget(path);
    const std::string what = target.ok() ? target->what : std::string("a directory");
    return Status::Error("--record-bag '" + path + "' exists (" + what +
                         "); a rosbag2 bag is written as a new folder (ros2 bag record refuses "
                         "an existing one too) or as a .mcap file: give one of those");
  }
  const fs::path parent = fs::absolute(fs::path(path), ec).parent_path();
  if (std::string problem = io::CheckWritableDirectory(parent.string(), "--record-bag");
      !problem.empty()) {
    return Status::Error(problem);
  }
  return Status::Ok();
}

FlowBag2Sink::FlowBag2Sink(pipeline::FlowRecordingOptions options)
    : recorder_(std::move(options)) {}

FlowBag2Sink::~FlowBag2Sink() {
  if (writer_) Discard();  // never finished by Stop(): nothing is replaced
}

void FlowBag2Sink::Discard() {
  if (writer_) (void)writer_->Close();
  writer_.reset();
  std::error_code ec;
  fs::remove_all(tmp_, ec);
}

Status FlowBag2Sink::Start() {
  if (Status s = CheckBag2Path(recorder_.options().path); !s.ok()) return s;
  folder_ = !IsMcapPath(recorder_.options().path);
  if (folder_) {
    final_ = recorder_.options().path;
    tmp_ = final_ + ".partial-" + std::to_string(::getpid());
    std::error_code ec;
    fs::remove_all(tmp_, ec);  // a partial folder of this process id: ours, from no other run
    if (!fs::create_directory(tmp_, ec)) {
      return Status::Error("cannot create the folder '" + tmp_ + "': " + ec.message());
    }
    const std::string name = fs::path(final_).filename().string();
    mcap_ = (fs::path(tmp_) / (name + "_0.mcap")).string();
  } else {
    Result<io::OutputTarget> target = io::ResolveOutputTarget(recorder_.options().path);
    if (!target.ok()) return target.status();
    final_ = target->path;
    tmp_ = mcap_ = final_ + ".tmp.mcap";
  }
  writer_ = std::make_unique<detail::McapBagWriter>();
  if (Status s = writer_->Open(mcap_); !s.ok()) {
    Discard();
    return s;
  }
  recorder_.Start();
  return Status::Ok();
}

Status FlowBag2Sink::Write(const pipeline::FlowFrame& frame) {
  return recorder_.Write(frame, writer_.get());
}

Status FlowBag2Sink::RecordInputs(const pipeline::WindowItem& item) {
  if (!writer_) return Status::Error("the bag '" + recorder_.options().path + "' is not open");
  return recorder_.WriteInputs(item, writer_.get());
}

Status FlowBag2Sink::Stop() {
  if (!writer_) return Status::Ok();
  Status closed = writer_->Close();
  if (closed.ok() && folder_) {
    const std::string yaml = MetadataYaml(fs::path(mcap_).filename().string(), *writer_);
    closed = io::WriteFileAtomically(
        (fs::path(tmp_) / "metadata.yaml").string(),
        std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(yaml.data()), yaml.size()));
  }
  if (recorder_.failed() || !closed.ok()) {
    Discard();
    return Status::Error("the bag '" + recorder_.options().path +
                         "' was not written (nothing replaced it)" +
                         (closed.ok() ? std::string() : ": " + closed.message()));
  }
  // The bag's data on disk before it appears under its name.
  if (Status s = io::FlushFileSystemOf(fs::absolute(mcap_).parent_path().string()); !s.ok()) {
    Discard();
    return s;
  }
  std::error_code ec;
  fs::rename(tmp_, final_, ec);
  if (ec) {
    const std::string from = tmp_;
    Discard();
    return Status::Error("cannot rename '" + from + "' to '" + final_ + "': " + ec.message());
  }
  writer_.reset();
  return Status::Ok();
}

}  // namespace sfrt::ros2
