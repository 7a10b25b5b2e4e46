#include "sfrt/run_shards.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <set>
#include <string_view>

#include "sfrt/camera/stereo_source.h"
#include "sfrt/config/vocabulary.h"
#include "sfrt/pipeline/stats.h"

namespace sfrt::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// ------------------------------------------------------------------------------ the merge rules

// How the shards' values of one summary field become the single run's.
enum class Rule {
  kSame,         // must agree (objects member by member, arrays element by element)
  kSum,          // counters: added (objects: member by member)
  kInUnitOrder,  // per-unit lists: joined, in the dataset's order of their "sequence"
  kUnion,        // messages: each once, in shard order
  kRebuilt,      // computed again from the shards' samples and shard blocks (MergedSummary)
};

struct FieldRule {
  std::string_view path;  // "a.b"; "[]" stands for any element of an array
  Rule rule;
};

// Every field not named here must agree between the shards.
constexpr FieldRule kFieldRules[] = {
    {"frames", Rule::kSum},
    {"drops", Rule::kSum},
    {"windows", Rule::kSum},
    {"preprocess", Rule::kSum},
    {"deadline.misses", Rule::kSum},
    {"deadline.skipped_after_miss", Rule::kSum},
    {"deadline.fallback_entries", Rule::kSum},
    {"deadline.recoveries", Rule::kSum},
    {"deadline.frames_at_fallback_size", Rule::kSum},
    {"output_errors.count", Rule::kSum},
    {"output_errors.skipped", Rule::kInUnitOrder},
    {"bad_frames", Rule::kInUnitOrder},
    {"warnings", Rule::kUnion},
    {"source.description", Rule::kRebuilt},
    {"source.windows_expected", Rule::kSum},
    {"source.images_decoded", Rule::kSum},
    {"source.images_listed", Rule::kSum},
    {"source.units", Rule::kInUnitOrder},
    {"sinks[].windows", Rule::kSum},
    {"sinks[].dropped", Rule::kSum},
    {"sinks[].write_ms", Rule::kRebuilt},
    {"latency_ms", Rule::kRebuilt},
    {"latency_attribution_ms", Rule::kRebuilt},
    {"latency_samples_ms", Rule::kRebuilt},
    {"wall_s", Rule::kSum},
    {"fps", Rule::kRebuilt},
    {"completed", Rule::kRebuilt},
    {"stopped_by", Rule::kRebuilt},
    {"error", Rule::kRebuilt},
    {"outputs.dir", Rule::kRebuilt},
    {"outputs.last", Rule::kRebuilt},
    {"outputs.last_sequence", Rule::kRebuilt},
    {"shard", Rule::kRebuilt},
};

// The pipeline lists at most this many skipped outputs (pipeline.cc's kMaxListedSkips).
constexpr size_t kMaxListedSkips = 100;

Rule RuleOf(const std::string& path) {
  for (const FieldRule& r : kFieldRules) {
    if (r.path == path) return r.rule;
  }
  return Rule::kSame;
}

std::string Join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// ------------------------------------------------------------------------------------ the walk

class Merger {
 public:
  Merger(std::vector<const eval::ShardFile*> shards, std::vector<std::string> order)
      : shards_(std::move(shards)), order_(std::move(order)) {}

  // The shards' summaries field by field into *out (the rebuilt fields left out).
  Status Walk(const std::string& path, const std::vector<const json*>& values, json* out) const {
    switch (RuleOf(path)) {
      case Rule::kRebuilt:
        return Status::Ok();
      case Rule::kSum:
        return Sum(path, values, out);
      case Rule::kInUnitOrder:
        return InUnitOrder(path, values, out);
      case Rule::kUnion:
        return Union(path, values, out);
      case Rule::kSame:
        break;
    }
    const json& first = *values[0];
    if (first.is_object() && AllOfType(values, first.type())) {
      if (Status keys = SameKeys(path, values); !keys.ok()) return keys;
      *out = json::object();
      for (const auto& [key, _] : first.items()) {
        if (Status s = Walk(Join(path, key), Members(values, key), &(*out)[key]); !s.ok()) {
          return s;
        }
        if (RuleOf(Join(path, key)) == Rule::kRebuilt) out->erase(key);
      }
      return Status::Ok();
    }
    if (first.is_array() && AllOfType(values, first.type()) && SameSize(values)) {
      *out = json::array();
      for (size_t i = 0; i < first.size(); ++i) {
        std::vector<const json*> elements;
        for (const json* v : values) elements.push_back(&(*v)[i]);
        json merged;
        if (Status s = Walk(path + "[]", elements, &merged); !s.ok()) return s;
        out->push_back(std::move(merged));
      }
      return Status::Ok();
    }
    for (size_t i = 1; i < values.size(); ++i) {
      if (*values[i] != first) return Differs(path, i, *values[i], first);
    }
    *out = first;
    return Status::Ok();
  }

