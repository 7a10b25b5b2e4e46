// sfrt_kernel_bench: Google Benchmark cases for every convolution of SceneEDNet, on each ISA
// this CPU runs, at the layer's real shape for a given input size (default 540x960).
//
// Each case runs one layer through a Session of a one-layer model (the layer, preceded by its
// nearest-2x upsample and, for the last decoder convolution, the crop, so the session fuses them
// as it does in the full model). The session's Run() is the kernel call plus a few checks, so the
// time is the kernel's whatever kernel the session picks (direct, fused phase, Winograd); the
// label names it. Times: CPU time of the calling thread with 1 thread, wall time with more.
// Counters: GFLOP/s (2 x the layer's 3x3 MACs over its output, the same
// "effective" count `sfrt bench` uses, so shortcuts show as a higher rate) and MMAC per run.
//
// Flags (besides Google Benchmark's own --benchmark_*):
//   --sfrt_size=HxW       model input size the layer shapes derive from (default 540x960)
//   --sfrt_width=D        channel width divisor, 1 = published widths (default 1)
//   --sfrt_isa=a,b        ISAs to run (default: every ISA this CPU and build support)
//   --sfrt_threads=1,2    session thread counts (default 1)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/session.h"
#include "sfrt/session_environment.h"

namespace sfrt {
namespace {

// One benchmarked layer: a one-layer model and the input it reads.
struct LayerCase {
  std::string name;  // e.g. "conv6_up_1024to512"
  exporter::ConvSpec conv;
  bool upsample = false;  // a nearest-2x upsample precedes the convolution
  Padding crop;           // explicit crop after the upsample (all zero: none)
  int in_height = 0;      // the one-layer model's input (low resolution when upsampled)
  int in_width = 0;
  int out_height = 0;
  int out_width = 0;
  double macs = 0;  // out_h * out_w * kh * kw * cin * cout
};

int CeilDiv(int a, int b) { return (a + b - 1) / b; }

// Walks the SceneEDNet spec at input height x width and returns every convolution's case.
std::vector<LayerCase> SceneEdNetCases(const exporter::ModelSpec& spec, int height, int width) {
  std::vector<LayerCase> cases;
  int h = height, w = width;
  bool pending_up = false;
  Padding pending_crop;
  for (const exporter::LayerSpec& layer : spec.layers) {
    if (std::holds_alternative<exporter::UpsampleSpec>(layer)) {
      pending_up = true;
    } else if (const auto* crop = std::get_if<exporter::CropSpec>(&layer)) {
      // ToInputSize (the only crop SceneEDNet has): excess rows/columns from the top/left.
      pending_crop.top = 2 * h - height;
      pending_crop.left = 2 * w - width;
      (void)crop;
    } else {
      const auto& conv = std::get<exporter::ConvSpec>(layer);
      LayerCase c;
      c.conv = conv;
      c.upsample = pending_up;
      c.crop = pending_crop;
      c.in_height = h;
      c.in_width = w;
      int ch = pending_up ? 2 * h - pending_crop.top : h;
      int cw = pending_up ? 2 * w - pending_crop.left : w;
      c.out_height = CeilDiv(ch, conv.stride_h);
      c.out_width = CeilDiv(cw, conv.stride_w);
      c.macs = double(c.out_height) * c.out_width * conv.kernel_h * conv.kernel_w *
               conv.in_channels * conv.out_channels;
      std::ostringstream name;
      name << conv.name << (pending_up ? "_up" : "") << "_" << conv.in_channels << "to"
           << conv.out_channels << "_s" << conv.stride_h << "_" << c.out_height << "x"
           << c.out_width;
      c.name = name.str();
      cases.push_back(c);
      h = c.out_height;
      w = c.out_width;
      pending_up = false;
      pending_crop = Padding{};
    }
  }
  return cases;
}

std::shared_ptr<const Model> BuildModel(const LayerCase& c, std::string* error) {
  exporter::ModelSpec spec;
  spec.name = "bench-" + c.name;
  spec.input.channels = c.conv.in_channels;
  spec.input.image_order.clear();
  exporter::SetOutputChannels(spec, c.conv.out_channels);
  spec.output.channel_names.clear();
  if (c.upsample) spec.layers.push_back(exporter::UpsampleSpec{"up", 2, 2, {}});
  if (c.crop.top != 0 || c.crop.left != 0) {
    exporter::CropSpec crop;
    crop.name = "crop";
    crop.rule = CropRule::kExplicit;
    crop.amounts = c.crop;
    spec.layers.push_back(crop);
  }
  spec.layers.push_back(c.conv);
  auto bytes = exporter::SerializeModel(spec);
  if (!bytes.ok()) {
    *error = bytes.message();
    return nullptr;
  }
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  if (!model.ok()) {
    *error = model.message();
    return nullptr;
  }
  return model.value();
}

void RunLayer(benchmark::State& state, const LayerCase& c, Isa isa, int threads) {
  // Models are built lazily and one at a time (the full-width layers hold up to 38 MB).
  static std::string cached_name;
  static std::shared_ptr<const Model> cached_model;
  if (cached_name != c.name) {
    cached_model.reset();
    std::string error;
    cached_model = BuildModel(c, &error);
    if (cached_model == nullptr) {
      state.SkipWithError(("building the model of " + c.name + ": " + error).c_str());
      return;
    }
    cached_name = c.name;
  }
  SessionOptions options;
  options.max_height = c.in_height;
  options.max_width = c.in_width;
  options.isa = isa;
  options.threads = threads;
  if (Status env = tools::ApplySessionEnvironment(options); !env.ok()) {
    state.SkipWithError(env.message().c_str());
    return;
  }
  auto session = Session::Create(cached_model, options);
  if (!session.ok()) {
    state.SkipWithError(("Session::Create: " + session.message()).c_str());
    return;
  }
  std::string kernels;
  for (const PlannedStep& step : (*session)->steps()) {
    if (std::strcmp(step.kernel, "view") == 0) continue;
    if (!kernels.empty()) kernels += "+";
    kernels += step.kernel;
  }
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> dist(0.0f, 1.0f);
  std::vector<float> input(static_cast<size_t>(c.in_height) * c.in_width * c.conv.in_channels);
  for (float& v : input) v = dist(rng);
  std::vector<float> output(static_cast<size_t>(c.out_height) * c.out_width * c.conv.out_channels);
  for (auto _ : state) {
    const Status s = (*session)->Run(input, c.in_height, c.in_width, output);
    if (!s.ok()) {
      state.SkipWithError(("Run: " + s.message()).c_str());
      break;
    }
    benchmark::DoNotOptimize(output.data());
    benchmark::ClobberMemory();
  }
  state.SetLabel(kernels);
  state.counters["GFLOP"] =
      benchmark::Counter(2.0 * c.macs * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["MMAC"] = benchmark::Counter(c.macs * 1e-6);
}

std::vector<std::string> Split(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream in(list);
  for (std::string item; std::getline(in, item, ',');) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// Parses and removes the --sfrt_* flags; returns false (after printing why) on a bad value.
struct Flags {
  int height = 540;
  int width = 960;
  int width_divisor = 1;
  std::vector<Isa> isas = SupportedIsas();
  std::vector<int> threads = {1};
};

bool ParseFlags(int* argc, char** argv, Flags* flags) {
  int kept = 1;
  for (int i = 1; i < *argc; ++i) {
    const std::string arg = argv[i];
    auto value_of = [&](const char* flag) -> const char* {
      const size_t n = std::strlen(flag);
      return arg.compare(0, n, flag) == 0 && arg.size() > n && arg[n] == '=' ? argv[i] + n + 1
                                                                             : nullptr;
    };
    if (const char* size = value_of("--sfrt_size")) {
      if (std::sscanf(size, "%dx%d", &flags->height, &flags->width) != 2 || flags->height < 1 ||
          flags->width < 1) {
        std::fprintf(stderr, "sfrt_kernel_bench: --sfrt_size must be HxW, got '%s'\n", size);
        return false;
      }
    } else if (const char* width = value_of("--sfrt_width")) {
      flags->width_divisor = std::atoi(width);
      if (flags->width_divisor < 1 || 64 % flags->width_divisor != 0) {
        std::fprintf(stderr, "sfrt_kernel_bench: --sfrt_width must divide 64, got '%s'\n", width);
        return false;
      }
    } else if (const char* isa_list = value_of("--sfrt_isa")) {
      flags->isas.clear();
      for (const std::string& name : Split(isa_list)) {
        Isa isa = Isa::kRef;
        if (!ParseIsa(name, &isa) || !IsaSupported(isa)) {
          std::fprintf(stderr, "sfrt_kernel_bench: --sfrt_isa '%s' is not one of %s\n",
                       name.c_str(), SupportedIsaList().c_str());
          return false;
        }
        flags->isas.push_back(isa);
      }
    } else if (const char* thread_list = value_of("--sfrt_threads")) {
      flags->threads.clear();
      for (const std::string& t : Split(thread_list)) {
        const int n = std::atoi(t.c_str());
        if (n < 1) {
          std::fprintf(stderr, "sfrt_kernel_bench: --sfrt_threads '%s' is not >= 1\n", t.c_str());
          return false;
        }
        flags->threads.push_back(n);
      }
    } else {
      argv[kept++] = argv[i];
    }
  }
  *argc = kept;
  if (flags->isas.empty() || flags->threads.empty()) {
    std::fprintf(stderr, "sfrt_kernel_bench: --sfrt_isa and --sfrt_threads need a value\n");
    return false;
  }
  return true;
}

}  // namespace
}  // namespace sfrt

int main(int argc, char** argv) {
  using namespace sfrt;
  Flags flags;
  if (!ParseFlags(&argc, argv, &flags)) return 2;
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;

  static const std::vector<LayerCase> cases =
      SceneEdNetCases(exporter::SceneEdNetSpec(flags.width_divisor), flags.height, flags.width);
  for (const LayerCase& c : cases) {
    for (Isa isa : flags.isas) {
      for (int threads : flags.threads) {
        const std::string name = "sceneednet_" + std::to_string(flags.height) + "x" +
                                 std::to_string(flags.width) + "/" + c.name + "/" + IsaName(isa) +
                                 "/threads:" + std::to_string(threads);
        auto* b = benchmark::RegisterBenchmark(name.c_str(), RunLayer, c, isa, threads)
                      ->Unit(benchmark::kMillisecond);
        // One thread: times and rates from the benchmark thread's CPU time, which other
        // processes on a shared machine distort far less than wall time. More threads: wall
        // time (the pool's threads are not the benchmark thread).
        if (threads > 1) b->UseRealTime();
      }
    }
  }
  benchmark::AddCustomContext("sfrt_supported_isas", SupportedIsaList());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
