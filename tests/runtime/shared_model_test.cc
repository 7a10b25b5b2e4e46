// Proves the promise of sfrt/model.h that a Model is never modified after loading and that any
// number of threads and Sessions may share one (std::shared_ptr<const Model>). SceneEDNet at
// 1/16 width, in float32, int8 and bf16, is loaded from a buffer the Model borrows on pages
// mapped read-only (as a memory-mapped file is), so a write to the model's bytes faults. Sessions
// on several threads, each its own, with 1 or 2 threads and different maximum sizes, created
// together and run together (others created and destroyed meanwhile, on every ISA this CPU runs
// and on several at once) must each give, run after run, the bytes one Session gives serially.
// A race the outputs do not show is for the sanitizer build (the asan preset) to report.
#include <gtest/gtest.h>
#include <sys/mman.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <iterator>
#include <latch>
#include <memory>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "common/bf16_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "common/session_compare.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/isa.h"
#include "sfrt/session.h"

namespace sfrt {
namespace {

enum class Form { kFloat32, kInt8, kBf16 };

const char* FormName(Form form) {
  switch (form) {
    case Form::kFloat32:
      return "fp32";
    case Form::kInt8:
      return "int8";
    case Form::kBf16:
      return "bf16";
  }
  return "?";
}

exporter::ModelSpec SpecOf(Form form) {
  exporter::ModelSpec spec = exporter::SceneEdNetSpec(16, 23);
  switch (form) {
    case Form::kFloat32:
      break;
    case Form::kInt8:
      return testing::Int8Spec(std::move(spec));
    case Form::kBf16:
      return testing::Bf16Spec(std::move(spec));
  }
  return spec;
}

// A copy of `bytes` on anonymous pages that are read-only once written.
class ReadOnlyBytes {
 public:
  explicit ReadOnlyBytes(const std::vector<uint8_t>& bytes) : size_(bytes.size()) {
    if (size_ == 0) return;
    void* p = mmap(nullptr, size_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) return;
    std::memcpy(p, bytes.data(), size_);
    if (mprotect(p, size_, PROT_READ) != 0) {
      munmap(p, size_);
      return;
    }
    data_ = p;
  }
  ~ReadOnlyBytes() {
    if (data_ != nullptr) munmap(data_, size_);
  }
  ReadOnlyBytes(const ReadOnlyBytes&) = delete;
  ReadOnlyBytes& operator=(const ReadOnlyBytes&) = delete;

  const void* data() const { return data_; }
  size_t size() const { return size_; }

 private:
  size_t size_ = 0;
  void* data_ = nullptr;
};

struct Input {
  int height = 0;
  int width = 0;
  std::vector<float> pixels;
};

// Odd sizes (crops and odd padding occur); the largest is every session's smallest maximum.
constexpr int kMaxHeight = 23;
constexpr int kMaxWidth = 35;

std::vector<Input> Inputs() {
  return {{kMaxHeight, kMaxWidth, testing::RandomImage(kMaxHeight, kMaxWidth, 12, 1)},
          {17, 27, testing::RandomImage(17, 27, 12, 2)},
          {kMaxHeight, kMaxWidth, testing::RandomImage(kMaxHeight, kMaxWidth, 12, 3)}};
}

SessionOptions Options(Isa isa, int threads, int max_height, int max_width) {
  SessionOptions options;
  options.isa = isa;
  options.threads = threads;
  options.max_height = max_height;
  options.max_width = max_width;
  return options;
}

// A model loaded from read-only pages, the inputs, and what one Session per ISA gives for each
// input, run serially before any thread starts.
class Shared {
 public:
  // Records a test failure (and leaves model() null) when the model or a reference fails.
  explicit Shared(Form form) : bytes_(testing::SerializeOrDie(SpecOf(form))), inputs_(Inputs()) {
    if (bytes_.data() == nullptr) {
      ADD_FAILURE() << "cannot map " << bytes_.size()
                    << " bytes read-only: " << std::strerror(errno);
      return;
    }
    auto model = Model::LoadBuffer(bytes_.data(), bytes_.size(), BufferOwnership::kBorrow, {},
                                   "shared.sfrt");
    if (!model.ok()) {
      ADD_FAILURE() << model.message();
      return;
    }
    model_ = *model;
  }

