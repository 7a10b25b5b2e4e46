#include "sfrt/shard_args.h"

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <nlohmann/json.hpp>

#include "sfrt/pipeline/io/atomic_write.h"

namespace sfrt::tools {
namespace {

// A non-negative integer from the environment; an error naming the variable.
Result<long> EnvInt(const char* name, bool required) {
  const char* text = std::getenv(name);
  if (text == nullptr || *text == '\0') {
    if (required) return Status::Error(std::string(name) + " is not set");
    return -1L;
  }
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (*end != '\0' || v < 0) {
    return Status::Error(std::string(name) + "='" + text + "' is not a non-negative integer");
  }
  return v;
}

Result<ShardSpec> Checked(long index, long count, const std::string& source) {
  if (count < 1 || count > 100000 || index < 0 || index >= count) {
    return Status::Error("--shard " + source + ": shard " + std::to_string(index) + " of " +
                         std::to_string(count) + " (expected 0 <= I < N, N at most 100000)");
  }
  return ShardSpec{static_cast<int>(index), static_cast<int>(count)};
}

Result<ShardSpec> FromScheduler(int shard_count) {
  Result<long> task = EnvInt("SLURM_ARRAY_TASK_ID", false);
  if (!task.ok()) return Status::Error("--shard auto: " + task.message());
  if (*task >= 0) {
    Result<long> count = EnvInt("SLURM_ARRAY_TASK_COUNT", true);
    if (!count.ok()) return Status::Error("--shard auto: " + count.message());
    Result<long> min = EnvInt("SLURM_ARRAY_TASK_MIN", false);
    if (!min.ok()) return Status::Error("--shard auto: " + min.message());
    return Checked(*task - std::max(0L, *min), *count, "auto (Slurm array job)");
  }
  Result<long> index = EnvInt("JOB_COMPLETION_INDEX", false);
  if (!index.ok()) return Status::Error("--shard auto: " + index.message());
  if (*index >= 0) {
    if (shard_count < 1) {
      return Status::Error(
          "--shard auto: JOB_COMPLETION_INDEX is set but a Kubernetes Indexed "
          "Job gives no count; give --shard-count (the Job's completions)");
    }
    return Checked(*index, shard_count, "auto (Kubernetes Indexed Job)");
  }
  return Status::Error(
      "--shard auto: neither SLURM_ARRAY_TASK_ID (a Slurm array job) nor "
      "JOB_COMPLETION_INDEX (a Kubernetes Indexed Job) is set; give --shard I/N");
}

}  // namespace

Result<ShardSpec> ParseShardFlag(const std::string& text, int shard_count) {
  if (text == "auto") return FromScheduler(shard_count);
  int index = -1;
  int count = -1;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%d/%d%c", &index, &count, &tail) != 2) {
    return Status::Error("--shard: expected I/N (e.g. 0/4) or auto, got '" + text + "'");
  }
  return Checked(index, count, text);
}

std::string ShardName(int index, int count) {
  return std::to_string(index) + "/" + std::to_string(count);
}

ShardProgress::ShardProgress(std::string shard, bool quiet, std::string status_path)
    : shard_(std::move(shard)),
      quiet_(quiet),
      status_path_(std::move(status_path)),
      start_(std::chrono::steady_clock::now()) {
  WriteStatus("running", 0, 0, "");
}

double ShardProgress::seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void ShardProgress::Update(int done, int total, const std::string& where) {
  if (where.empty() || done % 10 != 0) return;
  const double s = seconds();
  const double fps = s > 0 ? done / s : 0.0;
  if (!quiet_) {
    char line[160];
    std::snprintf(line, sizeof(line), "frame     %d/%d%s%s  %s  %.2f frames/s, ETA %.0f s",
                  done + 1, total, shard_.empty() ? "" : " of shard ", shard_.c_str(),
                  where.c_str(), fps, fps > 0 ? (total - done) / fps : 0.0);
    std::cout << line << "\n" << std::flush;
  }
  WriteStatus("running", done, total, "");
}

void ShardProgress::Done(int frames) { WriteStatus("done", frames, frames, ""); }

void ShardProgress::Failed(const std::string& message) { WriteStatus("failed", 0, 0, message); }

void ShardProgress::WriteStatus(const char* state, int done, int total,
                                const std::string& message) {
  if (status_path_.empty()) return;
  const double s = seconds();
  const double fps = s > 0 ? done / s : 0.0;
  const nlohmann::json status = {
      {"shard", shard_},       {"state", state},    {"frames_done", done},
      {"frames_total", total}, {"fps", fps},        {"eta_s", fps > 0 ? (total - done) / fps : 0.0},
      {"seconds", s},          {"message", message}};
  const std::string text = status.dump() + "\n";
  // A status file that cannot be written is not worth failing the shard for; said once.
  Status written = io::WriteFileAtomically(
      status_path_,
      std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
  if (!written.ok() && !status_path_.empty()) {
    std::cerr << "sfrt: warning: status file: " << written.message() << std::endl;
    status_path_.clear();
  }
}

}  // namespace sfrt::tools
