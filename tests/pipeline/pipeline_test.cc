// The pipeline with a fake frame source and the bundled 1/16-width demo model.
#include "sfrt/pipeline/pipeline.h"

#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <thread>

#include "pipeline/fake_window.h"
#include "sfrt/camera/rectifier.h"
#include "sfrt/pipeline/io/npy.h"
#include "sfrt/pipeline/io/pfm.h"
#include "sfrt/pipeline/log.h"
#include "sfrt/pipeline/output_sinks.h"
#include "sfrt/pipeline/sink.h"
#include "sfrt/pipeline/visualize.h"
#include "sfrt/session.h"

namespace sfrt::pipeline {
namespace {

namespace fs = std::filesystem;

constexpr int kH = 32;
constexpr int kW = 48;

std::shared_ptr<const Model> DemoModel() {
  auto model =
      Model::LoadFile(std::string(SFRT_SOURCE_DIR) + "/tools/demo/sceneednet-w16-demo.sfrt");
  EXPECT_TRUE(model.ok()) << model.message();
  return model.ok() ? *model : nullptr;
}

// Pair k: seeded noise, so every window differs.
cv::Mat PairImage(int k, int side) {
  cv::Mat m(kH, kW, CV_8UC3);
  cv::RNG rng(static_cast<uint64_t>(1000 + 2 * k + side));
  rng.fill(m, cv::RNG::UNIFORM, 0, 256);
  return m;
}

// Independent path: Preprocessor + a fresh Session on window k's images (default ISA and
// threads), the flow the pipeline must give for that window.
std::vector<float> DirectFlow(const std::shared_ptr<const Model>& model, int k) {
  std::vector<float> flow(static_cast<size_t>(kH) * kW * 3);
  auto params = PreprocessFromMetadata(model->metadata().input);
  EXPECT_TRUE(params.ok());
  auto pre = camera::Preprocessor::Create(*params, kH, kW);
  EXPECT_TRUE(pre.ok());
  SessionOptions so;
  so.max_height = kH;
  so.max_width = kW;
  auto session = Session::Create(model, so);
  EXPECT_TRUE(session.ok());
  if (!params.ok() || !pre.ok() || !session.ok()) return {};
  std::vector<float> input(pre->output_floats());
  EXPECT_TRUE(pre->Run(PairImage(k, 0), PairImage(k, 1), PairImage(k + 1, 0), PairImage(k + 1, 1),
                       input.data(), input.size())
                  .ok());
  EXPECT_TRUE((*session)->Run(input, kH, kW, flow).ok());
  return flow;
}

// Windows (k, k+1) for k < windows; optionally live, failing or raising `stop` after some.
class FakeSource : public FrameSource {
 public:
  explicit FakeSource(int windows) : windows_(windows) {}
  Result<cv::Size> Open() override { return cv::Size(kW, kH); }
  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>& stop) override {
    // Lockstep: window k is read only once window k - 1 has been written (and the pipeline's
    // on-miss state updated), so which size each window runs at does not depend on timing.
    if (done_ != nullptr) {
      const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
      while (done_->load() < next_ && next_ < windows_ && !stop.load() &&
             std::chrono::steady_clock::now() < give_up) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
    }
    if (next_ == fail_at_)
      return Status::Error("fake: frame 'k" + std::to_string(next_) + "' is bad");
    if (next_ == stop_at_ && stop_) {
      stop_signal_->store(SIGTERM);
      stop_->store(true);
    }
    if (next_ >= windows_) return Fetch::kEnd;
    PairImage(next_, 0).copyTo(item->left0);
    PairImage(next_, 1).copyTo(item->right0);
    PairImage(next_ + 1, 0).copyTo(item->left1);
    PairImage(next_ + 1, 1).copyTo(item->right1);
    item->meta.sequence = "seq";
    StampFakeWindow(&item->meta, next_);
    item->meta.continues = continues_ && next_ > 0;
    ++next_;
    return Fetch::kWindow;
  }
  std::string Describe() const override { return "fake"; }
  std::string kind() const override { return "fake"; }
  std::optional<int64_t> total_windows() const override { return windows_; }
  bool live() const override { return live_; }
  void ToJson(nlohmann::json* out) const override { (*out)["fake"] = true; }

  int windows_;
  int next_ = 0;
  bool live_ = false;
  bool continues_ = false;  // say that window k's pair t is window k-1's pair t+1 (it is)
  int fail_at_ = -1;
  int stop_at_ = -1;
  std::atomic<bool>* stop_ = nullptr;
  std::atomic<int>* stop_signal_ = nullptr;
  const std::atomic<int64_t>* done_ = nullptr;  // windows written so far (lockstep), or null
};

class PipelineTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sfrt_pipeline_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    options_.out_dir = dir_.string();
    options_.progress = ProgressMode::kOff;
    options_.model_path = "demo";
  }
  void TearDown() override { fs::remove_all(dir_); }

  nlohmann::json Summary() {
    std::ifstream in(dir_ / "summary.json");
    return nlohmann::json::parse(in);
  }
  std::vector<std::string> Files(const std::string& ext) {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir_)) {
      if (e.path().extension() == ext) out.push_back(e.path().filename().string());
    }
    std::sort(out.begin(), out.end());
    return out;
  }
  bool AnyTempFile() {
    for (const auto& e : fs::directory_iterator(dir_)) {
      if (e.path().filename().string().find(".tmp.") != std::string::npos) return true;
    }
    return false;
  }

  fs::path dir_;
  PipelineOptions options_;
};