  size_t OrderOf(const std::string& sequence) const {
    const auto at = std::find(order_.begin(), order_.end(), sequence);
    return static_cast<size_t>(at - order_.begin());
  }

 private:
  static bool AllOfType(const std::vector<const json*>& values, json::value_t type) {
    return std::all_of(values.begin(), values.end(),
                       [type](const json* v) { return v->type() == type; });
  }
  static bool SameSize(const std::vector<const json*>& values) {
    return std::all_of(values.begin(), values.end(),
                       [&](const json* v) { return v->size() == values[0]->size(); });
  }
  static std::vector<const json*> Members(const std::vector<const json*>& values,
                                          const std::string& key) {
    std::vector<const json*> members;
    for (const json* v : values) members.push_back(&(*v)[key]);
    return members;
  }

  Status Differs(const std::string& path, size_t shard, const json& mine, const json& first) const {
    return Status::Error(shards_[shard]->file + ": " + path + " is " + mine.dump() + " but " +
                         shards_[0]->file + " has " + first.dump() +
                         " (the shards of one run must agree)");
  }

  Status SameKeys(const std::string& path, const std::vector<const json*>& values) const {
    for (size_t i = 1; i < values.size(); ++i) {
      for (const json* pair[2] = {values[0], values[i]}; const json* side : pair) {
        for (const auto& [key, _] : side->items()) {
          if (values[0]->contains(key) && values[i]->contains(key)) continue;
          const size_t lacking = values[0]->contains(key) ? i : 0;
          return Status::Error(shards_[lacking]->file + ": no " + Join(path, key) + " (" +
                               shards_[lacking == 0 ? i : 0]->file + " has it)");
        }
      }
    }
    return Status::Ok();
  }

  Status Sum(const std::string& path, const std::vector<const json*>& values, json* out) const {
    const json& first = *values[0];
    if (first.is_object()) {
      if (Status keys = SameKeys(path, values); !keys.ok()) return keys;
      *out = json::object();
      for (const auto& [key, _] : first.items()) {
        if (Status s = Sum(Join(path, key), Members(values, key), &(*out)[key]); !s.ok()) return s;
      }
      return Status::Ok();
    }
    if (std::any_of(values.begin(), values.end(), [](const json* v) { return v->is_null(); })) {
      *out = nullptr;  // unknown somewhere (a count the source did not know): unknown
      return Status::Ok();
    }
    for (size_t i = 0; i < values.size(); ++i) {
      if (!values[i]->is_number()) {
        return Status::Error(shards_[i]->file + ": " + path + " is " + values[i]->dump() +
                             ", not a count");
      }
    }
    if (AllOfType(values, json::value_t::number_unsigned) ||
        AllOfType(values, json::value_t::number_integer)) {
      int64_t sum = 0;
      for (const json* v : values) sum += v->get<int64_t>();
      *out = sum;
    } else {
      double sum = 0;
      for (const json* v : values) sum += v->get<double>();
      *out = sum;
    }
    return Status::Ok();
  }

