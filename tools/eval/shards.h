// An evaluation split over N machines (a Slurm array job, a Kubernetes Indexed Job), merged into
// exactly the numbers one machine gives.
//
// The work list is the dataset's units (Scene Flow sequences, KITTI scenes), sorted; unit k goes to
// shard k mod N and is never split. Each shard's `--json` holds, beside its own report:
//   "shard":      {"index", "count", "units" (the whole list), "list_sha256"}
//   "provenance": {"model_sha256", "sfrt_version", "isa" (the ISA its session ran; "" without
//                  frames), "model_training", "options" (everything that changes the numbers)}
//   "partials":   per unit of this shard, its frames and, per method, the raw sums and counts
//                 (MetricsAccumulator::State, KittiCounts::State)
// MergeShards checks that the N shards of one list are all there, none twice, with one model,
// version, ISA and option set (each refusal names the shard's file and the field), and rebuilds the
// report: the units' accumulators merged in list order, as a single run merges its sequences, so
// every mean, share, median and count is the single run's, bit for bit.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "eval/evaluate.h"

namespace sfrt::eval {

// The sorted units and the SHA-256 of their names, one per line.
WorkList MakeWorkList(std::vector<std::string> units);

// Unit k (in list order) belongs to shard k mod N.
inline bool InShard(size_t unit, const ShardSpec& shard) {
  return static_cast<int>(unit % static_cast<size_t>(shard.count)) == shard.index;
}

// A shard's provenance: the model file's SHA-256, the options (EvalReport::options).
Status SetShardProvenance(const EvalOptions& options, EvalReport* report);

// The "shard", "provenance" and "partials" members of a shard's JSON (FormatJson adds them).
std::string ShardJson(const EvalReport& report);

// One shard's JSON as read from `file` (for the messages).
struct ShardFile {
  std::string file;
  nlohmann::json json;
};

// The N shards of one work list in index order, each once: refused (naming the file and field)
// when they do not share shard.count, shard.list_sha256 and shard.units, when one is given twice
// or one is missing. `what` names a shard's file in the refusal ("the --json").
Result<std::vector<const ShardFile*>> ShardsInOrder(const std::vector<ShardFile>& shards,
                                                    const std::string& what);

// Every shard has the first one's value of object.key (refused naming the shard's file, the
// field down to the member that differs, and both values).
Status SameEverywhere(const std::vector<ShardFile>& shards, const char* object, const char* key);

// The single run's report rebuilt from all N shards' JSON.
Result<EvalReport> MergeShards(const std::vector<ShardFile>& shards);

}  // namespace sfrt::eval