TEST_F(PipelineTest, ReplayWritesEveryWindowAndMatchesDirectInference) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(4);
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_EQ(r.frames, 4);
  EXPECT_EQ(r.stopped_by, "end of source");
  EXPECT_EQ(Files(".pfm"), (std::vector<std::string>{"seq_000000.pfm", "seq_000001.pfm",
                                                     "seq_000002.pfm", "seq_000003.pfm"}));
  EXPECT_EQ(Files(".png").size(), 4u);
  EXPECT_FALSE(AnyTempFile());

  for (int k = 0; k < 4; ++k) {
    const std::vector<float> flow = DirectFlow(model, k);
    char name[32];
    std::snprintf(name, sizeof(name), "seq_%06d.pfm", k);
    auto written = io::ReadPfm((dir_ / name).string());
    ASSERT_TRUE(written.ok()) << written.message();
    ASSERT_EQ(written->data.size(), flow.size());
    for (size_t i = 0; i < flow.size(); ++i)
      ASSERT_EQ(written->data[i], flow[i]) << name << " " << i;
  }

  nlohmann::json j = Summary();
  EXPECT_EQ(j["frames"]["written"], 4);
  EXPECT_EQ(j["frames"]["total"], 4);
  EXPECT_EQ(j["completed"], true);
  EXPECT_EQ(j["queue_policy"], "block");
  EXPECT_EQ(j["drops"]["preprocess"], 0);
  EXPECT_EQ(j["latency_ms"]["end_to_end"]["count"], 4);
  for (const char* stage : {"source", "preprocess", "infer", "output", "end_to_end"}) {
    const auto& p = j["latency_ms"][stage];
    EXPECT_LE(p["p50"].get<double>(), p["p90"].get<double>()) << stage;
    EXPECT_LE(p["p90"].get<double>(), p["p99"].get<double>()) << stage;
    EXPECT_LE(p["p99"].get<double>(), p["max"].get<double>()) << stage;
  }
}

// An int8 model: the preprocess stage writes the uint8 input straight from the pixels and the
// infer stage runs it (Session::RunQuantized); every window's flow is the float32 input's, bit
// for bit (DirectFlow quantises a float32 input in the session), and the summary says which.
TEST_F(PipelineTest, AnInt8ModelIsFedUint8StraightFromThePixelsWithTheFloatInputsFlow) {
  auto loaded =
      Model::LoadFile(std::string(SFRT_SOURCE_DIR) + "/models/sceneednet-default-int8.sfrt");
  ASSERT_TRUE(loaded.ok()) << loaded.message();
  const std::shared_ptr<const Model> model = *loaded;
  for (bool quantized : {true, false}) {
    SCOPED_TRACE(quantized ? "uint8 input" : "float32 input");
    options_.quantized_input = quantized;
    options_.height = kH;  // the model records its traced size; run at the fake frames'
    options_.width = kW;
    FakeSource source(3);
    PipelineResult r = RunPipeline(model, &source, options_);
    ASSERT_TRUE(r.status.ok()) << r.status.message();
    EXPECT_EQ(Summary()["input_type"], quantized ? "uint8" : "float32");
    for (int k = 0; k < 3; ++k) {
      char name[32];
      std::snprintf(name, sizeof(name), "seq_%06d.pfm", k);
      auto written = io::ReadPfm((dir_ / name).string());
      ASSERT_TRUE(written.ok()) << written.message();
      EXPECT_EQ(written->data, DirectFlow(model, k)) << name;
    }
  }
}

TEST_F(PipelineTest, NewestWinsNeverGoesBackInTimeAndAccountsForEveryWindow) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(300);
  source.live_ = true;  // kNewestWins by default
  options_.write_png = false;
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  nlohmann::json j = Summary();
  EXPECT_EQ(j["queue_policy"], "newest-wins");
  const int64_t read = j["frames"]["read"];
  const int64_t written = j["frames"]["written"];
  const int64_t dropped = j["drops"]["preprocess"].get<int64_t>() +
                          j["drops"]["infer"].get<int64_t>() + j["drops"]["output"].get<int64_t>();
  EXPECT_EQ(read, 300);
  EXPECT_EQ(written + dropped + j["drops"]["discarded_at_stop"].get<int64_t>(), read);
  // The source makes a window in microseconds, the network needs far longer: windows are
  // dropped rather than queued.
  EXPECT_GT(dropped, 0);
  // Written frames are in capture order (names sort by frame number), the last one included.
  std::vector<std::string> files = Files(".pfm");
  EXPECT_EQ(static_cast<int64_t>(files.size()), written);
  EXPECT_EQ(files.back(), "seq_000299.pfm");
}

TEST_F(PipelineTest, StopRequestFinishesWindowsInFlightAndSaysSo) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  std::atomic<bool> stop{false};
  std::atomic<int> sig{0};
  FakeSource source(200);
  source.stop_at_ = 3;
  source.stop_ = &stop;
  source.stop_signal_ = &sig;
  options_.stop = &stop;
  options_.stop_signal = &sig;
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_EQ(r.stopped_by, "SIGTERM");
  nlohmann::json j = Summary();
  EXPECT_EQ(j["stopped_by"], "SIGTERM");
  EXPECT_EQ(j["completed"], false);
  const int64_t written = j["frames"]["written"];
  EXPECT_GE(written, 3);  // everything read before the stop was finished (queue policy block)
  EXPECT_LT(written, 200);
  EXPECT_EQ(written, j["frames"]["read"].get<int64_t>());
  EXPECT_FALSE(AnyTempFile());
  for (const std::string& f : Files(".pfm")) {
    auto pfm = io::ReadPfm((dir_ / f).string());
    EXPECT_TRUE(pfm.ok()) << pfm.message();
  }
}

TEST_F(PipelineTest, SourceErrorEndsTheRunWithTheErrorInTheSummary) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(10);
  source.fail_at_ = 2;
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_FALSE(r.status.ok());
  EXPECT_NE(r.status.message().find("frame 'k2' is bad"), std::string::npos);
  nlohmann::json j = Summary();
  EXPECT_EQ(j["stopped_by"], "error");
  EXPECT_NE(j["error"].get<std::string>().find("frame 'k2' is bad"), std::string::npos);
  EXPECT_EQ(j["frames"]["written"], 2);  // the windows read before the error are written
}