  Status InUnitOrder(const std::string& path, const std::vector<const json*>& values,
                     json* out) const {
    std::vector<json> all;
    for (size_t i = 0; i < values.size(); ++i) {
      if (!values[i]->is_array()) {
        return Status::Error(shards_[i]->file + ": " + path + " is not a list");
      }
      all.insert(all.end(), values[i]->begin(), values[i]->end());
    }
    std::stable_sort(all.begin(), all.end(), [this](const json& a, const json& b) {
      return OrderOf(a.value("sequence", "")) < OrderOf(b.value("sequence", ""));
    });
    if (path == "output_errors.skipped" && all.size() > kMaxListedSkips) {
      all.resize(kMaxListedSkips);
    }
    *out = std::move(all);
    return Status::Ok();
  }

  Status Union(const std::string& path, const std::vector<const json*>& values, json* out) const {
    *out = json::array();
    for (size_t i = 0; i < values.size(); ++i) {
      if (!values[i]->is_array()) {
        return Status::Error(shards_[i]->file + ": " + path + " is not a list");
      }
      for (const json& item : *values[i]) {
        if (std::find(out->begin(), out->end(), item) == out->end()) out->push_back(item);
      }
    }
    return Status::Ok();
  }

  std::vector<const eval::ShardFile*> shards_;
  std::vector<std::string> order_;
};

// ------------------------------------------------------------------------------ rebuilt fields

// One series' samples from every shard (latency_samples_ms.<group>.<name>, or .<name> when
// group is empty), joined.
Result<std::vector<double>> JoinedSamples(const std::vector<const eval::ShardFile*>& shards,
                                          const std::string& group, const std::string& name) {
  std::vector<double> all;
  for (const eval::ShardFile* s : shards) {
    const json& samples = s->json.at("latency_samples_ms");
    const json& series = group.empty() ? samples.at(name) : samples.at(group).at(name);
    if (series.is_null()) continue;
    if (!series.is_array()) {
      return Status::Error(s->file + ": latency_samples_ms." + Join(group, name) +
                           " is not a list of milliseconds");
    }
    for (const json& v : series) all.push_back(v.get<double>());
  }
  return all;
}

json Percentiles(const std::vector<double>& samples) {
  return pipeline::PercentilesJson(profiling::Summarize(samples));
}

// latency_ms, latency_attribution_ms and the queued pictures' write_ms from all samples.
Status RebuildLatencies(const std::vector<const eval::ShardFile*>& shards, json* out) {
  json& lat = (*out)["latency_ms"];
  for (const char* stage : config::kStageNames) {
    Result<std::vector<double>> all = JoinedSamples(shards, "stages", stage);
    if (!all.ok()) return all.status();
    lat[stage] = Percentiles(*all);
  }
  Result<std::vector<double>> e2e = JoinedSamples(shards, "", "end_to_end");
  if (!e2e.ok()) return e2e.status();
  lat["end_to_end"] = Percentiles(*e2e);
  json parts = json::object();
  double p50_sum = 0;
  for (int p = 0; p < pipeline::kLatencyParts; ++p) {
    const char* name = pipeline::LatencyPartName(static_cast<pipeline::LatencyPart>(p));
    Result<std::vector<double>> all = JoinedSamples(shards, "parts", name);
    if (!all.ok()) return all.status();
    parts[name] = Percentiles(*all);
    p50_sum += parts[name]["p50"].get<double>();
  }
  (*out)["latency_attribution_ms"] = {
      {"parts", parts}, {"sum_of_p50", p50_sum}, {"end_to_end_p50", lat["end_to_end"]["p50"]}};
  Result<std::vector<double>> pictures = JoinedSamples(shards, "", "pictures");
  if (!pictures.ok()) return pictures.status();
  for (size_t i = 0; i < (*out)["sinks"].size(); ++i) {
    if (shards[0]->json["sinks"][i].contains("write_ms")) {
      (*out)["sinks"][i]["write_ms"] = Percentiles(*pictures);
    }
  }
  return Status::Ok();
}

// How the run ended: completed when every shard did; the first shard's reason that is not the
// end of the source, and its error.
void RebuildEnding(const std::vector<const eval::ShardFile*>& shards, json* out) {
  bool completed = true;
  std::string stopped_by = "end of source";
  json error = nullptr;
  for (const eval::ShardFile* s : shards) {
    completed = completed && s->json.at("completed").get<bool>();
    const std::string mine = s->json.at("stopped_by").get<std::string>();
    if (stopped_by == "end of source" && mine != stopped_by) stopped_by = mine;
    if (error.is_null() && !s->json.at("error").is_null()) error = s->json["error"];
  }
  (*out)["completed"] = completed;
  (*out)["stopped_by"] = stopped_by;
  (*out)["error"] = error;
}

