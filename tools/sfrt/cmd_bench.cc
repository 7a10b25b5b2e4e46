// sfrt bench: times Session::Run on one model and input size for every requested ISA and thread
// count, in the same process and interleaved round by round (so a machine shared with other
// work slows every configuration alike), and reports median / p90 / p99 / min, effective
// GFLOP/s (2 x the model's nominal multiply-accumulates / median time, so exact shortcuts that
// skip arithmetic count as speed) and each configuration's time relative to the first one.
#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "sfrt/commands.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/session.h"
#include "sfrt/shapes.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "bench";

struct BenchArgs {
  std::string model;
  std::string size = "540x960";
  std::string isas = "best";
  std::string threads = "1";
  int warmup = 1;
  int runs = 5;
  double min_seconds = 0.0;
  std::string json;
};

struct Config {
  Isa isa = Isa::kRef;
  int threads = 1;
  std::unique_ptr<Session> session;
  std::vector<double> ms;
  std::string kernels;
};

std::vector<std::string> SplitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const size_t lo = static_cast<size_t>(pos);
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (v[hi] - v[lo]) * (pos - static_cast<double>(lo));
}

std::string Fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

int RunBench(const BenchArgs& args) {
  int height = 0, width = 0;
  if (!ParseSize(args.size, &height, &width)) {
    return ReportError(kName, "--size: expected HxW (e.g. 540x960), got '" + args.size + "'",
                       kExitUsage);
  }
  if (args.runs < 1 || args.warmup < 0 || args.min_seconds < 0) {
    return ReportError(kName, "--runs must be >= 1, --warmup and --min-seconds >= 0", kExitUsage);
  }
  std::vector<Isa> isas;
  for (const std::string& name : SplitList(args.isas)) {
    if (name == "all") {
      for (Isa isa : SupportedIsas()) isas.push_back(isa);
      continue;
    }
    if (name == "best") {
      isas.push_back(BestIsa());
      continue;
    }
    Isa isa = Isa::kRef;
    if (!ParseIsa(name, &isa) || isa == Isa::kAuto) {
      return ReportError(kName,
                         "--isa: '" + name + "' is not one of ref, avx2, avx512, neon, best, all",
                         kExitUsage);
    }
    isas.push_back(isa);
  }
  std::vector<int> thread_counts;
  for (const std::string& t : SplitList(args.threads)) {
    int n = 0;
    if (!ParseSize("1x" + t, &n, &n) || n < 1) {
      return ReportError(kName, "--threads: '" + t + "' is not a positive integer", kExitUsage);
    }
    thread_counts.push_back(n);
  }
  if (isas.empty() || thread_counts.empty()) {
    return ReportError(kName, "--isa and --threads need at least one value", kExitUsage);
  }
  if (std::string problem = CheckInputFile(args.model, "model file"); !problem.empty()) {
    return ReportError(kName, problem, kExitFailure);
  }
  auto model = Model::LoadFile(args.model);
  if (!model.ok()) return ReportError(kName, model.message(), kExitFailure);
  auto geometry = InferGeometry(**model, height, width);
  if (!geometry.ok()) return ReportError(kName, geometry.message(), kExitFailure);
  uint64_t macs = 0;
  for (const LayerGeometry& g : *geometry) macs += g.macs;

  std::vector<Config> configs;
  for (Isa isa : isas) {
    for (int threads : thread_counts) {
      SessionOptions options;
      options.max_height = height;
      options.max_width = width;
      options.isa = isa;
      options.threads = threads;
      auto session = Session::Create(*model, options);
      if (!session.ok()) return ReportError(kName, session.message(), kExitFailure);
      Config c;
      c.isa = isa;
      c.threads = threads;
      c.session = std::move(session).value();
      for (const PlannedStep& step : c.session->steps()) {
        if (c.kernels.find(step.kernel) != std::string::npos) continue;
        if (!c.kernels.empty()) c.kernels += " ";
        c.kernels += step.kernel;
      }
      configs.push_back(std::move(c));
    }
  }

  const int channels = (*model)->metadata().input.channels;
  std::vector<float> input(static_cast<size_t>(height) * width * channels);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> dist(0.0f, 255.0f);
  for (float& v : input) v = dist(rng);
  std::vector<float> output(geometry->back().output.elements());

  std::printf("model %s at %dx%d: %.2f GMAC (%.1f GFLOP) per run\n", args.model.c_str(), height,
              width, static_cast<double>(macs) / 1e9, 2.0 * static_cast<double>(macs) / 1e9);
  for (const Config& c : configs) {
    std::printf("  %-6s x%d threads: %s\n", IsaName(c.isa), c.threads, c.kernels.c_str());
  }
  std::fflush(stdout);

  using Clock = std::chrono::steady_clock;
  auto run_once = [&](Config& c, bool record) -> bool {
    const auto t0 = Clock::now();
    const Status s = c.session->Run(input, height, width, output);
    const auto t1 = Clock::now();
    if (!s.ok()) {
      ReportError(kName, s.message(), kExitFailure);
      return false;
    }
    if (record) c.ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    return true;
  };
  for (int i = 0; i < args.warmup; ++i) {
    for (Config& c : configs) {
      if (!run_once(c, false)) return kExitFailure;
    }
  }
  // Round-robin: every configuration once per round.
  const auto start = Clock::now();
  for (int round = 0;; ++round) {
    const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
    if (round >= args.runs && elapsed >= args.min_seconds) break;
    for (Config& c : configs) {
      if (!run_once(c, true)) return kExitFailure;
    }
  }

  struct rusage usage {};
  getrusage(RUSAGE_SELF, &usage);
  const double base = Percentile(configs.front().ms, 0.5);
  std::printf("\n%-7s %7s %5s %10s %10s %10s %10s %9s %11s\n", "isa", "threads", "runs",
              "median ms", "p90 ms", "p99 ms", "min ms", "GFLOP/s", "vs first");
  std::ostringstream json;
  json << "{\n  \"model\": \"" << args.model << "\",\n  \"height\": " << height
       << ",\n  \"width\": " << width << ",\n  \"macs\": " << macs
       << ",\n  \"peak_rss_kib\": " << usage.ru_maxrss
       << ",\n  \"peak_rss_mib\": " << static_cast<double>(usage.ru_maxrss) / 1024.0
       << ",\n  \"sessions\": " << configs.size() << ",\n  \"results\": [";
  for (size_t i = 0; i < configs.size(); ++i) {
    const Config& c = configs[i];
    const double median = Percentile(c.ms, 0.5);
    const double gflops = 2.0 * static_cast<double>(macs) / (median * 1e6);
    std::printf("%-7s %7d %5zu %10s %10s %10s %10s %9s %10sx\n", IsaName(c.isa), c.threads,
                c.ms.size(), Fixed(median, 2).c_str(), Fixed(Percentile(c.ms, 0.9), 2).c_str(),
                Fixed(Percentile(c.ms, 0.99), 2).c_str(),
                Fixed(*std::min_element(c.ms.begin(), c.ms.end()), 2).c_str(),
                Fixed(gflops, 1).c_str(), Fixed(median / base, 3).c_str());
    json << (i ? "," : "") << "\n    {\"isa\": \"" << IsaName(c.isa)
         << "\", \"threads\": " << c.threads << ", \"runs\": " << c.ms.size()
         << ", \"median_ms\": " << median << ", \"p90_ms\": " << Percentile(c.ms, 0.9)
         << ", \"p99_ms\": " << Percentile(c.ms, 0.99)
         << ", \"min_ms\": " << *std::min_element(c.ms.begin(), c.ms.end())
         << ", \"gflops\": " << gflops << ", \"kernels\": \"" << c.kernels << "\"}";
  }
  json << "\n  ]\n}\n";
  if (configs.size() == 1) {
    std::printf(
        "peak resident memory %.1f MiB (this process: the model, one session, input and "
        "output)\n",
        static_cast<double>(usage.ru_maxrss) / 1024.0);
  } else {
    std::printf(
        "peak resident memory %.1f MiB (all %zu sessions together; time one "
        "configuration alone for one session's)\n",
        static_cast<double>(usage.ru_maxrss) / 1024.0, configs.size());
  }
  if (!args.json.empty()) {
    std::ofstream out(args.json);
    out << json.str();
    if (!out) return ReportError(kName, "cannot write --json " + args.json, kExitFailure);
  }
  return kExitOk;
}

}  // namespace