TEST_F(PipelineTest, MaxFramesStopsAfterThatManyFrames) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(20);
  options_.max_frames = 3;
  options_.flow_format = FlowFormat::kNpy;
  options_.write_png = false;
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_EQ(r.frames, 3);
  EXPECT_EQ(r.stopped_by, "max-frames");
  EXPECT_EQ(Files(".npy").size(), 3u);
}

// ---- latency.on_miss: smaller-input
constexpr int kFbH = 20;  // fallback size: smaller in both dimensions, another aspect ratio
constexpr int kFbW = 36;

// The flow of window k computed directly: the window's images resized to height x width the way
// the pipeline's resize-only path does, preprocessed, and run by a fresh session planned for
// exactly that size.
std::vector<float> DirectFlow(const std::shared_ptr<const Model>& model, int k, int height,
                              int width) {
  auto params = PreprocessFromMetadata(model->metadata().input);
  EXPECT_TRUE(params.ok());
  auto pre = camera::Preprocessor::Create(*params, height, width);
  EXPECT_TRUE(pre.ok());
  auto rect = camera::StereoRectifier::CreateResizeOnly(cv::Size(kW, kH), cv::Size(width, height));
  EXPECT_TRUE(rect.ok());
  cv::Mat l0, r0, l1, r1;
  EXPECT_TRUE(rect->Apply(PairImage(k, 0), PairImage(k, 1), &l0, &r0).ok());
  EXPECT_TRUE(rect->Apply(PairImage(k + 1, 0), PairImage(k + 1, 1), &l1, &r1).ok());
  std::vector<float> input(pre->output_floats());
  EXPECT_TRUE(pre->Run(l0, r0, l1, r1, input.data(), input.size()).ok());
  SessionOptions so;
  so.max_height = height;
  so.max_width = width;
  auto session = Session::Create(model, so);
  EXPECT_TRUE(session.ok());
  std::vector<float> flow(static_cast<size_t>(height) * width * 3);
  EXPECT_TRUE((*session)->Run(input, height, width, flow).ok());
  return flow;
}

std::string Stem(int k) {
  char name[32];
  std::snprintf(name, sizeof(name), "seq_%06d", k);
  return name;
}

class SmallerInputTest : public PipelineTest {
 protected:
  void SetUp() override {
    PipelineTest::SetUp();
    options_.on_miss = config::MissAction::kSmallerInput;
    options_.smaller_input_on_miss = {kFbH, kFbW};
    options_.after_window = [this](const FrameMeta&) { ++done_; };
  }
  // Height and width of each written window's flow file, in window order.
  std::vector<std::pair<int, int>> FlowSizes(int windows) {
    std::vector<std::pair<int, int>> sizes;
    for (int k = 0; k < windows; ++k) {
      auto pfm = io::ReadPfm((dir_ / (Stem(k) + ".pfm")).string());
      EXPECT_TRUE(pfm.ok()) << pfm.message();
      sizes.emplace_back(pfm.ok() ? pfm->height : -1, pfm.ok() ? pfm->width : -1);
    }
    return sizes;
  }
  std::atomic<int64_t> done_{0};
};

TEST_F(SmallerInputTest, ImpossibleBudgetRunsEveryLaterWindowAtTheFallbackSizeLikeADirectSession) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(5);
  source.done_ = &done_;
  options_.budget_ms = 0.001;  // every window misses
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  ASSERT_EQ(r.frames, 5);
  const std::pair<int, int> full{kH, kW}, fb{kFbH, kFbW};
  EXPECT_EQ(FlowSizes(5), (std::vector<std::pair<int, int>>{full, fb, fb, fb, fb}));
  // The numbers, not only the shapes: bit-identical to sessions planned for each size (the
  // runtime is deterministic for a given ISA and thread count; session_test checks that a
  // session planned larger gives the same result).
  for (int k = 0; k < 5; ++k) {
    const int h = k == 0 ? kH : kFbH, w = k == 0 ? kW : kFbW;
    const std::vector<float> want = DirectFlow(model, k, h, w);
    auto got = io::ReadPfm((dir_ / (Stem(k) + ".pfm")).string());
    ASSERT_TRUE(got.ok()) << got.message();
    ASSERT_EQ(got->data.size(), want.size()) << k;
    for (size_t i = 0; i < want.size(); ++i) ASSERT_EQ(got->data[i], want[i]) << k << " " << i;
  }
  // The visualisation keeps one size whatever size the flow was computed at.
  const cv::Mat first = cv::imread((dir_ / (Stem(0) + ".png")).string());
  ASSERT_FALSE(first.empty());
  for (int k = 1; k < 5; ++k) {
    const cv::Mat png = cv::imread((dir_ / (Stem(k) + ".png")).string());
    EXPECT_EQ(png.size(), first.size()) << k;
  }
  nlohmann::json d = Summary()["deadline"];
  EXPECT_EQ(d["on_miss"], "smaller-input");
  EXPECT_EQ(d["misses"], 5);
  EXPECT_EQ(d["fallback_size"], nlohmann::json::array({kFbH, kFbW}));
  EXPECT_EQ(d["recover_after_frames"], 30);
  EXPECT_EQ(d["fallback_entries"], 1);
  EXPECT_EQ(d["recoveries"], 0);
  EXPECT_EQ(d["frames_at_fallback_size"], 4);
  EXPECT_EQ(r.frames_at_fallback_size, 4);
  EXPECT_EQ(r.fallback_entries, 1);
}

