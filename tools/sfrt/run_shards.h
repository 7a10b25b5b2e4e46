// `sfrt run --shard I/N`: a dataset replay split over N machines (a Slurm array job, a
// Kubernetes Indexed Job), and `sfrt merge` of the shards' summaries into the summary one
// machine's run writes.
//
// The units are the dataset's sequences (KITTI: its scenes) or the bags of a folder
// (--replay-bags), sorted (eval::MakeWorkList, the list `sfrt eval --shard` splits too); unit k
// goes to shard k mod N and is never split, so no window is lost or doubled at a shard's edge. A
// shard writes its files under <out>/shard-I-of-N/ (no two shards write one file), and its
// summary.json holds, beside the run's own keys:
//   "shard":      {"index", "count", "units" (the whole list), "list_sha256", "mine" (its
//                  units), "order" (the dataset's own order of the units), "description" (the
//                  whole dataset's source line), "out" (its --out; the merge's outputs.dir
//                  when the shards share it, else the list of their folders)}
//   "provenance": {"model_sha256", "sfrt_version"}
//   "latency_samples_ms": every latency sample behind its percentiles
//                 (PipelineOptions::summary_samples)
//
// MergeRunShards checks that the N shards of one list are all there, none twice, and that they
// agree on everything that is not a count (the model and its SHA-256, version, ISA, threads,
// queue policy, outputs, deadline settings, source options): a refusal names the shard's file
// and the field. It then builds the single run's summary.json: counters summed (frames, windows,
// drops, pairs, images, misses, output errors), per-unit lists (bad frames, skipped outputs) in
// the dataset's order, and every percentile computed again from all shards' samples, which are
// exactly the percentiles of all their windows (up to the last LatestValues::kDefaultCapacity
// windows of each shard, as a single run keeps). Two values cannot be one run's: "wall_s" is the
// shards' wall times summed (machine time) and "fps" the frames over it; "merged" lists the
// shards' files, folders, frames and wall times.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "eval/evaluate.h"
#include "eval/shards.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/shard_args.h"
#include "sfrt/status.h"

namespace sfrt::tools {

// What one shard of a dataset replay reads.
struct RunShardPlan {
  ShardSpec shard;
  eval::WorkList list;             // the dataset's units, sorted, and their SHA-256
  std::vector<std::string> mine;   // this shard's units, in list order
  std::vector<std::string> order;  // the units in the dataset's order (its single run's)
  std::string description;         // the whole dataset's source line
  std::string out;                 // --out; this shard writes to dir
  std::string dir;                 // <out>/shard-I-of-N
};

// The plan for shard `shard` of the units `order` (in the source's own order: a dataset's
// sequences, a folder's bags), whose source line is `description`; `what` names a unit in the
// refusal ("sequence", "bag"). Refused when the shard would have no unit (more shards than units).
Result<RunShardPlan> PlanRunShard(std::vector<std::string> order, std::string description,
                                  const std::string& what, const ShardSpec& shard,
                                  const std::string& out);
// The same for the dataset at `root` (rendering pass `pass`): its sequences; refused also when
// the dataset cannot be read.
Result<RunShardPlan> PlanDatasetShard(const std::string& root, const std::string& pass,
                                      const ShardSpec& shard, const std::string& out);

// The members a shard adds to its summary ("shard", "provenance").
void AnnotateRunShard(const RunShardPlan& plan, const std::string& model_sha256,
                      nlohmann::json* summary);

// The shards' summary.json files as `sfrt merge` finds them: `path` is a summary.json, the --out
// the shards share (the summary.json of each shard-I-of-N folder in it, a merged summary.json
// beside them ignored), or a shard's folder (its summary.json). Empty when `path` is a folder
// with none of these.
std::vector<std::string> FindRunShardSummaries(const std::string& path);

// True when `json` is a summary.json of sfrt run (a shard's, or another that MergeRunShards
// refuses as not a shard's).
bool IsRunSummary(const nlohmann::json& json);

// The single run's summary.json from all N shards' summaries.
Result<nlohmann::json> MergeRunShards(const std::vector<eval::ShardFile>& shards);

// The console's figures of a summary.json (a merged one included): frames, why it stopped, the
// chain's counts, fps, the stages', end to end's and its parts' percentiles, the pictures'.
pipeline::PipelineResult ResultFromSummary(const nlohmann::json& summary);

// The console summary of a run that started (sfrt run, and sfrt merge of a run's shards).
void PrintRunResult(const std::string& source_description, const pipeline::PipelineResult& result);

}  // namespace sfrt::tools