// outputs.dir (the --out the shards share), outputs.last (the window written last by the shard
// whose last unit comes last in the dataset's order) and the "merged" record.
void RebuildOutputs(const std::vector<const eval::ShardFile*>& shards, const Merger& merger,
                    json* out) {
  const json& block = shards[0]->json.at("shard");
  json& outputs = (*out)["outputs"];
  // The --out the shards share (the single run's), or where each shard wrote when they differ.
  outputs["dir"] = block.at("out");
  outputs["last"] = "";
  outputs["last_sequence"] = "";
  size_t latest = 0;
  json merged_shards = json::array();
  for (const eval::ShardFile* s : shards) {
    const json& mine = s->json.at("outputs");
    const std::string sequence = mine.value("last_sequence", "");
    const std::string last = mine.value("last", "");
    if (!last.empty() && (outputs["last"] == "" || merger.OrderOf(sequence) >= latest)) {
      latest = merger.OrderOf(sequence);
      outputs["last"] = last;
      outputs["last_sequence"] = sequence;
    }
    if (s->json["shard"].at("out") != block["out"]) outputs["dir"] = json::array();
    merged_shards.push_back({{"file", s->file},
                             {"index", s->json["shard"]["index"]},
                             {"dir", mine.at("dir")},
                             {"frames", s->json["frames"]["written"]},
                             {"wall_s", s->json["wall_s"]}});
  }
  if (outputs["dir"].is_array()) {
    for (const json& m : merged_shards) outputs["dir"].push_back(m["dir"]);
  }
  (*out)["source"]["description"] = block.at("description");
  (*out)["merged"] = {{"shards", merged_shards},
                      {"units", block.at("units")},
                      {"list_sha256", block.at("list_sha256")},
                      {"note",
                       "wall_s: the shards' wall times summed (machine time); fps: the frames "
                       "written over it"}};
  const double wall = (*out)["wall_s"].get<double>();
  (*out)["fps"] = wall > 0 ? (*out)["frames"]["written"].get<double>() / wall : 0.0;
}

Result<json> Merge(const std::vector<eval::ShardFile>& shards) {
  for (const eval::ShardFile& s : shards) {
    if (!s.json.contains("shard") || !s.json.contains("latency_samples_ms")) {
      return Status::Error(s.file +
                           ": no shard record or latency samples (not the summary of "
                           "sfrt run --shard)");
    }
  }
  Result<std::vector<const eval::ShardFile*>> ordered =
      eval::ShardsInOrder(shards, "the summary.json");
  if (!ordered.ok()) return ordered.status();
  for (const char* key : {"order", "description"}) {
    if (Status same = eval::SameEverywhere(shards, "shard", key); !same.ok()) return same;
  }
  for (const eval::ShardFile* s : *ordered) {
    if (!s->json.contains("latency_samples_ms")) {
      return Status::Error(s->file +
                           ": no latency_samples_ms (not the summary of sfrt run "
                           "--shard)");
    }
  }
  const Merger merger(*ordered, shards[0].json["shard"]["order"].get<std::vector<std::string>>());
  std::vector<const json*> values;
  for (const eval::ShardFile* s : *ordered) values.push_back(&s->json);
  json out;
  if (Status s = merger.Walk("", values, &out); !s.ok()) return s;
  if (Status s = RebuildLatencies(*ordered, &out); !s.ok()) return s;
  RebuildEnding(*ordered, &out);
  RebuildOutputs(*ordered, merger, &out);
  return out;
}

profiling::Summary SummaryFromJson(const json& p) {
  profiling::Summary s;
  if (!p.is_object()) return s;
  s.count = p.value("count", size_t{0});
  s.p50 = p.value("p50", 0.0);
  s.p90 = p.value("p90", 0.0);
  s.p99 = p.value("p99", 0.0);
  s.max = p.value("max", 0.0);
  return s;
}