Command AddBenchCommand(CLI::App& parent) {
  auto args = std::make_shared<BenchArgs>();
  CLI::App* cmd =
      parent.add_subcommand("bench", "Time a model per ISA and thread count in the same run");
  cmd->add_option("--model", args->model, "Model file (.sfrt)")->required();
  cmd->add_option("--size", args->size, "Input size HxW (default 540x960)");
  cmd->add_option("--isa", args->isas,
                  "Comma-separated ISAs to time: ref, avx2, avx512, neon, best (default), all");
  cmd->add_option("--threads", args->threads, "Comma-separated thread counts (default 1)");
  cmd->add_option("--warmup", args->warmup, "Untimed runs per configuration first (default 1)");
  cmd->add_option("--runs", args->runs, "Timed runs per configuration, at least (default 5)");
  cmd->add_option("--min-seconds", args->min_seconds,
                  "Keep running rounds until this much time has passed (default 0)");
  cmd->add_option("--json", args->json,
                  "Also write the results as JSON (median_ms, p90_ms, p99_ms, min_ms, gflops, "
                  "isa, threads per configuration)");
  cmd->footer(
      "Every configuration (ISA x threads) gets its own session, planned once; rounds run each\n"
      "configuration once, in turn, on the same seeded random input. GFLOP/s counts the model's\n"
      "nominal arithmetic (2 x MACs of the plain convolutions), so the fused upsample-conv's\n"
      "saved work shows as speed. 'vs first' is median / the first configuration's median.\n"
      "Peak resident memory (also peak_rss_mib in the JSON) is the whole process's: with one\n"
      "configuration (one --isa, one --threads) it is one session's, as a deployment has it.\n"
      "Exit codes: 0 success, 1 model fails to load, plan or run, 2 usage error.");
  return Command{cmd, [args] { return RunBench(*args); }};
}

}  // namespace sfrt::tools