TEST_F(SmallerInputTest, GenerousBudgetNeverSwitches) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(4);
  options_.budget_ms = 1e7;  // no window takes hours
  options_.write_png = false;
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  const std::pair<int, int> full{kH, kW};
  EXPECT_EQ(FlowSizes(4), (std::vector<std::pair<int, int>>(4, full)));
  nlohmann::json d = Summary()["deadline"];
  EXPECT_EQ(d["misses"], 0);
  EXPECT_EQ(d["fallback_entries"], 0);
  EXPECT_EQ(d["frames_at_fallback_size"], 0);
}

TEST_F(SmallerInputTest, RecoversAfterNInBudgetFallbackWindowsAndAMissAtFallbackRestartsTheCount) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(11);
  source.done_ = &done_;
  // "In budget" decided by the test seam, not by the clock: misses at windows 0, 3 and 8.
  options_.miss_verdict = [](const FrameMeta& m, bool) {
    return m.window == 0 || m.window == 3 || m.window == 8;
  };
  options_.recover_after = 3;
  options_.write_png = false;
  options_.flow_format = FlowFormat::kNpy;
  options_.latency_log = (dir_ / "latency.csv").string();
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  ASSERT_EQ(r.frames, 11);
  // 0: full, miss -> fallback. 1, 2: in budget (count 2). 3: miss at fallback, count restarts.
  // 4, 5, 6: three in budget -> full size from 7. 8: miss at full size -> fallback again.
  const std::vector<bool> want_fb = {false, true,  true,  true, true, true,
                                     true,  false, false, true, true};
  for (int k = 0; k < 11; ++k) {
    auto npy = io::ReadNpy((dir_ / (Stem(k) + ".npy")).string());
    ASSERT_TRUE(npy.ok()) << npy.message();
    const std::vector<int64_t> want =
        want_fb[k] ? std::vector<int64_t>{kFbH, kFbW, 3} : std::vector<int64_t>{kH, kW, 3};
    EXPECT_EQ(npy->shape, want) << "window " << k;
  }
  // The latency log says which size each window ran at.
  std::ifstream log(dir_ / "latency.csv");
  std::string line;
  ASSERT_TRUE(std::getline(log, line));
  EXPECT_EQ(line,
            "window,source_ms,preprocess_ms,infer_ms,output_ms,end_to_end_ms,input_height,"
            "input_width,done_monotonic_ms");
  double previous_done_ms = 0;
  for (int k = 0; k < 11; ++k) {
    ASSERT_TRUE(std::getline(log, line)) << k;
    const size_t last_comma = line.rfind(',');
    const std::string size_columns = line.substr(0, last_comma);
    const std::string want_size = want_fb[k] ? ",20,36" : ",32,48";
    EXPECT_EQ(size_columns.substr(size_columns.size() - want_size.size()), want_size) << line;
    // Completion times are on the steady clock and increase window by window.
    const double done_ms = std::stod(line.substr(last_comma + 1));
    EXPECT_GT(done_ms, previous_done_ms) << line;
    previous_done_ms = done_ms;
  }
  nlohmann::json d = Summary()["deadline"];
  EXPECT_EQ(d["misses"], 3);
  EXPECT_EQ(d["recover_after_frames"], 3);
  EXPECT_EQ(d["fallback_entries"], 2);
  EXPECT_EQ(d["recoveries"], 1);
  EXPECT_EQ(d["frames_at_fallback_size"], 8);
}

TEST_F(SmallerInputTest, FallbackNotSmallerThanTheInputSizeIsAnErrorNamingBothSizes) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(2);
  options_.on_miss = config::MissAction::kSmallerInput;
  options_.smaller_input_on_miss = {kH, kW + 8};
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_FALSE(r.status.ok());
  EXPECT_NE(r.status.message().find("fallback size 32x56"), std::string::npos)
      << r.status.message();
  EXPECT_NE(r.status.message().find("model input size 32x48"), std::string::npos)
      << r.status.message();
  EXPECT_EQ(r.frames, 0);
}

TEST_F(PipelineTest, SummaryOffWritesNoSummaryJsonButEveryFrame) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(3);
  options_.write_summary = false;
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_EQ(r.frames, 3);
  EXPECT_EQ(r.summary_path, "");
  EXPECT_FALSE(fs::exists(dir_ / "summary.json"));
  EXPECT_EQ(Files(".pfm").size(), 3u);
}

// The summary is a sink's business like every output: each sink's Finished() receives the
// document summary.json holds (with write_summary off too), after its Stop(); a setup that fails
// still reports why; a Finished() that fails fails the run, naming the sink.
TEST_F(PipelineTest, EverySinkReceivesTheRunsSummaryEvenWhenTheRunNeverStarted) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  class Report : public FlowSink {
   public:
    std::string name() const override { return "report"; }
    Status Start() override { return fail_start ? Status::Error("no link") : Status::Ok(); }
    Status Write(const FlowFrame&) override { return Status::Ok(); }
    Status Stop() override {
      stopped = true;
      return Status::Ok();
    }
    Status Finished(const nlohmann::json& summary) override {
      finished_after_stop = stopped;
      got = summary;
      return fail ? Status::Error("link down") : Status::Ok();
    }
    bool stopped = false;
    bool finished_after_stop = false;
    bool fail = false;
    bool fail_start = false;
    nlohmann::json got;
  } sink;
  options_.sinks.push_back(&sink);
  options_.write_summary = false;
  FakeSource source(3);
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_TRUE(sink.finished_after_stop);
  EXPECT_EQ(sink.got["frames"]["written"], 3);
  EXPECT_EQ(sink.got["stopped_by"], "end of source");
  EXPECT_EQ(sink.got["sinks"].back()["name"], "report");
  EXPECT_FALSE(fs::exists(dir_ / "summary.json"));

  // With the file as well: the same document, byte for byte what the sink saw.
  options_.write_summary = true;
  FakeSource again(3);
  sink = Report();
  r = RunPipeline(model, &again, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_EQ(r.summary_path, (dir_ / "summary.json").string());
  EXPECT_EQ(Summary(), sink.got);

  // A run whose setup fails (here the sink's own Start()) still reports why.
  FakeSource third(3);
  sink = Report();
  sink.fail_start = true;
  r = RunPipeline(model, &third, options_);
  EXPECT_FALSE(r.started);
  EXPECT_FALSE(sink.got.is_null());
  EXPECT_EQ(sink.got["stopped_by"], "error");
  EXPECT_EQ(sink.got["error"], r.status.message());

  // A failing Finished() fails a run that had no error, naming the sink.
  FakeSource fourth(3);
  sink = Report();
  sink.fail = true;
  r = RunPipeline(model, &fourth, options_);
  EXPECT_EQ(r.status.message(), "sink 'report': link down");
}