  std::shared_ptr<const Model>& model() { return model_; }
  const std::vector<Input>& inputs() const { return inputs_; }

  // The serial outputs on `isa` (kAuto: BestIsa()). Records a failure and returns an empty list
  // when a run fails or gives an output that could not tell a wrong input's output from the
  // right one: not finite, or the same for two inputs.
  std::vector<std::vector<float>> SerialOutputs(Isa isa) const {
    auto session = Session::Create(model_, Options(isa, 1, kMaxHeight, kMaxWidth));
    if (!session.ok()) {
      ADD_FAILURE() << session.message();
      return {};
    }
    std::vector<std::vector<float>> outputs;
    for (const Input& input : inputs_) {
      auto shape = (*session)->OutputShape(input.height, input.width);
      if (!shape.ok()) {
        ADD_FAILURE() << shape.message();
        return {};
      }
      std::vector<float> out(shape->elements(), NAN);
      const Status s = (*session)->Run(input.pixels, input.height, input.width, out);
      if (!s.ok()) {
        ADD_FAILURE() << s.message();
        return {};
      }
      for (float v : out) {
        if (!std::isfinite(v)) {
          ADD_FAILURE() << IsaName(isa) << ": the serial output has " << v;
          return {};
        }
      }
      for (const std::vector<float>& other : outputs) {
        if (other == out) {
          ADD_FAILURE() << IsaName(isa) << ": two inputs give the same serial output";
          return {};
        }
      }
      outputs.push_back(std::move(out));
    }
    return outputs;
  }

 private:
  ReadOnlyBytes bytes_;                 // outlives model_, which borrows it
  std::shared_ptr<const Model> model_;  // declared after bytes_: released first
  std::vector<Input> inputs_;
};

// Runs `session` over `inputs` `passes` times, starting each pass at input `first` (so threads
// run different inputs at the same moment), and compares every output with `want` bit for bit.
// Returns the first mismatch or failure as text, "" when there was none. For worker threads:
// records no test failure itself.
std::string RunAndCompare(Session& session, const std::vector<Input>& inputs,
                          const std::vector<std::vector<float>>& want, int passes, size_t first) {
  size_t largest = 0;
  for (const std::vector<float>& w : want) largest = std::max(largest, w.size());
  std::vector<float> out(largest);
  for (int pass = 0; pass < passes; ++pass) {
    for (size_t n = 0; n < inputs.size(); ++n) {
      const size_t k = (first + n) % inputs.size();
      const Input& input = inputs[k];
      std::fill(out.begin(), out.end(), NAN);  // an output not written cannot match
      const Status s = session.Run(input.pixels, input.height, input.width, out);
      if (!s.ok())
        return "pass " + std::to_string(pass) + ", input " + std::to_string(k) + ": " + s.message();
      for (size_t i = 0; i < want[k].size(); ++i) {
        if (std::memcmp(&out[i], &want[k][i], sizeof(float)) != 0) {
          return "pass " + std::to_string(pass) + ", input " + std::to_string(k) + ": element " +
                 std::to_string(i) + " is " + std::to_string(out[i]) + ", serially " +
                 std::to_string(want[k][i]);
        }
      }
    }
  }
  return "";
}

// Creates a Session with `options`, then as RunAndCompare.
std::string CreateRunAndCompare(std::shared_ptr<const Model> model, const SessionOptions& options,
                                const std::vector<Input>& inputs,
                                const std::vector<std::vector<float>>& want, int passes,
                                size_t first) {
  auto session = Session::Create(std::move(model), options);
  if (!session.ok()) return "Create: " + session.message();
  return RunAndCompare(**session, inputs, want, passes, first);
}

std::string Describe(const SessionOptions& options) {
  return std::string(IsaName(options.isa)) + " x" + std::to_string(options.threads) + ", max " +
         std::to_string(options.max_height) + "x" + std::to_string(options.max_width);
}

class SharedModel : public ::testing::TestWithParam<std::tuple<Isa, Form>> {
 protected:
  void SetUp() override {
    isa_ = std::get<0>(GetParam());
    if (!IsaSupported(isa_)) {
      GTEST_SKIP() << "this CPU or build cannot run " << IsaName(isa_)
                   << " (supported: " << SupportedIsaList() << ")";
    }
    shared_ = std::make_unique<Shared>(std::get<1>(GetParam()));
    ASSERT_NE(shared_->model(), nullptr);
    want_ = shared_->SerialOutputs(isa_);
    ASSERT_EQ(want_.size(), shared_->inputs().size());
  }