using profiling::FormatFixed;

}  // namespace

Result<RunShardPlan> PlanRunShard(std::vector<std::string> order, std::string description,
                                  const std::string& what, const ShardSpec& shard,
                                  const std::string& out) {
  RunShardPlan plan;
  plan.shard = shard;
  plan.list = eval::MakeWorkList(order);
  plan.order = std::move(order);
  plan.description = std::move(description);
  for (size_t k = 0; k < plan.list.units.size(); ++k) {
    if (eval::InShard(k, shard)) {
      plan.mine.push_back(plan.list.units[k]);
    }
  }
  if (plan.mine.empty()) {
    const std::string n = std::to_string(plan.list.units.size());
    return Status::Error("shard " + ShardName(shard.index, shard.count) + " has no unit: " +
                         plan.description + " has " + n + " " + what + "(s), fewer than the " +
                         std::to_string(shard.count) + " shards; split it into at most " + n);
  }
  plan.out = out;
  plan.dir = (fs::path(out) /
              ("shard-" + std::to_string(shard.index) + "-of-" + std::to_string(shard.count)))
                 .string();
  return plan;
}

Result<RunShardPlan> PlanDatasetShard(const std::string& root, const std::string& pass,
                                      const ShardSpec& shard, const std::string& out) {
  camera::DatasetOptions options;
  options.pass = pass;
  camera::Result<camera::DatasetInfo> info = camera::DetectDataset(root, options);
  if (!info.ok()) return Status::Error(info.message());
  return PlanRunShard(info->sequences, camera::DescribeDataset(*info), "sequence", shard, out);
}

void AnnotateRunShard(const RunShardPlan& plan, const std::string& model_sha256,
                      nlohmann::json* summary) {
  (*summary)["shard"] = {{"index", plan.shard.index},
                         {"count", plan.shard.count},
                         {"units", plan.list.units},
                         {"list_sha256", plan.list.sha256},
                         {"mine", plan.mine},
                         {"order", plan.order},
                         {"description", plan.description},
                         {"out", plan.out}};
  (*summary)["provenance"] = {{"model_sha256", model_sha256}, {"sfrt_version", SFRT_VERSION}};
}

std::vector<std::string> FindRunShardSummaries(const std::string& path) {
  std::error_code ec;
  if (!fs::is_directory(path, ec)) return {path};
  std::vector<std::string> found;
  for (const fs::directory_entry& e : fs::directory_iterator(path, ec)) {
    const std::string name = e.path().filename().string();
    int index = -1;
    int count = -1;
    char tail = 0;
    if (std::sscanf(name.c_str(), "shard-%d-of-%d%c", &index, &count, &tail) != 2) continue;
    if (fs::is_regular_file(e.path() / "summary.json", ec)) {
      found.push_back((e.path() / "summary.json").string());
    }
  }
  std::sort(found.begin(), found.end());
  // A shard's own folder (or any run's): its summary.json.
  const fs::path own = fs::path(path) / "summary.json";
  if (found.empty() && fs::is_regular_file(own, ec)) found.push_back(own.string());
  return found;
}

bool IsRunSummary(const nlohmann::json& json) {
  return json.is_object() && json.contains("stopped_by") && json.contains("latency_ms");
}

Result<nlohmann::json> MergeRunShards(const std::vector<eval::ShardFile>& shards) {
  if (shards.empty()) return Status::Error("no shard given");
  try {  // a file that is JSON but not a shard's summary is refused, not a crash
    return Merge(shards);
  } catch (const nlohmann::json::exception& e) {
    std::string files;
    for (const eval::ShardFile& s : shards) files += (files.empty() ? "" : ", ") + s.file;
    return Status::Error("a shard's summary.json is not what sfrt run --shard writes (" + files +
                         "): " + e.what());
  }
}