// A robot program's view: with no file outputs, a callback sink receives every window in order,
// without a copy (the views point into the pipeline's buffers), with the flow a direct Session
// gives, the sequence numbers and capture times, and nothing lands in the output directory but
// the summary.
TEST_F(PipelineTest, CallbackSinkReceivesEveryFlowFrameInOrderMatchingDirectInference) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(4);
  options_.write_flow = false;
  options_.write_png = false;
  struct Seen {
    int64_t frame0, frame1, capture1;
    int height, width, channels;
    std::vector<float> flow;
    bool image_at_model_size;
  };
  std::vector<Seen> seen;
  bool started = false, stopped = false;
  class RecordingSink : public FlowSink {
   public:
    RecordingSink(std::vector<Seen>* seen, bool* started, bool* stopped)
        : seen_(seen), started_(started), stopped_(stopped) {}
    std::string name() const override { return "recording"; }
    Status Start() override {
      *started_ = true;
      return Status::Ok();
    }
    Status Write(const FlowFrame& f) override {
      seen_->push_back({f.meta->frame0, f.meta->frame1, f.meta->capture_ns[1], f.height, f.width,
                        f.channels, std::vector<float>(f.flow.begin(), f.flow.end()),
                        f.left_image->rows == kH && f.left_image->cols == kW});
      return Status::Ok();
    }
    Status Stop() override {
      *stopped_ = true;
      return Status::Ok();
    }

   private:
    std::vector<Seen>* seen_;
    bool* started_;
    bool* stopped_;
  } sink(&seen, &started, &stopped);
  options_.sinks.push_back(&sink);
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_TRUE(started);
  EXPECT_TRUE(stopped);
  ASSERT_EQ(seen.size(), 4u);
  EXPECT_TRUE(Files(".pfm").empty());
  EXPECT_TRUE(Files(".png").empty());

  for (int k = 0; k < 4; ++k) {
    SCOPED_TRACE(k);
    EXPECT_EQ(seen[k].frame0, k);
    EXPECT_EQ(seen[k].frame1, k + 1);
    EXPECT_GT(seen[k].capture1, 0);
    EXPECT_EQ(seen[k].height, kH);
    EXPECT_EQ(seen[k].width, kW);
    EXPECT_EQ(seen[k].channels, 3);
    EXPECT_TRUE(seen[k].image_at_model_size);
    const std::vector<float> flow = DirectFlow(model, k);
    EXPECT_EQ(seen[k].flow, flow);
  }
}

// A program composes the pipeline's own outputs itself: two flow formats in two directories,
// PNGs and a latency log, with no output from the options. Each window's files hold the flow a
// direct Session gives; every sink's Completed() sees the window after the last Write() with its
// final end to end, and the log has one line per window.
TEST_F(PipelineTest, OutputSinksComposedByTheCallerWriteEveryWindowAndLogItsFinalTimes) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  options_.write_flow = false;
  options_.write_png = false;
  fs::create_directories(dir_ / "npy");
  fs::create_directories(dir_ / "pfm");
  FlowFileSink npy((dir_ / "npy").string(), config::FlowFormat::kNpy);
  FlowFileSink pfm((dir_ / "pfm").string(), config::FlowFormat::kPfm);
  FlowRenderer renderer(VisualizerOptions{});
  PngSink png(dir_.string(), &renderer);
  LatencyLogSink log((dir_ / "latency.csv").string());
  class TimingSink : public FlowSink {
   public:
    std::string name() const override { return "timing"; }
    Status Write(const FlowFrame& f) override {
      write_ns = f.meta->stage_ns[3][1];  // not yet set while the sinks write
      return Status::Ok();
    }
    Status Completed(const WindowRecord& r) override {
      const FrameMeta& m = *r.meta;
      EXPECT_EQ(write_ns, 0);
      EXPECT_GT(m.stage_ns[3][1], 0);
      EXPECT_DOUBLE_EQ(r.end_to_end_ms,
                       static_cast<double>(m.stage_ns[3][1] - m.capture_ns[1]) / 1e6);
      EXPECT_TRUE(r.step_ns.empty());  // no profiler
      ++completed;
      return Status::Ok();
    }
    int64_t write_ns = -1;
    int completed = 0;
  } timing;
  options_.sinks = {&npy, &pfm, &png, &log, &timing};
  FakeSource source(3);
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  ASSERT_EQ(r.frames, 3);
  EXPECT_EQ(timing.completed, 3);
  EXPECT_TRUE(Files(".pfm").empty());  // nothing from the options
  ASSERT_EQ(Files(".png").size(), 3u);
  for (int k = 0; k < 3; ++k) {
    SCOPED_TRACE(k);
    const std::string stem = "seq_00000" + std::to_string(k);
    const std::vector<float> want = DirectFlow(model, k);
    Result<io::NpyArray> a = io::ReadNpy((dir_ / "npy" / (stem + ".npy")).string());
    ASSERT_TRUE(a.ok()) << a.message();
    EXPECT_EQ(a->shape, (std::vector<int64_t>{kH, kW, 3}));
    EXPECT_EQ(a->data, want);
    Result<io::PfmImage> b = io::ReadPfm((dir_ / "pfm" / (stem + ".pfm")).string());
    ASSERT_TRUE(b.ok()) << b.message();
    EXPECT_EQ(b->data, want);
    const cv::Mat picture = cv::imread((dir_ / (stem + ".png")).string());
    EXPECT_FALSE(picture.empty());
  }
  std::ifstream in(dir_ / "latency.csv");
  std::string line;
  int lines = 0;
  while (std::getline(in, line)) ++lines;
  EXPECT_EQ(lines, 1 + 3);
}