  Isa isa_ = Isa::kRef;
  std::unique_ptr<Shared> shared_;
  std::vector<std::vector<float>> want_;
};

TEST_P(SharedModel, SessionsOnSeveralThreadsShareOneModelAndEachMatchesTheSerialResultBitForBit) {
  // One Session per thread, created once every thread is ready, so that the Creates overlap as
  // well as the Runs: 1 and 2 threads, the serial session's maximum size and larger ones.
  const SessionOptions configs[] = {Options(isa_, 1, kMaxHeight, kMaxWidth),
                                    Options(isa_, 2, kMaxHeight, kMaxWidth),
                                    Options(isa_, 1, 64, 80), Options(isa_, 2, 48, 61)};
  constexpr int kPasses = 7;  // 21 runs per thread
  const size_t n = std::size(configs);
  std::latch start(static_cast<std::ptrdiff_t>(n));
  std::vector<std::string> failures(n);
  std::vector<std::thread> threads;
  for (size_t t = 0; t < n; ++t) {
    threads.emplace_back([&, t] {
      start.arrive_and_wait();
      failures[t] =
          CreateRunAndCompare(shared_->model(), configs[t], shared_->inputs(), want_, kPasses, t);
    });
  }
  for (std::thread& thread : threads) thread.join();
  for (size_t t = 0; t < n; ++t) {
    EXPECT_EQ(failures[t], "") << "thread " << t << " (" << Describe(configs[t]) << ")";
  }
}

TEST_P(SharedModel, SessionsCreatedAndDestroyedWhileOthersRunChangeNoResult) {
  // Two threads run a Session each until two others have each created, run and destroyed
  // several Sessions. The test drops its own reference to the Model once the threads hold
  // theirs, so the last Session to go frees it, and none may keep it.
  const SessionOptions runners[] = {Options(isa_, 1, kMaxHeight, kMaxWidth),
                                    Options(isa_, 2, 40, 64)};
  constexpr int kChurners = 2;
  constexpr int kCycles = 6;
  const std::vector<Input>& inputs = shared_->inputs();
  std::latch start(static_cast<std::ptrdiff_t>(std::size(runners)) + kChurners);
  std::atomic<int> churning{kChurners};
  std::vector<std::string> failures(std::size(runners) + kChurners);
  std::vector<std::thread> threads;
  for (size_t t = 0; t < std::size(runners); ++t) {
    threads.emplace_back([&, t, model = shared_->model()]() mutable {
      auto session = Session::Create(std::move(model), runners[t]);
      start.arrive_and_wait();
      if (!session.ok()) {
        failures[t] = "Create: " + session.message();
        return;
      }
      int runs = 0;
      do {  // at least one pass, and on until the churners are done
        failures[t] = RunAndCompare(**session, inputs, want_, 1, t + runs);
        ++runs;
      } while (failures[t].empty() && churning.load() > 0);
    });
  }
  for (int c = 0; c < kChurners; ++c) {
    const size_t t = std::size(runners) + c;
    threads.emplace_back([&, t, c, model = shared_->model()]() mutable {
      start.arrive_and_wait();
      for (int cycle = 0; cycle < kCycles && failures[t].empty(); ++cycle) {
        // 1 or 2 threads; maximum sizes from the inputs' own up.
        const SessionOptions options =
            Options(isa_, 1 + (cycle + c) % 2, kMaxHeight + 5 * cycle, kMaxWidth + 3 * c);
        failures[t] = CreateRunAndCompare(model, options, inputs, want_, 1, cycle + c);
        if (!failures[t].empty()) failures[t] += " (" + Describe(options) + ")";
      }
      model.reset();
      churning.fetch_sub(1);
    });
  }
  const std::weak_ptr<const Model> watch = shared_->model();
  shared_->model().reset();
  for (std::thread& thread : threads) thread.join();
  for (size_t t = 0; t < failures.size(); ++t) {
    EXPECT_EQ(failures[t], "") << "thread " << t
                               << (t < std::size(runners) ? " (" + Describe(runners[t]) + ")"
                                                          : std::string(", creating sessions"));
  }
  EXPECT_TRUE(watch.expired()) << "a destroyed Session still holds the Model";
}

INSTANTIATE_TEST_SUITE_P(EveryIsa, SharedModel,
                         ::testing::Combine(::testing::Values(Isa::kRef, Isa::kAvx2, Isa::kAvx512,
                                                              Isa::kNeon, Isa::kAvx512Amx),
                                            ::testing::Values(Form::kFloat32, Form::kInt8,
                                                              Form::kBf16)),
                         [](const ::testing::TestParamInfo<std::tuple<Isa, Form>>& param) {
                           return std::string(IsaName(std::get<0>(param.param))) + "_" +
                                  FormName(std::get<1>(param.param));
                         });

class SharedModelAcrossIsas : public ::testing::TestWithParam<Form> {};

TEST_P(SharedModelAcrossIsas,
       SessionsOfEveryIsaRunTogetherOnOneModelAndEachMatchesItsSerialResult) {
  // Every ISA this CPU runs packs the same weights its own way, at the same time; and one
  // Session with the default ISA and threads (kAuto: the best ISA; 1 thread).
  Shared shared(GetParam());
  ASSERT_NE(shared.model(), nullptr);
  std::vector<SessionOptions> configs;
  for (Isa isa : SupportedIsas()) configs.push_back(Options(isa, 2, kMaxHeight, kMaxWidth));
  SessionOptions best;
  best.max_height = kMaxHeight;
  best.max_width = kMaxWidth;
  configs.push_back(best);
  std::vector<std::vector<std::vector<float>>> want;
  for (const SessionOptions& options : configs) {
    want.push_back(shared.SerialOutputs(options.isa));
    ASSERT_EQ(want.back().size(), shared.inputs().size()) << Describe(options);
  }
  constexpr int kPasses = 3;
  std::latch start(static_cast<std::ptrdiff_t>(configs.size()));
  std::vector<std::string> failures(configs.size());
  std::vector<std::thread> threads;
  for (size_t t = 0; t < configs.size(); ++t) {
    threads.emplace_back([&, t] {
      start.arrive_and_wait();
      failures[t] =
          CreateRunAndCompare(shared.model(), configs[t], shared.inputs(), want[t], kPasses, t);
    });
  }
  for (std::thread& thread : threads) thread.join();
  for (size_t t = 0; t < configs.size(); ++t) {
    EXPECT_EQ(failures[t], "") << Describe(configs[t]);
  }
}

INSTANTIATE_TEST_SUITE_P(EveryForm, SharedModelAcrossIsas,
                         ::testing::Values(Form::kFloat32, Form::kInt8, Form::kBf16),
                         [](const ::testing::TestParamInfo<Form>& param) {
                           return std::string(FormName(param.param));
                         });

}  // namespace
}  // namespace sfrt