pipeline::PipelineResult ResultFromSummary(const nlohmann::json& j) {
  pipeline::PipelineResult r;
  r.started = true;
  r.frames = j.at("frames").value("written", int64_t{0});
  r.stopped_by = j.value("stopped_by", "");
  r.fps = j.value("fps", 0.0);
  r.paced = j.at("timing").value("paced", false);
  for (int st = 0; st < config::kStageCount; ++st) {
    r.stage[st] = SummaryFromJson(j.at("latency_ms").value(config::kStageNames[st], json()));
  }
  r.end_to_end = SummaryFromJson(j.at("latency_ms").value("end_to_end", json()));
  const json& parts = j.at("latency_attribution_ms").at("parts");
  for (int p = 0; p < pipeline::kLatencyParts; ++p) {
    r.parts[p] = SummaryFromJson(
        parts.value(pipeline::LatencyPartName(static_cast<pipeline::LatencyPart>(p)), json()));
  }
  const json& windows = j.at("windows");
  r.chain.windows = windows.value("formed", int64_t{0});
  r.chain.broken_by_loss = windows.value("broken_by_lost_frame", int64_t{0});
  r.chain.skipped_for_gap = windows.value("skipped_for_gap", int64_t{0});
  r.chain.stream_restarts = windows.value("stream_restarts", int64_t{0});
  for (const json& sink : j.value("sinks", json::array())) {
    if (!sink.contains("write_ms")) continue;
    r.pictures_queued = true;
    r.pictures_ms = SummaryFromJson(sink["write_ms"]);
    r.pictures_dropped = sink.value("dropped", uint64_t{0});
  }
  return r;
}

void PrintRunResult(const std::string& source_description, const pipeline::PipelineResult& result) {
  std::cout << "source      " << source_description << "\n"
            << "frames      " << result.frames << " (stopped by " << result.stopped_by << ")\n";
  if (result.chain.breaks() > 0) {
    std::cout << "windows     " << result.chain.breaks() << " pair(s) opened no window (lost frame "
              << result.chain.broken_by_loss << ", stamp gap " << result.chain.skipped_for_gap
              << ", stamps going back " << result.chain.stream_restarts << ")\n";
  }
  std::cout << "throughput  " << FormatFixed(result.fps, 2) << " fps"
            << (result.paced ? "" : " (unpaced replay: this is its measure)") << "\n";
  for (int st = 0; st < config::kStageCount; ++st) {
    const std::string name = config::kStageNames[st];
    std::cout << "p50 " << name << std::string(11 - name.size(), ' ')
              << FormatFixed(result.stage[st].p50, 2) << " ms\n";
  }
  std::cout << "end to end  p50 " << FormatFixed(result.end_to_end.p50, 2) << " ms, p99 "
            << FormatFixed(result.end_to_end.p99, 2) << " ms, max "
            << FormatFixed(result.end_to_end.max, 2) << " ms"
            << (result.paced ? " (capture to output: the latency)\n"
                             : " (not a latency: windows of an unpaced replay wait in the queues; "
                               "--replay-fps N paces it like a camera)\n");
  // Where the end to end went: consecutive parts of each window's latency (they add up to it).
  std::cout << "end to end, by part (p50 / p99 ms):\n";
  double p50_sum = 0;
  for (int p = 0; p < pipeline::kLatencyParts; ++p) {
    const std::string name = pipeline::LatencyPartName(static_cast<pipeline::LatencyPart>(p));
    std::cout << "  " << name << std::string(20 - name.size(), ' ')
              << FormatFixed(result.parts[p].p50, 2) << " / " << FormatFixed(result.parts[p].p99, 2)
              << "\n";
    p50_sum += result.parts[p].p50;
  }
  std::cout << "  sum of p50s         " << FormatFixed(p50_sum, 2) << " (end to end p50 "
            << FormatFixed(result.end_to_end.p50, 2) << ")\n";
  if (result.pictures_queued) {
    std::cout << "pictures    encoded off the output stage: p50 "
              << FormatFixed(result.pictures_ms.p50, 2) << " ms, p99 "
              << FormatFixed(result.pictures_ms.p99, 2) << " ms per window, "
              << result.pictures_dropped << " dropped to keep up\n";
  }
  if (!result.summary_path.empty()) std::cout << "summary     " << result.summary_path << "\n";
}

}  // namespace sfrt::tools