// picture_queue: the PNGs are encoded on a thread of their own; every window still gets its
// picture (block policy for files) by the time RunPipeline returns, and the summary lists the
// queued sink with its encoder times.
TEST_F(PipelineTest, QueuedPicturesAreAllWrittenAndMeasuredApart) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  options_.picture_queue = 2;
  FakeSource source(5);
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_EQ(r.frames, 5);
  EXPECT_EQ(Files(".png").size(), 5u);
  EXPECT_EQ(Files(".pfm").size(), 5u);
  EXPECT_TRUE(r.pictures_queued);
  EXPECT_EQ(r.pictures_ms.count, 5u);
  EXPECT_EQ(r.pictures_dropped, 0u);
  const nlohmann::json sinks = Summary()["sinks"];
  ASSERT_EQ(sinks.size(), 3u);
  EXPECT_EQ(sinks[0]["name"], "flow files");
  EXPECT_EQ(sinks[1]["name"], "pictures");
  EXPECT_EQ(sinks[1]["inner"], nlohmann::json::array({"png"}));
  EXPECT_EQ(sinks[1]["windows"], 5);
  EXPECT_EQ(sinks[2]["name"], "window index");
}

// A source that says its windows continue one another: each pair is rectified once (pair t of
// window k is window k-1's rectified pair t+1), and every window's flow is still the one a
// direct Session gives on its own four images.
TEST_F(PipelineTest, ContinuingWindowsRectifyEachPairOnceAndKeepTheirFlow) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(4);
  source.continues_ = true;
  options_.write_png = false;
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  ASSERT_EQ(r.frames, 4);
  const nlohmann::json pre = Summary()["preprocess"];
  EXPECT_EQ(pre["pairs_rectified"], 5);  // 4 windows, 5 pairs
  EXPECT_EQ(pre["pairs_reused"], 3);
  for (int k = 0; k < 4; ++k) {
    SCOPED_TRACE(k);
    Result<io::PfmImage> got =
        io::ReadPfm((dir_ / ("seq_00000" + std::to_string(k) + ".pfm")).string());
    ASSERT_TRUE(got.ok()) << got.message();
    EXPECT_EQ(got->data, DirectFlow(model, k));
  }
}

// A sink that fails: under kSkip the window is dropped everywhere (its flow file is removed and
// the sinks before it retract it) and the run goes on; under kStop the run ends naming the sink.
TEST_F(PipelineTest, FailingSinkDropsTheWindowEverywhereOrStopsTheRunNamingTheSink) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  class CountingSink : public FlowSink {
   public:
    std::string name() const override { return "counting"; }
    Status Write(const FlowFrame&) override {
      ++writes;
      return Status::Ok();
    }
    void Retract() override { ++retracts; }
    int writes = 0, retracts = 0;
  } first;
  CallbackSink failing(
      [](const FlowFrame& f) {
        return f.meta->frame0 == 1 ? Status::Error("planner queue full") : Status::Ok();
      },
      "planner");
  options_.write_png = false;
  options_.sinks = {&first, &failing};
  options_.on_output_error = OutputErrorPolicy::kSkip;
  {
    FakeSource source(3);
    PipelineResult r = RunPipeline(model, &source, options_);
    ASSERT_TRUE(r.status.ok()) << r.status.message();
    EXPECT_EQ(r.frames, 2);
    EXPECT_EQ(r.output_errors, 1);
    EXPECT_EQ(first.writes, 3);
    EXPECT_EQ(first.retracts, 1);
    EXPECT_EQ(Files(".pfm"), (std::vector<std::string>{"seq_000000.pfm", "seq_000002.pfm"}));
    const nlohmann::json skipped = Summary()["output_errors"]["skipped"];
    ASSERT_EQ(skipped.size(), 1u);
    EXPECT_EQ(skipped[0]["error"], "sink 'planner': planner queue full");
  }
  options_.on_output_error = OutputErrorPolicy::kStop;
  FakeSource source(3);
  PipelineResult r = RunPipeline(model, &source, options_);
  EXPECT_FALSE(r.status.ok());
  EXPECT_EQ(r.status.message(), "sink 'planner': planner queue full");
  EXPECT_EQ(r.frames, 1);
}

// The library's messages go to PipelineOptions::log, not to stderr: a skipped window's warning
// and the progress lines reach the program's own log.
TEST_F(PipelineTest, WarningsAndProgressGoToTheProgramsLogNotToStderr) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  class RecordingLog : public LogSink {
   public:
    void Write(LogLevel level, std::string_view tag, std::string_view text) override {
      std::lock_guard<std::mutex> lock(mu);
      lines.push_back(std::string(LogLevelName(level)) + " " + std::string(tag) + ": " +
                      std::string(text));
    }
    void Progress(std::string_view, bool) override {
      std::lock_guard<std::mutex> lock(mu);
      ++progress;
    }
    std::mutex mu;
    std::vector<std::string> lines;
    int progress = 0;
  } log;
  CallbackSink failing(
      [](const FlowFrame& f) {
        return f.meta->frame0 == 1 ? Status::Error("planner queue full") : Status::Ok();
      },
      "planner");
  options_.write_png = false;
  options_.sinks = {&failing};
  options_.on_output_error = OutputErrorPolicy::kSkip;
  options_.progress = ProgressMode::kLines;
  options_.progress_every = 1;
  options_.log = &log;
  FakeSource source(3);
  testing::internal::CaptureStderr();
  PipelineResult r = RunPipeline(model, &source, options_);
  const std::string err = testing::internal::GetCapturedStderr();
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  EXPECT_EQ(err, "");
  EXPECT_EQ(log.lines, (std::vector<std::string>{
                           "warn warning: window seq_000001 skipped: sink 'planner': planner "
                           "queue full"}));
  EXPECT_EQ(log.progress, 2);  // one per written window (the final line is not repeated)
}

