#include "eval/shards.h"

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "sfrt/sha256.h"

namespace sfrt::eval {
namespace {

using nlohmann::json;

// The options that change the numbers, as the shards must agree on them.
json OptionsJson(const EvalOptions& o) {
  return {{"model_size", {o.model_height, o.model_width}},
          {"max_frames", o.max_frames},
          {"classical", o.classical},
          {"thresholds", ThresholdsName(o.thresholds)},
          {"allow_camera_mismatch", o.allow_camera_mismatch},
          {"depth", kDepthSourceNames[static_cast<size_t>(o.depth)]},
          {"isa_asked", IsaName(o.isa)}};
}

Result<const json*> Member(const ShardFile& s, const char* object, const char* key) {
  if (!s.json.is_object() || !s.json.contains(object) || !s.json[object].is_object() ||
      !s.json[object].contains(key)) {
    return Status::Error(s.file + ": no " + std::string(object) + "." + key +
                         " (not the --json of an sfrt eval --shard run)");
  }
  return &s.json[object][key];
}

// The shards in index order, each once, all N of them.
Result<std::vector<const ShardFile*>> ByIndex(const std::vector<ShardFile>& shards, int count,
                                              const std::string& what) {
  std::vector<const ShardFile*> at(static_cast<size_t>(count), nullptr);
  for (const ShardFile& s : shards) {
    Result<const json*> index = Member(s, "shard", "index");
    if (!index.ok()) return index.status();
    if (!(*index)->is_number_integer() || (*index)->get<int>() < 0 ||
        (*index)->get<int>() >= count) {
      return Status::Error(s.file + ": shard.index " + (*index)->dump() + " is not in 0.." +
                           std::to_string(count - 1));
    }
    const ShardFile*& slot = at[(*index)->get<size_t>()];
    if (slot != nullptr) {
      return Status::Error(s.file + ": shard " + (*index)->dump() + " of " + std::to_string(count) +
                           " is given twice (also " + slot->file + ")");
    }
    slot = &s;
  }
  for (int i = 0; i < count; ++i) {
    if (at[static_cast<size_t>(i)] == nullptr) {
      return Status::Error("shard " + std::to_string(i) + " of " + std::to_string(count) +
                           " is missing (give " + what + " of every shard)");
    }
  }
  return at;
}

// The header of the single run: the report's fields the first unit's shard (shard 0) holds.
void ReadHeader(const json& j, EvalReport* r) {
  r->dataset = j.value("dataset", "");
  r->has_model = !j["model"].is_null();
  r->model_path = r->has_model ? j["model"].get<std::string>() : "";
  r->model_name = r->has_model ? j["model_name"].get<std::string>() : "";
  r->focal = j["camera"].value("focal", 0.0);
  r->baseline = j["camera"].value("baseline", 0.0);
  r->cx = j["camera"].value("cx", 0.0);
  r->cy = j["camera"].value("cy", 0.0);
  r->camera_note = j.value("camera_note", "");
  r->height = j["image_size"][0].get<int>();
  r->width = j["image_size"][1].get<int>();
  r->model_height = j["model_size"][0].get<int>();
  r->model_width = j["model_size"][1].get<int>();
  r->thresholds = j.value("thresholds", "absolute") == std::string("relative")
                      ? Thresholds::kRelative
                      : Thresholds::kAbsolute;
  r->kitti = j.value("layout", "") == std::string("kitti");
  r->has_classical = j.contains("classical");
  const std::string training = j["provenance"].value("model_training", "unknown");
  r->model_training = training == "trained"     ? TrainingState::kTrained
                      : training == "untrained" ? TrainingState::kUntrained
                                                : TrainingState::kUnknown;
}

// One unit's partial result.
Result<SequenceResult> ReadPartial(const ShardFile& s, const json& p, Thresholds thresholds) {
  SequenceResult seq;
  seq.name = p.value("unit", "");
  seq.frames = p.value("frames", 0);
  for (int m = 0; m < kMethodCount; ++m) {
    seq.methods[m] = MetricsAccumulator(thresholds);
    if (!p["methods"].contains(kMethodNames[m])) continue;
    Result<MetricsAccumulator> acc =
        MetricsAccumulator::FromState(p["methods"][kMethodNames[m]], thresholds);
    if (!acc.ok()) {
      return Status::Error(s.file + ": partials " + seq.name + " " + kMethodNames[m] + ": " +
                           acc.message());
    }
    seq.methods[m] = *acc;
    if (p.contains("conventions") && p["conventions"].contains(kMethodNames[m])) {
      Result<ConventionSet> set = ConventionSet::FromState(p["conventions"][kMethodNames[m]]);
      if (!set.ok()) {
        return Status::Error(s.file + ": partials " + seq.name + " " + kMethodNames[m] + ": " +
                             set.message());
      }
      seq.conventions[m] = *set;
    }
    if (p.contains("kitti") && p["kitti"].contains(kMethodNames[m])) {
      Result<KittiCounts> counts = KittiCounts::FromState(p["kitti"][kMethodNames[m]]);
      if (!counts.ok())
        return Status::Error(s.file + ": partials " + seq.name + ": " + counts.message());
      seq.kitti[m] = *counts;
    }
  }
  return seq;
}

}  // namespace

Status SameEverywhere(const std::vector<ShardFile>& shards, const char* object, const char* key) {
  Result<const json*> first = Member(shards[0], object, key);
  if (!first.ok()) return first.status();
  for (size_t i = 1; i < shards.size(); ++i) {
    Result<const json*> v = Member(shards[i], object, key);
    if (!v.ok()) return v.status();
    if (**v == **first) continue;
    std::string field = std::string(object) + "." + key;
    const json* mine = *v;
    const json* theirs = *first;
    if (mine->is_object() && theirs->is_object()) {  // name the member that differs
      for (const auto& [name, value] : mine->items()) {
        if (theirs->contains(name) && (*theirs)[name] == value) continue;
        field += "." + name;
        mine = &value;
        theirs = theirs->contains(name) ? &(*theirs)[name] : nullptr;
        break;
      }
    }
    return Status::Error(shards[i].file + ": " + field + " is " + mine->dump() + " but " +
                         shards[0].file + " has " + (theirs ? theirs->dump() : "none") +
                         " (the shards of one job must agree)");
  }
  return Status::Ok();
}

Result<std::vector<const ShardFile*>> ShardsInOrder(const std::vector<ShardFile>& shards,
                                                    const std::string& what) {
  if (shards.empty()) return Status::Error("no shard given");
  for (const char* key : {"count", "list_sha256", "units"}) {
    if (Status same = SameEverywhere(shards, "shard", key); !same.ok()) return same;
  }
  const json& count = shards[0].json["shard"]["count"];
  if (!count.is_number_integer() || count.get<int>() < 1) {
    return Status::Error(shards[0].file + ": shard.count " + count.dump() + " is not a count");
  }
  return ByIndex(shards, count.get<int>(), what);
}

WorkList MakeWorkList(std::vector<std::string> units) {
  std::sort(units.begin(), units.end());
  Sha256 sha;
  for (const std::string& u : units) {
    sha.Update(u.data(), u.size());
    sha.Update("\n", 1);
  }
  return WorkList{std::move(units), sha.FinishHex()};
}

Status SetShardProvenance(const EvalOptions& options, EvalReport* report) {
  report->shard = options.shard;
  if (report->has_model) {
    Result<std::string> sha = Sha256OfFile(options.model_path);
    if (!sha.ok()) return sha.status();
    report->model_sha256 = *sha;
  }
  report->options = OptionsJson(options).dump();
  return Status::Ok();
}

std::string ShardJson(const EvalReport& r) {
  json shard = {{"index", r.shard->index},
                {"count", r.shard->count},
                {"units", r.list.units},
                {"list_sha256", r.list.sha256}};
  const char* training = r.model_training == TrainingState::kTrained     ? "trained"
                         : r.model_training == TrainingState::kUntrained ? "untrained"
                                                                         : "unknown";
  json provenance = {{"model_sha256", r.model_sha256},
                     {"sfrt_version", SFRT_VERSION},
                     {"isa", r.isa},
                     {"model_training", training},
                     {"options", json::parse(r.options)}};
  json partials = json::array();
  for (const SequenceResult& seq : r.sequences) {
    json p = {{"unit", seq.name}, {"frames", seq.frames}, {"methods", json::object()}};
    for (int m = 0; m < kMethodCount; ++m) {
      if ((m == 0 && !r.has_model) || (m == 2 && !r.has_classical)) continue;
      p["methods"][kMethodNames[m]] = seq.methods[m].State();
      if (r.kitti) p["kitti"][kMethodNames[m]] = seq.kitti[m].State();
      if (!r.kitti) p["conventions"][kMethodNames[m]] = seq.conventions[m].State();
    }
    partials.push_back(p);
  }
  return "\"shard\": " + shard.dump() + ",\n  \"provenance\": " + provenance.dump() +
         ",\n  \"partials\": " + partials.dump();
}

namespace {

Result<EvalReport> Merge(const std::vector<ShardFile>& shards) {
  Result<std::vector<const ShardFile*>> ordered = ShardsInOrder(shards, "the --json");
  if (!ordered.ok()) return ordered.status();
  for (const char* key : {"model_sha256", "sfrt_version", "options", "model_training"}) {
    if (Status same = SameEverywhere(shards, "provenance", key); !same.ok()) return same;
  }
  // One ISA among the shards that ran frames (float32 kernels round differently per ISA).
  std::string isa;
  for (const ShardFile* s : *ordered) {
    const std::string mine = s->json["provenance"].value("isa", "");
    if (mine.empty()) continue;
    if (!isa.empty() && mine != isa) {
      return Status::Error(s->file + ": provenance.isa is \"" + mine +
                           "\" but another shard ran \"" + isa +
                           "\" (float32 results differ between ISAs; pin --isa)");
    }
    isa = mine;
  }
  EvalReport r;
  ReadHeader((*ordered)[0]->json, &r);
  r.list.units = shards[0].json["shard"]["units"].get<std::vector<std::string>>();
  r.list.sha256 = shards[0].json["shard"]["list_sha256"].get<std::string>();
  // The units' partials, in list order.
  std::map<std::string, SequenceResult> by_unit;
  for (const ShardFile* s : *ordered) {
    for (const json& p : s->json["partials"]) {
      Result<SequenceResult> seq = ReadPartial(*s, p, r.thresholds);
      if (!seq.ok()) return seq.status();
      by_unit[seq->name] = *seq;
    }
  }
  for (MetricsAccumulator& m : r.overall) m = MetricsAccumulator(r.thresholds);
  for (const std::string& unit : r.list.units) {
    auto found = by_unit.find(unit);
    if (found == by_unit.end()) continue;  // a unit max_frames left out
    r.sequences.push_back(found->second);
    r.frames += found->second.frames;
  }
  MergeSequences(&r);
  const std::string depth = shards[0].json["provenance"]["options"].value("depth", "gt");
  r.depth = depth == "stereo" ? DepthSource::kStereo : DepthSource::kGroundTruth;
  return r;
}

}  // namespace

Result<EvalReport> MergeShards(const std::vector<ShardFile>& shards) {
  if (shards.empty()) return Status::Error("no shard given");
  // A file that is JSON but not a shard's (a key missing or of another type) is refused, not a
  // crash.
  try {
    return Merge(shards);
  } catch (const nlohmann::json::exception& e) {
    std::string files;
    for (const ShardFile& s : shards) files += (files.empty() ? "" : ", ") + s.file;
    return Status::Error("a shard's JSON is not what sfrt eval --shard writes (" + files +
                         "): " + e.what());
  }
}

}  // namespace sfrt::eval
