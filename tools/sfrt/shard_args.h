// --shard I/N and --shard auto (sfrt eval, sfrt run), and a shard's progress: a line every
// few frames on the console and a small status file a scheduler's log can show.
#pragma once

#include <chrono>
#include <string>

#include "eval/shard_spec.h"
#include "sfrt/status.h"

namespace sfrt::tools {

using eval::ShardSpec;

// "I/N" (0 <= I < N), or "auto": SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN (0 when unset) of
// SLURM_ARRAY_TASK_COUNT (a Slurm array job), else JOB_COMPLETION_INDEX of `shard_count` (a
// Kubernetes Indexed Job, which sets no count). Errors say which variable or value is wrong.
Result<ShardSpec> ParseShardFlag(const std::string& text, int shard_count);

// "2/3".
std::string ShardName(int index, int count);

// Frames done, rate and ETA: on stdout every 10 frames (unless quiet), and, when `status_path` is
// not empty, rewritten atomically as one JSON object {"shard", "state" (running, done, failed),
// "frames_done", "frames_total", "fps", "eta_s", "message"}.
class ShardProgress {
 public:
  ShardProgress(std::string shard, bool quiet, std::string status_path);
  void Update(int done, int total, const std::string& where);
  void Done(int frames);
  void Failed(const std::string& message);
  double seconds() const;

 private:
  void WriteStatus(const char* state, int done, int total, const std::string& message);
  std::string shard_;
  bool quiet_;
  std::string status_path_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace sfrt::tools