// A sink whose Start() fails ends the run before any stage starts, naming the sink.
TEST_F(PipelineTest, SinkThatCannotStartEndsTheRunBeforeTheFirstFrame) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  class NoStart : public FlowSink {
   public:
    std::string name() const override { return "robot-link"; }
    Status Start() override { return Status::Error("socket refused"); }
    Status Write(const FlowFrame&) override {
      ++writes;
      return Status::Ok();
    }
    int writes = 0;
  } sink;
  options_.sinks.push_back(&sink);
  FakeSource source(3);
  PipelineResult r = RunPipeline(model, &source, options_);
  EXPECT_FALSE(r.started);
  EXPECT_EQ(r.status.message(), "sink 'robot-link': socket refused");
  EXPECT_EQ(sink.writes, 0);
  EXPECT_TRUE(Files(".pfm").empty());
}

// The end to end latency split into consecutive parts (LatencyPart): a live window's parts from
// its capture, dequeue, pairing and conversion times and the stage times; a file window's first
// three parts are 0. Each window's parts add up to its end to end exactly.
TEST(SplitLatency, PartsAreConsecutiveAndAddUpToTheEndToEnd) {
  FrameMeta m;
  const int64_t ms = 1'000'000;
  m.capture_ns[1] = 100 * ms;
  m.dequeue_ns = 101 * ms;
  m.paired_ns = 103 * ms;
  m.converted_ns = 106 * ms;
  const int64_t stages[4][2] = {
      {90 * ms, 110 * ms}, {115 * ms, 121 * ms}, {128 * ms, 136 * ms}, {145 * ms, 155 * ms}};
  for (int st = 0; st < 4; ++st) {
    m.stage_ns[st][0] = stages[st][0];
    m.stage_ns[st][1] = stages[st][1];
  }
  double parts[kLatencyParts];
  SplitLatency(m, parts);
  const double want[kLatencyParts] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  double sum = 0;
  for (int p = 0; p < kLatencyParts; ++p) {
    EXPECT_DOUBLE_EQ(parts[p], want[p]) << LatencyPartName(static_cast<LatencyPart>(p));
    sum += parts[p];
  }
  EXPECT_DOUBLE_EQ(sum, 55.0);  // output end 155 ms - capture 100 ms
  EXPECT_STREQ(LatencyPartName(LatencyPart::kCaptureToDequeue), "capture_to_dequeue");
  EXPECT_STREQ(LatencyPartName(LatencyPart::kOutput), "output");

  m.dequeue_ns = m.paired_ns = m.converted_ns = 0;  // a file: captured when the read ended
  m.capture_ns[1] = 104 * ms;
  SplitLatency(m, parts);
  EXPECT_EQ(parts[0], 0);
  EXPECT_EQ(parts[1], 0);
  EXPECT_EQ(parts[2], 0);
  EXPECT_DOUBLE_EQ(parts[3], 6.0);
}

// summary.json carries the split for every part, with the p50 sum beside the end-to-end p50.
TEST_F(PipelineTest, SummaryAttributesTheEndToEndToNamedParts) {
  auto model = DemoModel();
  ASSERT_TRUE(model);
  FakeSource source(5);
  PipelineResult r = RunPipeline(model, &source, options_);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  const nlohmann::json a = Summary()["latency_attribution_ms"];
  ASSERT_TRUE(a.is_object()) << Summary().dump();
  double sum = 0;
  for (int p = 0; p < kLatencyParts; ++p) {
    const char* name = LatencyPartName(static_cast<LatencyPart>(p));
    ASSERT_TRUE(a["parts"].contains(name)) << name;
    EXPECT_EQ(a["parts"][name]["count"], 5) << name;
    EXPECT_GE(a["parts"][name]["p50"].get<double>(), 0) << name;
    sum += a["parts"][name]["p50"].get<double>();
  }
  EXPECT_NEAR(a["sum_of_p50"].get<double>(), sum, 1e-9);
  EXPECT_EQ(a["end_to_end_p50"].get<double>(), r.end_to_end.p50);
  // A file source: nothing is dequeued, paired or converted.
  EXPECT_EQ(a["parts"]["capture_to_dequeue"]["max"], 0);
  EXPECT_EQ(a["parts"]["convert"]["max"], 0);
}

TEST(PreprocessFromMetadata, CopiesTheModelsPreprocessing) {
  InputDesc d;
  d.channels = 12;
  d.image_order = {"right0", "left0", "right1", "left1"};
  d.color_order = "RGB";
  d.scale = 0.5f;
  d.mean[1] = 3;
  d.std[2] = 4;
  auto p = PreprocessFromMetadata(d);
  ASSERT_TRUE(p.ok()) << p.message();
  EXPECT_EQ(p->image_order[0], camera::ImageSlot::kRight0);
  EXPECT_EQ(p->image_order[3], camera::ImageSlot::kLeft1);
  EXPECT_EQ(p->color_order, camera::ColorOrder::kRGB);
  EXPECT_EQ(p->scale, 0.5f);
  EXPECT_EQ(p->mean[1], 3.0f);
  EXPECT_EQ(p->std[2], 4.0f);
  d.color_order = "YUV";
  auto bad = PreprocessFromMetadata(d);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.message().find("color order 'YUV'"), std::string::npos);
}

