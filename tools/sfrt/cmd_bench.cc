// sfrt bench: times Session::Run on one model and input size for every requested ISA and thread
// count, in the same process and interleaved round by round (so a machine shared with other
// work slows every configuration alike). Reports per configuration: p50/p90/p99/p99.9/max and
// standard deviation, effective GFLOP/s (2 x the model's nominal multiply-accumulates / median
// time, so exact shortcuts that skip arithmetic count as speed) and its share of the measured
// peak FMA throughput, the time of each planned step (run order, top N, by op type) and its
// place on the roofline (bench_roofline.h), and per run the page faults, context switches and
// CPU migrations that explain spikes; with --budget-ms, whether a percentile meets a latency
// budget (exit 3 when it does not). `sfrt bench --peak` runs only the peak microbenchmarks: fp32
// FMA per ISA, int8 (AVX-512 VNNI, AMX), int16 (AVX-512 VNNI) and bf16 (AVX512_BF16, AMX) dot
// products, the read bandwidth, and reports whether AMX could run. Statistics and counters live
// in tools/profiling/.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <span>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "profiling/peak_bandwidth.h"
#include "profiling/peak_dot.h"
#include "profiling/peak_fma.h"
#include "profiling/system_info.h"
#include "sfrt/bench_roofline.h"
#include "sfrt/commands.h"
#include "sfrt/config/limits.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/model_notes.h"
#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/stats.h"
#include "sfrt/session.h"
#include "sfrt/session_environment.h"
#include "sfrt/shapes.h"