TEST(Visualizer, ColoursDirectionByHueAndZByADivergingMap) {
  cv::Mat left(4, 4, CV_8UC3, cv::Scalar(10, 20, 30));
  std::vector<float> flow(4 * 4 * 3, 0.0f);
  flow[0] = 2.0f;       // pixel (0,0): +X at full scale, Z = 0
  flow[3 + 2] = -1.0f;  // pixel (0,1): Z negative, the largest |Z|
  flow[6 + 2] = 0.5f;   // pixel (0,2): Z positive, half scale
  Visualizer vis;
  cv::Mat canvas;
  vis.Render(left, flow.data(), 3, "t", &canvas);
  ASSERT_EQ(canvas.size(), vis.layout().canvas);  // panels at the top left, legend below
  ASSERT_GE(canvas.cols, 12);
  EXPECT_EQ(canvas.at<cv::Vec3b>(0, 0), cv::Vec3b(10, 20, 30));  // the left image
  EXPECT_EQ(canvas.at<cv::Vec3b>(0, 4), cv::Vec3b(0, 0, 255));   // +X: red, full value
  EXPECT_EQ(canvas.at<cv::Vec3b>(1, 4), cv::Vec3b(0, 0, 0));     // no motion: black
  EXPECT_EQ(canvas.at<cv::Vec3b>(0, 8), DivergingColor(0.0));    // Z = 0
  EXPECT_EQ(canvas.at<cv::Vec3b>(0, 9), DivergingColor(-1.0));   // Z = -max
  EXPECT_EQ(canvas.at<cv::Vec3b>(0, 10), DivergingColor(0.5));   // Z = max / 2
  EXPECT_EQ(DivergingColor(0.0), cv::Vec3b(255, 255, 255));
  const cv::Vec3b cold = DivergingColor(-1.0), warm = DivergingColor(1.0);
  EXPECT_GT(cold[0], cold[2]);  // blue end
  EXPECT_GT(warm[2], warm[0]);  // red end
  EXPECT_DOUBLE_EQ(vis.last_xy_scale(), 2.0);
  EXPECT_DOUBLE_EQ(vis.last_z_scale(), 1.0);
}

}  // namespace
}  // namespace sfrt::pipeline

namespace sfrt::pipeline {
namespace {

ModelMetadata TracedAt(int height, int width, TrainingState training) {
  ModelMetadata m;
  m.input.traced_height = height;
  m.input.traced_width = width;
  m.training = training;
  return m;
}

TEST(ChooseInputSize, WithoutSizeATrainedModelRunsAtTheSizeItRecords) {
  PipelineOptions o;
  Result<InputSizeChoice> c =
      ChooseInputSize(o, TracedAt(96, 128, TrainingState::kTrained), 540, 720);
  ASSERT_TRUE(c.ok()) << c.message();
  EXPECT_EQ(c->height, 96);
  EXPECT_EQ(c->width, 128);
  EXPECT_NE(c->reason.find("the size the trained model records"), std::string::npos) << c->reason;
  EXPECT_TRUE(c->aspect_note.empty());  // 720/540 is 128/96
}

TEST(ChooseInputSize, WithoutSizeAModelNotMarkedTrainedOrUntracedRunsAtTheFramesSize) {
  PipelineOptions o;
  Result<InputSizeChoice> untrained =
      ChooseInputSize(o, TracedAt(128, 224, TrainingState::kUntrained), 120, 160);
  ASSERT_TRUE(untrained.ok());
  EXPECT_EQ(untrained->height, 120);
  EXPECT_EQ(untrained->width, 160);
  Result<InputSizeChoice> untraced =
      ChooseInputSize(o, TracedAt(0, 0, TrainingState::kTrained), 120, 160);
  ASSERT_TRUE(untraced.ok());
  EXPECT_EQ(untraced->height, 120);
  EXPECT_NE(untraced->reason.find("records none"), std::string::npos) << untraced->reason;
  Result<InputSizeChoice> unknown =  // exported without --training-state: origin unknown
      ChooseInputSize(o, TracedAt(128, 224, TrainingState::kUnknown), 120, 160);
  ASSERT_TRUE(unknown.ok());
  EXPECT_EQ(unknown->width, 160);
}

TEST(ChooseInputSize, ASizeOfTheInverseAspectIsRefusedWithTheSwapUnlessAllowed) {
  PipelineOptions o;
  o.height = 128;  // WxH for 96x128 on 192x256 frames
  o.width = 96;
  const ModelMetadata m = TracedAt(96, 128, TrainingState::kTrained);
  Result<InputSizeChoice> refused = ChooseInputSize(o, m, 192, 256);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.message().find("did you mean 96x128 (HxW)?"), std::string::npos)
      << refused.message();
  o.allow_aspect_change = true;
  Result<InputSizeChoice> allowed = ChooseInputSize(o, m, 192, 256);
  ASSERT_TRUE(allowed.ok());
  EXPECT_EQ(allowed->height, 128);
  EXPECT_FALSE(allowed->aspect_note.empty());
}

TEST(ChooseInputSize, AnotherAspectThatIsNotTheSwapRunsWithANote) {
  PipelineOptions o;
  o.height = 96;
  o.width = 128;  // 4:3 on 16:9 frames: a stretch, not a swapped order
  Result<InputSizeChoice> c =
      ChooseInputSize(o, TracedAt(96, 128, TrainingState::kTrained), 540, 960);
  ASSERT_TRUE(c.ok()) << c.message();
  EXPECT_EQ(c->reason, "as asked");
  EXPECT_NE(c->aspect_note.find("stretched"), std::string::npos) << c->aspect_note;
  o.height = 540;  // within 10% of the frames' aspect: no note
  o.width = 950;
  Result<InputSizeChoice> same = ChooseInputSize(o, ModelMetadata{}, 540, 960);
  ASSERT_TRUE(same.ok());
  EXPECT_TRUE(same->aspect_note.empty());
}

}  // namespace
}  // namespace sfrt::pipeline