namespace sfrt::tools {
namespace {

// At most this many timed (or warm-up) runs per configuration: each keeps its step times.
constexpr int kMaxRuns = 100000;

namespace prof = sfrt::profiling;
using Json = nlohmann::ordered_json;

constexpr char kName[] = "bench";
// A configuration's chosen percentile exceeded --budget-ms.
constexpr int kExitBudgetMissed = 3;

struct BenchArgs {
  std::string model;
  std::string size;  // empty: the model's traced size (DefaultInputSize)
  std::string isas = "best";
  std::string threads = "1";
  int warmup = 1;
  int runs = 5;
  double min_seconds = 0.0;
  std::string json;
  int top = 10;
  double budget_ms = 0;  // set when budget_given
  bool budget_given = false;
  std::string budget_percentile = "p99";
  bool peak = false;
  double peak_seconds = 0.2;
  bool quantized_input = false;  // time RunQuantized on the input quantised once beforehand
  // --tuning, once per variant ("default" or NAME=VALUE,...: session_environment.h); empty: the
  // default tuning alone.
  std::vector<std::string> tunings;
};

// Per-run process counters of one configuration.
struct RunCounters {
  std::vector<double> wall_ms;
  std::vector<int64_t> minor_faults;
  std::vector<int64_t> major_faults;
  std::vector<int64_t> voluntary_switches;
  std::vector<int64_t> involuntary_switches;
  std::vector<int64_t> migrations;  // empty when the counter is unavailable
};

struct Config {
  Isa isa = Isa::kRef;
  int threads = 1;
  std::string tuning = "default";  // the --tuning variant, on top of the SFRT_* variables
  std::unique_ptr<Session> session;
  std::string kernels;
  std::vector<prof::StepLabel> labels;
  std::unique_ptr<prof::StepRecorder> recorder;
  std::vector<int64_t> stamps;  // steps + 1, reused by every run
  RunCounters counters;
  double peak_gflops = 0;  // 0: not measured
  std::string peak_kernel;
  bool placed = false;  // `roofline` holds the steps' roofline (the peaks were measured)
  prof::Roofline roofline;
};

// What --isa, --threads and --tuning ask for: a configuration for each combination.
struct BenchLists {
  std::vector<Isa> isas;
  std::vector<int> thread_counts;
  std::vector<std::string> tunings;
};

// The switches --tuning takes, their defaults in brackets: "winograd=auto|off|f2|f4 [auto], ...".
std::string TuningSwitchList() {
  std::string list;
  for (const tools::TuningSwitch& s : tools::TuningSwitches()) {
    std::string values;
    for (std::string_view v : tools::TuningValues(s)) {
      if (!values.empty()) values += "|";
      values += v;
    }
    if (!list.empty()) list += ", ";
    list += std::string(s.name) + "=" + values + " [" + s.default_value + "]";
  }
  return list;
}

std::vector<std::string> SplitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

std::string Fixed(double v, int digits) { return prof::FormatCell(v, digits); }

double Mib(size_t bytes) { return static_cast<double>(bytes) / (1024.0 * 1024.0); }

// What a configuration's session planned at load: its arena and its packed weights.
size_t PlannedBytes(const Config& c) {
  return c.session->arena_bytes() + c.session->packed_weight_bytes();
}

// A budget as given, without rounding or exponent for ordinary values: 1000000, 12.5, 1e-06.
std::string Milliseconds(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.10g", v);
  return buf;
}

// "avx512 x2 threads", and the tuning variant where it is not the default:
// "avx512amx x2 threads (amx_pairs=off)".
std::string ConfigName(const Config& c) {
  std::string name = std::string(IsaName(c.isa)) + " x" + std::to_string(c.threads) + " threads";
  if (c.tuning != "default") name += " (" + c.tuning + ")";
  return name;
}

// --tuning into its list of variants (the default alone without it); "" on success, else the
// usage message.
std::string ParseTunings(const BenchArgs& args, std::vector<std::string>* tunings) {
  for (const std::string& variant : args.tunings) {
    if (variant == "each") {
      for (const std::string& v : tools::EachTuningVariant()) tunings->push_back(v);
      continue;
    }
    KernelTuning scratch;
    if (Status s = tools::ApplyTuningVariant(variant, scratch); !s.ok()) {
      return "--tuning: " + s.message();
    }
    tunings->push_back(variant);
  }
  if (tunings->empty()) tunings->push_back("default");
  return "";
}

// --isa and --threads into lists; "" on success, else the usage message.
std::string ParseLists(const BenchArgs& args, std::vector<Isa>* isas,
                       std::vector<int>* thread_counts) {
  for (const std::string& name : SplitList(args.isas)) {
    if (name == "all") {
      for (Isa isa : SupportedIsas()) isas->push_back(isa);
      continue;
    }
    if (name == "best") {
      isas->push_back(BestIsa());
      continue;
    }
    Isa isa = Isa::kRef;
    if (!ParseIsa(name, &isa) || isa == Isa::kAuto) {
      return "--isa: '" + name + "' is not one of " + IsaNameList(false) + ", best, all";
    }
    isas->push_back(isa);
  }
  for (const std::string& t : SplitList(args.threads)) {
    int n = 0;
    const char* end = t.data() + t.size();
    auto [ptr, ec] = std::from_chars(t.data(), end, n);
    if (t.empty() || ec != std::errc() || ptr != end) {
      return "--threads: '" + t + "' is not an integer";
    }
    if (std::string problem = config::CheckRange(config::kThreads, "--threads", n);
        !problem.empty()) {
      return problem;
    }
    thread_counts->push_back(config::ResolveThreads(n));
  }
  if (isas->empty() || thread_counts->empty()) {
    return "--isa and --threads need at least one value";
  }
  return "";
}

Json BuildJson() {
  const prof::BuildInfo& b = prof::GetBuildInfo();
  return Json{{"compiler", b.compiler},         {"build_type", b.build_type},
              {"cxx_flags", b.cxx_flags},       {"version", b.version},
              {"git_describe", b.git_describe}, {"system", b.system}};
}

Json CpuJson() {
  Json isas = Json::array();
  for (Isa isa : SupportedIsas()) isas.push_back(IsaName(isa));
  return Json{{"model", prof::CpuModel()},
              {"available_cpus", prof::AvailableCpus()},
              {"supported_isas", isas}};
}

void PrintBuildAndCpu() {
  const prof::BuildInfo& b = prof::GetBuildInfo();
  std::printf("build  %s, %s, flags '%s', sfrt %s (%s), %s\n", b.compiler.c_str(),
              b.build_type.empty() ? "no build type" : b.build_type.c_str(), b.cxx_flags.c_str(),
              b.version.c_str(), b.git_describe.c_str(), b.system.c_str());
  std::printf("cpu    %s, %d CPUs available to this process; ISAs this build runs here: %s\n",
              prof::CpuModel().c_str(), prof::AvailableCpus(), SupportedIsaList().c_str());
}

// Through the one atomic writer: a failed write (a full disk) leaves the previous file whole.
Status WriteJson(const std::string& path, const Json& json) {
  const std::string text = json.dump(2) + "\n";
  return io::WriteFileAtomically(
      path, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
}

// `sfrt bench --peak`, int8, int16 and bf16: a table per type whose loop this CPU runs, else the
// reason, once per thread count (whatever --isa); then whether AMX could run. Adds the rows and
// reasons to `json`; false after printing the error of a failed measurement.
bool RunPeakDot(const BenchArgs& args, const std::vector<int>& thread_counts, Json* json) {
  Json unavailable = Json::object();
  for (prof::DotType type : {prof::DotType::kInt8, prof::DotType::kInt16, prof::DotType::kBf16,
                             prof::DotType::kAmxInt8, prof::DotType::kAmxBf16}) {
    const bool integer = prof::DotTypeIsInteger(type);
    const char* name = prof::DotTypeName(type);
    const char* unit = integer ? "GOP/s" : "GFLOP/s";
    const std::string key = std::string("peak_") + name;
    (*json)[key] = Json::array();
    if (std::string why = prof::PeakDotUnavailable(type); !why.empty()) {
      std::printf("\npeak %s dot-product throughput: not available (%s)\n", name, why.c_str());
      unavailable[name] = why;
      continue;
    }
    std::printf(
        "\npeak %s dot-product throughput: %s counts 2 %s per multiply-accumulate; "
        "fastest of 20 windows over about %.2f s each\n",
        name, unit, integer ? "integer ops" : "flops", args.peak_seconds);
    std::printf("%-7s %7s %10s %10s %11s  %s\n", "type", "threads", unit, "GMAC/s", "per thread",
                "loop");
    for (int threads : thread_counts) {
      Result<prof::PeakDot> peak = prof::MeasurePeakDot(type, threads, args.peak_seconds);
      if (!peak.ok()) {
        ReportError(kName, peak.message(), kExitFailure);
        return false;
      }
      std::printf("%-7s %7d %10s %10s %11s  %s\n", name, threads, Fixed(peak->gops, 1).c_str(),
                  Fixed(peak->gmacs, 1).c_str(), Fixed(peak->gops / threads, 1).c_str(),
                  peak->kernel.c_str());
      const std::string ops = integer ? "gops" : "gflops";
      (*json)[key].push_back(Json{{"threads", threads},
                                  {ops, peak->gops},
                                  {"gmacs", peak->gmacs},
                                  {ops + "_per_thread", peak->gops / threads},
                                  {"kernel", peak->kernel}});
    }
  }
  if (std::string why = prof::AmxUnavailable(); !why.empty()) {
    std::printf("\namx: not available (%s)\n", why.c_str());
    unavailable["amx"] = why;
  } else {
    std::printf("\namx: available (AMX-TILE, AMX-INT8, AMX-BF16, XTILEDATA granted)\n");
  }
  (*json)["peak_unavailable"] = unavailable;
  return true;
}

// `sfrt bench --peak`, memory: the read bandwidth per thread count (the roof of memory-bound
// steps). False after reporting an error.
bool RunPeakBandwidth(const BenchArgs& args, const std::vector<int>& thread_counts, Json* json) {
  std::printf("\npeak read bandwidth: fastest of 20 windows over about %.2f s each\n",
              args.peak_seconds);
  std::printf("%-7s %7s %10s %11s  %s\n", "memory", "threads", "GB/s", "per thread", "loop");
  Json rows = Json::array();
  for (int threads : thread_counts) {
    Result<prof::PeakBandwidth> peak = prof::MeasureReadBandwidth(threads, args.peak_seconds);
    if (!peak.ok()) {
      ReportError(kName, peak.message(), kExitFailure);
      return false;
    }
    std::printf("%-7s %7d %10s %11s  %s\n", "read", threads,
                Fixed(peak->gbytes_per_second, 1).c_str(),
                Fixed(peak->gbytes_per_second / threads, 1).c_str(), peak->kernel.c_str());
    rows.push_back(Json{{"threads", threads},
                        {"gbytes_per_second", peak->gbytes_per_second},
                        {"gbytes_per_second_per_thread", peak->gbytes_per_second / threads},
                        {"buffer_mib", peak->buffer_bytes >> 20},
                        {"kernel", peak->kernel}});
  }
  (*json)["peak_read_bandwidth"] = rows;
  return true;
}

// `sfrt bench --peak`: the microbenchmarks alone.
int RunPeak(const BenchArgs& args, const std::vector<Isa>& isas,
            const std::vector<int>& thread_counts) {
  PrintBuildAndCpu();
  std::printf("\npeak fp32 FMA throughput: fastest of 20 windows over about %.2f s each\n",
              args.peak_seconds);
  std::printf("%-7s %7s %10s %11s  %s\n", "isa", "threads", "GFLOP/s", "per thread", "loop");
  Json results = Json::array();
  for (Isa isa : isas) {
    for (int threads : thread_counts) {
      Result<prof::PeakFma> peak = prof::MeasurePeakFma(isa, threads, args.peak_seconds);
      if (!peak.ok()) return ReportError(kName, peak.message(), kExitFailure);
      std::printf("%-7s %7d %10s %11s  %s\n", IsaName(isa), threads, Fixed(peak->gflops, 1).c_str(),
                  Fixed(peak->gflops / threads, 1).c_str(), peak->kernel.c_str());
      results.push_back(Json{{"isa", IsaName(isa)},
                             {"threads", threads},
                             {"gflops", peak->gflops},
                             {"gflops_per_thread", peak->gflops / threads},
                             {"kernel", peak->kernel}});
    }
  }
  Json json{{"peak", results}};
  if (!RunPeakDot(args, thread_counts, &json)) return kExitFailure;
  if (!RunPeakBandwidth(args, thread_counts, &json)) return kExitFailure;
  if (!args.json.empty()) {
    json["build"] = BuildJson();
    json["cpu"] = CpuJson();
    if (Status written = WriteJson(args.json, json); !written.ok()) {
      return ReportError(kName, "--json: " + written.message(), kExitFailure);
    }
  }
  return kExitOk;
}

template <typename T>
double MedianOf(const std::vector<T>& v) {
  std::vector<double> d(v.begin(), v.end());
  return prof::Percentile(std::move(d), 0.5);
}

template <typename T>
T MaxOf(const std::vector<T>& v) {
  return v.empty() ? T{} : *std::max_element(v.begin(), v.end());
}

Json StepsJson(const std::vector<prof::StepRow>& rows) {
  Json steps = Json::array();
  for (const prof::StepRow& r : rows) {
    steps.push_back(Json{{"step", r.step},
                         {"layers", r.label.name},
                         {"first_layer", r.label.first_layer},
                         {"last_layer", r.label.last_layer},
                         {"op", r.label.op},
                         {"kernel", r.label.kernel},
                         {"precision", r.label.precision},
                         {"median_ms", r.ms.p50},
                         {"mean_ms", r.ms.mean},
                         {"p99_ms", r.ms.p99},
                         {"max_ms", r.ms.max},
                         {"stddev_ms", r.ms.stddev},
                         {"share", r.share}});
  }
  return steps;
}

// The flags of a model run: size, the bounds of runs and warm-ups, the budget and its
// percentile. A usage error's message, or "".
std::string CheckModelRunFlags(const BenchArgs& args, int* height, int* width,
                               double* budget_percent) {
  if (!args.size.empty() && !ParseSize(args.size, height, width)) {
    return "--size: expected HxW (e.g. 540x960), got '" + args.size + "'";
  }
  if (!args.size.empty()) {  // without --size: the model's traced size, once it is loaded
    if (std::string problem = config::CheckSize(config::kInputSide, "--size", *height, *width);
        !problem.empty()) {
      return problem;
    }
  }
  // Each bound names its option; the upper ones keep the timing buffers small (a run is kept).
  for (const std::string& problem :
       {CheckAtLeast("--runs", args.runs, 1), CheckAtMost("--runs", args.runs, kMaxRuns),
        CheckAtLeast("--warmup", args.warmup, 0), CheckAtMost("--warmup", args.warmup, kMaxRuns),
        CheckAtLeast("--min-seconds", args.min_seconds, 0),
        CheckAtMost("--min-seconds", args.min_seconds, 86400),
        CheckAtLeast("--top", args.top, 0)}) {
    if (!problem.empty()) return problem;
  }
  if (args.budget_given) {
    if (!(args.budget_ms > 0) || !std::isfinite(args.budget_ms)) {
      return "--budget-ms must be a positive number of milliseconds, got " +
             FormatFloat(args.budget_ms);
    }
  }
  if (!prof::ParsePercentile(args.budget_percentile, budget_percent)) {
    return "--budget-percentile: '" + args.budget_percentile +
           "' is not a percentile (p50, p90, p99, p99.9, max, or a number in "
           "(0, 100])";
  }
  return "";
}

// The configuration of one ISA, thread count and tuning variant, its session planned and its
// timing buffers reserved for `runs` runs and some. kExitOk, or the exit code after reporting.
int MakeConfig(const BenchArgs& args, const std::shared_ptr<const Model>& model, Isa isa,
               int threads, const std::string& tuning, int height, int width, Config* c) {
  SessionOptions options;
  options.max_height = height;
  options.max_width = width;
  options.isa = isa;
  options.threads = threads;
  if (Status env = tools::ApplySessionEnvironment(options); !env.ok()) {
    return ReportError(kName, env.message(), kExitUsage);
  }
  if (Status s = tools::ApplyTuningVariant(tuning, options.tuning); !s.ok()) {
    return ReportError(kName, "--tuning: " + s.message(), kExitUsage);
  }
  auto session = Session::Create(model, options);
  if (!session.ok()) return ReportError(kName, session.message(), kExitFailure);
  c->isa = isa;
  c->threads = threads;
  c->tuning = tuning;
  c->session = std::move(session).value();
  for (const PlannedStep& step : c->session->steps()) {
    if (c->kernels.find(step.kernel) != std::string::npos) continue;
    if (!c->kernels.empty()) c->kernels += " ";
    c->kernels += step.kernel;
  }
  c->labels = prof::LabelSteps(*c->session);
  const size_t expected_runs = static_cast<size_t>(args.runs) + 16;
  c->recorder = std::make_unique<prof::StepRecorder>(c->labels.size(), expected_runs);
  c->stamps.resize(c->labels.size() + 1);
  RunCounters& k = c->counters;
  for (auto* v : {&k.minor_faults, &k.major_faults, &k.voluntary_switches, &k.involuntary_switches,
                  &k.migrations}) {
    v->reserve(expected_runs);
  }
  k.wall_ms.reserve(expected_runs);
  return kExitOk;
}

// One configuration per ISA, thread count and tuning variant, in that nesting. kExitOk, or the
// exit code after reporting.
int MakeConfigs(const BenchArgs& args, const std::shared_ptr<const Model>& model,
                const BenchLists& lists, int height, int width, std::vector<Config>* configs_out) {
  for (Isa isa : lists.isas) {
    if (std::string notice = PrecisionFallbackNotice(*model, isa); !notice.empty()) {
      std::printf("%s\n", notice.c_str());
    }
    for (int threads : lists.thread_counts) {
      for (const std::string& tuning : lists.tunings) {
        Config c;
        if (int code = MakeConfig(args, model, isa, threads, tuning, height, width, &c);
            code != kExitOk) {
          return code;
        }
        configs_out->push_back(std::move(c));
      }
    }
  }
  return kExitOk;
}

// The input every configuration runs on (seeded), and the output buffer.
struct BenchInput {
  int height = 0;
  int width = 0;
  std::vector<float> input;
  // --quantized-input: `input` as each session quantises it, from a 64-byte boundary in
  // input_u8_storage (as the tensors a session plans start), so that a first layer reading whole
  // cache lines of it is timed as it runs inside a network.
  std::vector<uint8_t> input_u8_storage;
  std::span<uint8_t> input_u8;
  std::vector<float> output;
};

// The warm-up runs, then rounds of every configuration once until --runs and --min-seconds are
// both reached, recording wall time, step times and the process counters. False after
// reporting a failed run.
bool TimeRuns(const BenchArgs& args, BenchInput& in, prof::MigrationCounter& migrations,
              std::vector<Config>& configs) {
  using Clock = std::chrono::steady_clock;
  auto run_once = [&](Config& c, bool record) -> bool {
    const prof::ResourceUsage u0 = prof::ReadResourceUsage();
    const int64_t m0 = migrations.Read();
    const auto t0 = Clock::now();
    const Status s =
        args.quantized_input
            ? c.session->RunQuantized(in.input_u8, in.height, in.width, in.output, c.stamps)
            : c.session->Run(in.input, in.height, in.width, in.output, c.stamps);
    const auto t1 = Clock::now();
    const int64_t m1 = migrations.Read();
    const prof::ResourceUsage du = prof::ReadResourceUsage() - u0;
    if (!s.ok()) {
      ReportError(kName, s.message(), kExitFailure);
      return false;
    }
    if (!record) return true;
    RunCounters& k = c.counters;
    k.wall_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    k.minor_faults.push_back(du.minor_faults);
    k.major_faults.push_back(du.major_faults);
    k.voluntary_switches.push_back(du.voluntary_switches);
    k.involuntary_switches.push_back(du.involuntary_switches);
    if (m0 >= 0 && m1 >= 0) k.migrations.push_back(m1 - m0);
    c.recorder->Add(c.stamps);
    return true;
  };
  // Every configuration once per round, the round's first one a later one each round (with two:
  // alternating), so that none always runs after the same other one. With several, each run's
  // workers spin for their spin_us before they sleep: that is waited out, untimed, so that they
  // do not take CPUs from the next configuration's run.
  const size_t n = configs.size();
  auto round_of = [&](int round, bool record) {
    for (size_t i = 0; i < n; ++i) {
      Config& c = configs[(static_cast<size_t>(round) + i) % n];
      if (!run_once(c, record)) return false;
      const int spin_us = c.session->options().spin_us;
      if (n > 1 && c.threads > 1 && spin_us > 0) {
        std::this_thread::sleep_for(std::chrono::microseconds(spin_us + 100));
      }
    }
    return true;
  };
  for (int i = 0; i < args.warmup; ++i) {
    if (!round_of(i, false)) return false;
  }
  const auto start = Clock::now();
  for (int round = 0;; ++round) {
    const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
    if (round >= args.runs && elapsed >= args.min_seconds) break;
    if (!round_of(round, true)) return false;
  }
  return true;
}

// One configuration's results, for --json.
Json ResultJson(const Config& c, const prof::Summary& s, double gflops, double percent_peak,
                int top_count, const prof::MigrationCounter& migrations) {
  const std::vector<prof::StepRow> rows = prof::StepTable(c.labels, c.recorder->durations_ms());
  double steps_total = 0;
  for (size_t r = 0; r < c.recorder->runs(); ++r) steps_total += c.recorder->total_ms(r);
  steps_total /= static_cast<double>(std::max<size_t>(c.recorder->runs(), 1));
  Json by_op = Json::array();
  for (const prof::OpRow& op : prof::ByOp(rows)) {
    by_op.push_back(Json{{"op", op.op},
                         {"steps", op.steps},
                         {"median_ms", op.median_ms},
                         {"mean_ms", op.mean_ms},
                         {"share", op.share}});
  }
  Json top = Json::array();
  for (const prof::StepRow& r : prof::TopSteps(rows, static_cast<size_t>(top_count))) {
    top.push_back(r.step);
  }
  const RunCounters& k = c.counters;
  Json per_run{{"wall_ms", k.wall_ms},
               {"minor_faults", k.minor_faults},
               {"major_faults", k.major_faults},
               {"voluntary_switches", k.voluntary_switches},
               {"involuntary_switches", k.involuntary_switches},
               {"cpu_migrations", migrations.available() ? Json(k.migrations) : Json(nullptr)}};
  return Json{{"isa", IsaName(c.isa)},
              {"threads", c.threads},
              {"tuning", c.tuning},
              {"runs", s.count},
              {"median_ms", s.p50},
              {"p90_ms", s.p90},
              {"p99_ms", s.p99},
              {"p999_ms", s.p999},
              {"max_ms", s.max},
              {"min_ms", s.min},
              {"mean_ms", s.mean},
              {"stddev_ms", s.stddev},
              {"gflops", gflops},
              {"peak_gflops", c.peak_gflops > 0 ? Json(c.peak_gflops) : Json()},
              {"percent_of_peak", c.peak_gflops > 0 ? Json(percent_peak) : Json()},
              {"peak_kernel", c.peak_kernel},
              {"kernels", c.kernels},
              {"arena_bytes", c.session->arena_bytes()},
              {"packed_weight_bytes", c.session->packed_weight_bytes()},
              {"isa_flags", prof::IsaFlags(IsaName(c.isa))},
              {"steps_total_mean_ms", steps_total},
              {"steps", StepsJson(rows)},
              {"top_steps", top},
              {"by_op", by_op},
              {"roofline", c.placed ? RooflineJson(c.roofline, s.p50) : Json(nullptr)},
              {"per_run", per_run}};
}

// The tables' last column, the tuning variant, where some configuration has one: "  <variant>",
// else "".
std::string TuningCell(const std::vector<Config>& configs, const std::string& tuning) {
  for (const Config& c : configs) {
    if (c.tuning != "default") return "  " + tuning;
  }
  return "";
}

// The summary table (median, tails, GFLOP/s, share of peak, against the first configuration);
// returns each configuration's results for --json.
Json PrintSummaryTable(const BenchArgs& args, const std::vector<Config>& configs, uint64_t macs,
                       const prof::MigrationCounter& migrations) {
  const double base = prof::Percentile(configs.front().counters.wall_ms, 0.5);
  std::printf("\n%-7s %7s %5s %9s %9s %9s %9s %9s %8s %9s %7s %9s%s\n", "isa", "threads", "runs",
              "median ms", "p90 ms", "p99 ms", "p99.9 ms", "max ms", "stddev", "GFLOP/s", "% peak",
              "vs first", TuningCell(configs, "tuning").c_str());
  Json results = Json::array();
  for (const Config& c : configs) {
    const prof::Summary s = prof::Summarize(c.counters.wall_ms);
    const double gflops = 2.0 * static_cast<double>(macs) / (s.p50 * 1e6);
    const double percent_peak = c.peak_gflops > 0 ? 100.0 * gflops / c.peak_gflops : NAN;
    std::printf("%-7s %7d %5zu %9s %9s %9s %9s %9s %8s %9s %7s %8sx%s\n", IsaName(c.isa), c.threads,
                s.count, Fixed(s.p50, 2).c_str(), Fixed(s.p90, 2).c_str(), Fixed(s.p99, 2).c_str(),
                Fixed(s.p999, 2).c_str(), Fixed(s.max, 2).c_str(), Fixed(s.stddev, 2).c_str(),
                Fixed(gflops, 1).c_str(), Fixed(percent_peak, 1).c_str(),
                Fixed(s.p50 / base, 3).c_str(), TuningCell(configs, c.tuning).c_str());
    results.push_back(ResultJson(c, s, gflops, percent_peak, args.top, migrations));
  }
  return results;
}

// The process counters per run (faults, switches, migrations), median / max and the slowest run.
void PrintProcessCounters(const std::vector<Config>& configs,
                          const prof::MigrationCounter& migrations) {
  // Process counters per run.
  std::printf("\nper run, median / max (getrusage, whole process%s):\n",
              migrations.available() ? "; migrations: perf_event_open" : "");
  std::printf("%-7s %7s %13s %13s %13s %13s %13s%s\n", "isa", "threads", "minor faults",
              "major faults", "vol. switch", "invol. sw.", "migrations",
              TuningCell(configs, "tuning").c_str());
  for (const Config& c : configs) {
    const RunCounters& k = c.counters;
    auto cell = [](const std::vector<int64_t>& v) {
      return Fixed(MedianOf(v), 0) + " / " + std::to_string(MaxOf(v));
    };
    std::printf("%-7s %7d %13s %13s %13s %13s %13s%s\n", IsaName(c.isa), c.threads,
                cell(k.minor_faults).c_str(), cell(k.major_faults).c_str(),
                cell(k.voluntary_switches).c_str(), cell(k.involuntary_switches).c_str(),
                migrations.available() ? cell(k.migrations).c_str() : "unavailable",
                TuningCell(configs, c.tuning).c_str());
    const size_t slowest = static_cast<size_t>(
        std::max_element(k.wall_ms.begin(), k.wall_ms.end()) - k.wall_ms.begin());
    std::printf(
        "        slowest run #%zu: %.2f ms, %lld minor / %lld major faults, %lld voluntary / "
        "%lld involuntary switches%s\n",
        slowest, k.wall_ms[slowest], static_cast<long long>(k.minor_faults[slowest]),
        static_cast<long long>(k.major_faults[slowest]),
        static_cast<long long>(k.voluntary_switches[slowest]),
        static_cast<long long>(k.involuntary_switches[slowest]),
        migrations.available() && slowest < k.migrations.size()
            ? (", " + std::to_string(k.migrations[slowest]) + " migrations").c_str()
            : "");
  }
  if (!migrations.available()) {
    std::printf("CPU migrations unavailable: %s\n", migrations.unavailable_reason().c_str());
  }
}

// Each configuration's steps in run order, the top steps and the time by op type.
void PrintStepTables(const BenchArgs& args, const std::vector<Config>& configs) {
  // Per-step tables.
  for (const Config& c : configs) {
    const std::vector<prof::StepRow> rows = prof::StepTable(c.labels, c.recorder->durations_ms());
    std::printf(
        "\n%s: %zu planned steps in run order (milliseconds over %zu runs; share "
        "of the steps' mean total)\n",
        ConfigName(c).c_str(), rows.size(), c.recorder->runs());
    std::fputs(prof::FormatStepTable(rows).c_str(), stdout);
    if (args.top > 0) {
      std::printf("top %d by median:\n", args.top);
      std::fputs(prof::FormatStepTable(prof::TopSteps(rows, static_cast<size_t>(args.top))).c_str(),
                 stdout);
    }
    std::printf("by op type:\n");
    std::fputs(prof::FormatOpTable(prof::ByOp(rows)).c_str(), stdout);
    if (c.placed) {
      std::printf(
          "roofline (median per step against the roof of the unit it runs on, peaks measured "
          "in this process after the runs):\n");
      std::fputs(
          FormatRoofline(rows, c.roofline, prof::Percentile(c.counters.wall_ms, 0.5)).c_str(),
          stdout);
    }
  }
}

// With more than one configuration: every step's median side by side, against the first's.
void PrintStepComparison(const std::vector<Config>& configs) {
  if (configs.size() < 2) return;
  std::printf("\nsteps side by side (median ms; [n]/[1]: against the first configuration):\n");
  std::vector<std::vector<prof::StepRow>> tables;
  const std::vector<double>& first = configs.front().counters.wall_ms;
  for (size_t i = 0; i < configs.size(); ++i) {
    const Config& c = configs[i];
    tables.push_back(prof::StepTable(c.labels, c.recorder->durations_ms()));
    if (i == 0) {
      std::printf("  [1] %s\n", ConfigName(c).c_str());
      continue;
    }
    // Round r ran every configuration once: how often this one beat the first.
    const std::vector<double>& mine = c.counters.wall_ms;
    const size_t rounds = std::min(first.size(), mine.size());
    size_t faster = 0;
    for (size_t r = 0; r < rounds; ++r) faster += mine[r] < first[r] ? 1 : 0;
    const double extra_mib = Mib(PlannedBytes(c)) - Mib(PlannedBytes(configs.front()));
    std::printf(
        "  [%zu] %s: %sx [1]'s median, faster than [1] in %zu of %zu rounds; arena and packed "
        "weights %+.1f MiB against [1]'s\n",
        i + 1, ConfigName(c).c_str(),
        Fixed(prof::Percentile(mine, 0.5) / prof::Percentile(first, 0.5), 3).c_str(), faster,
        rounds, extra_mib);
  }
  std::fputs(prof::FormatStepComparison(tables).c_str(), stdout);
}

// Each configuration's steps on the roofline: the peaks its kernels' units need at its thread
// count (each measured once), after the timed runs. False after reporting an error.
bool PlaceConfigs(const BenchArgs& args, int height, int width, std::vector<Config>& configs) {
  prof::PeakCache cache(args.peak_seconds);
  for (Config& c : configs) {
    const std::vector<prof::StepRow> rows = prof::StepTable(c.labels, c.recorder->durations_ms());
    Result<prof::Roofline> roofline = PlaceSessionSteps(
        *c.session, rows, height, width, args.quantized_input, c.peak_gflops, &cache);
    if (!roofline.ok()) {
      ReportError(kName, roofline.message(), kExitFailure);
      return false;
    }
    c.roofline = std::move(roofline).value();
    c.placed = true;
  }
  return true;
}

// --budget-ms: each configuration's chosen percentile against the budget, printed and put in
// `budget_json`. False when some configuration missed it.
bool CheckBudget(const BenchArgs& args, double budget_percent, const std::vector<Config>& configs,
                 Json* budget_json) {
  bool budget_met = true;
  const std::string label = prof::PercentileLabel(budget_percent);
  Json budget_results = Json::array();
  for (size_t i = 0; i < configs.size(); ++i) {
    const Config& c = configs[i];
    const double value = prof::Percentile(c.counters.wall_ms, budget_percent / 100.0);
    const bool met = value <= args.budget_ms;
    budget_met = budget_met && met;
    if (met) {
      std::printf("budget met: %s %s %.3f ms <= %s ms (%.3f ms to spare)\n", ConfigName(c).c_str(),
                  label.c_str(), value, Milliseconds(args.budget_ms).c_str(),
                  args.budget_ms - value);
    } else {
      std::printf("budget MISSED: %s %s %.3f ms > %s ms, over by %.3f ms (%.1f%%)\n",
                  ConfigName(c).c_str(), label.c_str(), value, Milliseconds(args.budget_ms).c_str(),
                  value - args.budget_ms, 100.0 * (value - args.budget_ms) / args.budget_ms);
    }
    budget_results.push_back(Json{{"isa", IsaName(c.isa)},
                                  {"threads", c.threads},
                                  {"tuning", c.tuning},
                                  {"value_ms", value},
                                  {"met", met},
                                  {"over_ms", value - args.budget_ms}});
  }
  *budget_json = Json{{"budget_ms", args.budget_ms},
                      {"percentile", label},
                      {"met", budget_met},
                      {"results", budget_results}};
  return budget_met;
}

// The seeded input every configuration runs on (and, for --quantized-input, its uint8 form as
// the sessions quantise it) and the output buffer. kExitOk, or the exit code after reporting.
int MakeBenchInput(const BenchArgs& args, const Model& model, const std::vector<Config>& configs,
                   int height, int width, size_t output_elements, BenchInput* in) {
  in->height = height;
  in->width = width;
  const int channels = model.metadata().input.channels;
  in->input.resize(static_cast<size_t>(height) * width * channels);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> dist(0.0f, 255.0f);
  for (float& v : in->input) v = dist(rng);
  in->output.resize(output_elements);
  if (!args.quantized_input) return kExitOk;
  // Every configuration plans the same input quantisation (the model's); quantised once here,
  // as a camera's preprocessing would (camera::Preprocessor::RunQuantized).
  const std::optional<QuantParams> q = configs.front().session->InputQuantization();
  if (!q) {
    return ReportError(kName,
                       "--quantized-input: " + args.model +
                           " takes no uint8 input (its input is not read by int8 convolutions "
                           "alone)",
                       kExitUsage);
  }
  constexpr size_t kAlign = 64;
  const size_t bytes = configs.front().session->QuantizedInputBytes(height, width);
  in->input_u8_storage.resize(bytes + kAlign);
  const size_t skip =
      (kAlign - reinterpret_cast<uintptr_t>(in->input_u8_storage.data()) % kAlign) % kAlign;
  in->input_u8 = std::span<uint8_t>(in->input_u8_storage.data() + skip, bytes);
  for (size_t i = 0; i < in->input.size(); ++i) in->input_u8[i] = QuantizeInput(in->input[i], *q);
  return kExitOk;
}

// After the timed runs: the peak FMA throughput per configuration and each one's roofline.
// kExitOk, or the exit code after reporting.
int MeasurePeaks(const BenchArgs& args, int height, int width, std::vector<Config>& configs) {
  std::map<std::pair<Isa, int>, prof::PeakFma> measured;  // once per ISA and thread count
  for (Config& c : configs) {
    auto found = measured.find({c.isa, c.threads});
    if (found == measured.end()) {
      Result<prof::PeakFma> peak = prof::MeasurePeakFma(c.isa, c.threads, args.peak_seconds);
      if (!peak.ok()) return ReportError(kName, peak.message(), kExitFailure);
      found = measured.emplace(std::pair{c.isa, c.threads}, *peak).first;
    }
    c.peak_gflops = found->second.gflops;
    c.peak_kernel = found->second.kernel;
  }
  return PlaceConfigs(args, height, width, configs) ? kExitOk : kExitFailure;
}

// The peaks '% peak' divides by, once per (ISA, threads).
void PrintPeakNotes(const std::vector<Config>& configs) {
  std::printf(
      "%% peak: GFLOP/s / the peak FMA throughput of the same ISA and threads, measured "
      "in this process after the runs:\n");
  std::map<std::pair<Isa, int>, bool> shown;
  for (const Config& c : configs) {
    if (shown[{c.isa, c.threads}]) continue;
    shown[{c.isa, c.threads}] = true;
    std::printf("  %-6s x%d: %.1f GFLOP/s (%s)\n", IsaName(c.isa), c.threads, c.peak_gflops,
                c.peak_kernel.c_str());
  }
}

void PrintResidentMemory(const prof::ResourceUsage& usage, size_t sessions) {
  if (sessions == 1) {
    std::printf(
        "peak resident memory %.1f MiB (this process: the model, one session, input and "
        "output)\n",
        static_cast<double>(usage.max_rss_kib) / 1024.0);
  } else {
    std::printf(
        "peak resident memory %.1f MiB (all %zu sessions together; time one "
        "configuration alone for one session's)\n",
        static_cast<double>(usage.max_rss_kib) / 1024.0, sessions);
  }
}

// `sfrt bench --model`: the configurations timed, their tables, --json and the budget's verdict.
int RunModelBench(const BenchArgs& args, const BenchLists& lists) {
  int height = 0, width = 0;
  double budget_percent = 99;
  if (std::string problem = CheckModelRunFlags(args, &height, &width, &budget_percent);
      !problem.empty()) {
    return ReportError(kName, problem, kExitUsage);
  }
  auto model = LoadModelFile(args.model);
  if (!model.ok()) return ReportError(kName, model.message(), kExitFailure);
  std::string size_source = "--size";
  if (args.size.empty()) size_source = DefaultInputSize((*model)->metadata(), &height, &width);
  auto geometry = InferGeometry(**model, height, width);
  if (!geometry.ok()) return ReportError(kName, geometry.message(), kExitFailure);
  uint64_t macs = 0;
  for (const LayerGeometry& g : *geometry) macs += g.macs;

  // Before any session's thread pool exists, so the pools' threads are counted too.
  prof::MigrationCounter migrations;
  std::vector<Config> configs;
  if (int code = MakeConfigs(args, *model, lists, height, width, &configs); code != kExitOk) {
    return code;
  }
  BenchInput in;
  if (int code = MakeBenchInput(args, **model, configs, height, width,
                                geometry->back().output.elements(), &in);
      code != kExitOk) {
    return code;
  }

  // Three significant digits: a small model's 0.0217 GMAC is not "0.02 GMAC (0.0 GFLOP)".
  std::printf("model  %s at %dx%d (%s): %.3g GMAC (%.3g GFLOP) per run\n", args.model.c_str(),
              height, width, size_source.c_str(), static_cast<double>(macs) / 1e9,
              2.0 * static_cast<double>(macs) / 1e9);
  PrintBuildAndCpu();
  for (const Config& c : configs) {
    const std::string flags = prof::IsaFlags(IsaName(c.isa));
    std::printf("  %s: %s (kernels built with %s); arena %.1f MiB, packed weights %.1f MiB\n",
                ConfigName(c).c_str(), c.kernels.c_str(),
                flags.empty() ? "the build's flags" : flags.c_str(), Mib(c.session->arena_bytes()),
                Mib(c.session->packed_weight_bytes()));
  }
  std::fflush(stdout);

  if (!TimeRuns(args, in, migrations, configs)) return kExitFailure;
  const prof::ResourceUsage usage = prof::ReadResourceUsage();
  if (args.peak_seconds > 0) {
    if (int code = MeasurePeaks(args, height, width, configs); code != kExitOk) return code;
  }
  const Json results = PrintSummaryTable(args, configs, macs, migrations);
  if (args.peak_seconds > 0) PrintPeakNotes(configs);
  PrintProcessCounters(configs, migrations);
  PrintStepTables(args, configs);
  PrintStepComparison(configs);
  std::printf("\n");
  PrintResidentMemory(usage, configs.size());

  bool budget_met = true;
  Json budget_json;
  if (args.budget_given) budget_met = CheckBudget(args, budget_percent, configs, &budget_json);

  if (!args.json.empty()) {
    Json json{{"model", args.model},
              {"height", height},
              {"width", width},
              {"size_source", size_source},
              {"macs", macs},
              {"peak_rss_kib", usage.max_rss_kib},
              {"peak_rss_mib", static_cast<double>(usage.max_rss_kib) / 1024.0},
              {"sessions", configs.size()},
              {"build", BuildJson()},
              {"cpu", CpuJson()},
              {"cpu_migrations", Json{{"available", migrations.available()},
                                      {"reason", migrations.unavailable_reason()}}},
              {"results", results}};
    if (args.budget_given) json["budget"] = budget_json;
    if (Status written = WriteJson(args.json, json); !written.ok()) {
      return ReportError(kName, "--json: " + written.message(), kExitFailure);
    }
  }
  if (!budget_met) {
    std::fprintf(stderr, "sfrt %s: latency budget missed: %s above %s ms (see 'budget MISSED')\n",
                 kName, prof::PercentileLabel(budget_percent).c_str(),
                 Milliseconds(args.budget_ms).c_str());
    return kExitBudgetMissed;
  }
  return kExitOk;
}

int RunBench(const BenchArgs& args) {
  BenchLists lists;
  if (std::string problem = ParseLists(args, &lists.isas, &lists.thread_counts); !problem.empty()) {
    return ReportError(kName, problem, kExitUsage);
  }
  if (std::string problem = ParseTunings(args, &lists.tunings); !problem.empty()) {
    return ReportError(kName, problem, kExitUsage);
  }
  // Found out now, not after the measurements: where --json goes must take a file.
  if (!args.json.empty()) {
    if (std::string problem = CheckOutputFile(args.json, "--json"); !problem.empty()) {
      return ReportError(kName, problem, kExitFailure);
    }
  }
  if (args.peak_seconds < 0 || (args.peak && args.peak_seconds <= 0)) {
    return ReportError(kName, "--peak-seconds must be > 0 with --peak, >= 0 otherwise", kExitUsage);
  }
  if (args.peak) {
    if (!args.model.empty() || args.budget_given || !args.tunings.empty()) {
      return ReportError(kName,
                         "--peak runs only the peak microbenchmarks; it takes no --model, "
                         "--budget-ms or --tuning (a model run measures the peak by itself)",
                         kExitUsage);
    }
    return RunPeak(args, lists.isas, lists.thread_counts);
  }
  if (args.model.empty()) {
    return ReportError(kName, "--model is required (or --peak for the peak microbenchmarks)",
                       kExitUsage);
  }
  return RunModelBench(args, lists);
}

}  // namespace

Command AddBenchCommand(CLI::App& parent) {
  auto args = std::make_shared<BenchArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "bench",
      "Time a model per ISA and thread count in the same run, per layer, against a budget");
  cmd->add_option("--model", args->model, "Model file (.sfrt); required unless --peak");
  cmd->add_option("--size", args->size,
                  "Input size HxW (default: the size the model was traced at, as sfrt inspect "
                  "uses, else 540x960)");
  cmd->add_option("--isa", args->isas,
                  "Comma-separated ISAs to time: " + IsaNameList(false) + ", best (default), all");
  cmd->add_option("--threads", args->threads,
                  "Comma-separated thread counts, each 0..256 (0: one per CPU; default 1)");
  cmd->add_option("--warmup", args->warmup,
                  "Untimed runs per configuration first, 0..100000 (default 1)");
  cmd->add_option("--runs", args->runs,
                  "Timed runs per configuration, at least; 1..100000 (default 5)");
  cmd->add_option("--min-seconds", args->min_seconds,
                  "Keep running rounds until this much time has passed (default 0)");
  cmd->add_option("--top", args->top, "Rows in the top-N table of steps by median (default 10)");
  CLI::Option* budget = cmd->add_option(
      "--budget-ms", args->budget_ms,
      "Latency budget: exit 3 when a configuration's --budget-percentile exceeds it");
  cmd->add_option("--budget-percentile", args->budget_percentile,
                  "Percentile checked against --budget-ms: p50, p90, p99 (default), p99.9, max, or "
                  "a number in (0, 100]");
  cmd->add_flag("--peak", args->peak,
                "Run only the peak microbenchmarks: fp32 FMA for --isa and --threads, int8, "
                "int16 and bf16 dot products and the memory read bandwidth for --threads");
  cmd->add_flag("--quantized-input", args->quantized_input,
                "Time Session::RunQuantized on the input quantised beforehand, as sfrt run feeds "
                "an int8 model (no quantise step); a usage error for a model that takes no uint8 "
                "input");
  cmd->add_option("--tuning", args->tunings,
                  "A kernel tuning variant to time, once per variant (repeat the flag): 'default', "
                  "comma-separated NAME=VALUE of " +
                      TuningSwitchList() +
                      " (the SFRT_<NAME> variables', applied on top of them), or 'each': the "
                      "default and every other value of every switch, one at a time (default: "
                      "the default alone)");
  cmd->add_option("--peak-seconds", args->peak_seconds,
                  "Time per peak measurement (default 0.2; 0 skips the FMA peak in a model run)");
  cmd->add_option(
      "--json", args->json,
      "Also write the results as JSON (per configuration median_ms, p90_ms, p99_ms, "
      "p999_ms, max_ms, stddev_ms, gflops, percent_of_peak, isa, threads, tuning, arena_bytes, "
      "packed_weight_bytes, steps, by_op, roofline, per_run counters; build, cpu, budget)");
  cmd->footer(
      "Every configuration (ISA x threads x --tuning variant) gets its own session, planned once;\n"
      "rounds run each configuration once, in turn, on the same seeded random input, each round\n"
      "starting one configuration later (two alternate which goes first). Times are steady_clock\n"
      "around Session::Run; percentiles interpolate linearly between ranks (NumPy's default),\n"
      "so with few runs p99.9 lies between the slowest runs; stddev is the population one.\n"
      "GFLOP/s counts the model's nominal arithmetic (2 x MACs of the plain convolutions), so\n"
      "the fused upsample-conv's saved work shows as speed; '% peak' divides it by the peak FMA\n"
      "throughput of the same ISA and thread count, measured in this process after the runs\n"
      "(--peak-seconds each; 'ref' is measured with the baseline ISA's 128-bit vectors).\n"
      "'vs first' is median / the first configuration's median; with several configurations, a\n"
      "table puts every step's median side by side against the first's (an A/B of two ISAs or\n"
      "two tunings in one process: --tuning default --tuning amx_pairs=off). Each session has\n"
      "its own threads, whose workers spin 200 us after a run before they sleep: with several\n"
      "configurations that is waited out after each run, untimed, so none runs beside another's\n"
      "spinning workers (each then wakes its own workers at its first step; one configuration\n"
      "alone runs back to back, its workers still spinning).\n"
      "Per step (Session::Run's step timestamps): median, p99, max and share of the steps' mean\n"
      "total, in run order, the --top N slowest, and summed by op type. Roofline (unless\n"
      "--peak-seconds 0): each step's median against the roof of the unit its kernel runs on\n"
      "(amx int8/bf16, int8 vnni, bf16 avx512, fma; memory for a step that only moves data):\n"
      "its actual MACs (a fused upsample-conv's phase pixels at 4 taps of 9, Winograd's\n"
      "transformed products) and least bytes moved (Session::Work), roof = min(the unit's\n"
      "peak, MACs/byte x read bandwidth), both measured in this process after the runs, the\n"
      "share reached and which roof binds; then the floors (every step at its roof; all MACs at\n"
      "the main unit's peak). Scalar int8/bf16, the AMX emulation and NEON dot products are\n"
      "'unmeasured' (no peak loop).\n"
      "Per run: minor/major page faults and voluntary/involuntary context switches (getrusage,\n"
      "whole process) and CPU migrations (perf_event_open; 'unavailable' with the reason where\n"
      "the kernel refuses).\n"
      "Also printed: compiler and version, build type and flags, each ISA's kernel flags, sfrt\n"
      "version and git describe (at configure time), CPU model (/proc/cpuinfo).\n"
      "Peak resident memory (also peak_rss_mib in the JSON) is the whole process's: with one\n"
      "configuration (one --isa, one --threads) it is one session's, as a deployment has it.\n"
      "--peak: only the microbenchmarks (independent accumulator chains in vector registers), no\n"
      "model: the fp32 FMA peak for each --isa and --threads (GFLOP/s, 2 flops per lane and FMA);\n"
      "then, for each --threads whatever --isa, the int8 peak (vpdpbusd on zmm, AVX-512 VNNI:\n"
      "GOP/s at 2 integer ops per u8 x s8 multiply-accumulate, and GMAC/s) and the bf16 peak\n"
      "(vdpbf16ps on zmm, AVX512_BF16: GFLOP/s at 2 flops per bf16 multiply-accumulate, and\n"
      "GMAC/s), and the AMX peaks amx_int8 (tdpbusd) and amx_bf16 (tdpbf16ps) on 6 C tiles, each\n"
      "only where CPUID and XCR0 (and, for AMX, the tile palette and Linux's arch_prctl\n"
      "permission) say the CPU and OS run it, else 'not available (<why>)'; and 'amx: available'\n"
      "or 'amx: not available (<the check that failed>)'; last, for each --threads, the memory\n"
      "read bandwidth (GB/s: each thread sums its slice of a 512 MiB buffer it touched first,\n"
      "four 64-byte accumulators), the roof of memory-bound steps. --json gets peak, peak_int8,\n"
      "peak_bf16, peak_amx_int8, peak_amx_bf16, peak_unavailable (the reasons) and\n"
      "peak_read_bandwidth.\n"
      "Exit codes: 0 success (and every budget met), 1 model fails to load, plan or run, 2 usage\n"
      "error, 3 --budget-ms missed: some configuration's --budget-percentile exceeds the budget\n"
      "(each miss is printed as 'budget MISSED: <isa> x<threads> threads [(<tuning>)]\n"
      "<percentile> ...').");
  return Command{cmd, [args, budget] {
                   args->budget_given = budget->count() > 0;
                   return RunBench(*args);
                 }};
}

}  // namespace sfrt::tools
