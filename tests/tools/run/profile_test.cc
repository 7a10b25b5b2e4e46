// `sfrt run --profile` and `--config` (issue #6): the profiler ring, the reports it writes
// (JSON, CSV, Chrome trace, PNG plots) and `sfrt report compare`, first through the library on a
// fake source, then through the sfrt binary on generated frames and generated profiles.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/profile_report.h"
#include "sfrt/pipeline/profiler.h"
#include "sfrt/session.h"

namespace sfrt::pipeline {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kH = 32;
constexpr int kW = 48;

std::string DemoModelPath() {
  return std::string(SFRT_SOURCE_DIR) + "/tools/demo/sceneednet-w16-demo.sfrt";
}

std::shared_ptr<const Model> DemoModel() {
  auto model = Model::LoadFile(DemoModelPath());
  EXPECT_TRUE(model.ok()) << model.message();
  return model.ok() ? *model : nullptr;
}

int64_t Now() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

cv::Mat Noise(int k) {
  cv::Mat m(kH, kW, CV_8UC3);
  cv::RNG rng(static_cast<uint64_t>(77 + k));
  rng.fill(m, cv::RNG::UNIFORM, 0, 256);
  return m;
}

class CountingSource : public FrameSource {
 public:
  explicit CountingSource(int windows) : windows_(windows) {}
  Result<cv::Size> Open() override { return cv::Size(kW, kH); }
  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>&) override {
    if (next_ >= windows_) return Fetch::kEnd;
    const int64_t start = Now();
    Noise(2 * next_).copyTo(item->left0);
    Noise(2 * next_ + 1).copyTo(item->right0);
    Noise(2 * next_ + 2).copyTo(item->left1);
    Noise(2 * next_ + 3).copyTo(item->right1);
    item->meta.frame0 = next_;
    item->meta.frame1 = next_ + 1;
    item->meta.stage_ns[0][0] = start;
    item->meta.capture_ns[0] = item->meta.capture_ns[1] = Now();
    ++next_;
    return Fetch::kWindow;
  }
  std::string Describe() const override { return "counting"; }
  std::string kind() const override { return "fake"; }
  bool live() const override { return false; }
  void ToJson(json*) const override {}

 private:
  int windows_;
  int next_ = 0;
};

fs::path TempDir(const std::string& name) {
  fs::path dir =
      fs::temp_directory_path() / ("sfrt_profile_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

json ReadJson(const fs::path& path) {
  json j = json::parse(ReadText(path), nullptr, /*allow_exceptions=*/false);
  EXPECT_FALSE(j.is_discarded()) << path << " is not valid JSON";
  return j;
}

// Checks the five report files of a run of `windows` windows over a session with `steps` steps.
void ExpectValidReports(const fs::path& dir, size_t windows, size_t steps) {
  // JSON
  const json j = ReadJson(dir / "profile.json");
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j["format"], "sfrt-profile");
  EXPECT_EQ(j["version"], 1);
  EXPECT_EQ(j["frames"]["retained"].get<size_t>(), windows);
  for (const char* st : {"source", "preprocess", "infer", "output", "end_to_end"}) {
    ASSERT_TRUE(j["stages"].contains(st)) << st;
    const json& s = j["stages"][st];
    EXPECT_EQ(s["count"].get<size_t>(), windows) << st;
    EXPECT_LE(s["p50"].get<double>(), s["p99"].get<double>()) << st;
    EXPECT_LE(s["p99"].get<double>(), s["max"].get<double>()) << st;
  }
  ASSERT_EQ(j["steps"].size(), steps);
  double step_sum = 0;
  for (const json& s : j["steps"]) step_sum += s["mean"].get<double>();
  // The steps run inside the infer stage: their mean durations sum to at most its mean.
  EXPECT_LE(step_sum, j["stages"]["infer"]["mean"].get<double>() + 1e-6);
  EXPECT_GT(j["overhead"]["clock_read_ns"].get<double>(), 0);
  EXPECT_GT(j["overhead"]["estimated_ns_per_frame"].get<double>(), 0);

  // CSV: a header and one row per frame, every row as wide as the header.
  std::istringstream csv(ReadText(dir / "frames.csv"));
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(csv, line)) lines.push_back(line);
  ASSERT_EQ(lines.size(), windows + 1);
  EXPECT_EQ(lines[0].rfind("window,frame0,frame1,capture_ns,source_start_ns", 0), 0u);
  const auto columns = [](const std::string& l) { return std::count(l.begin(), l.end(), ',') + 1; };
  EXPECT_EQ(columns(lines[0]), 4 + 8 + 4 + 4 + static_cast<long>(steps));
  EXPECT_NE(lines[0].find(",miss,input_height,input_width"), std::string::npos) << lines[0];
  for (size_t i = 1; i < lines.size(); ++i) EXPECT_EQ(columns(lines[i]), columns(lines[0]));

  // Chrome trace: one named track per stage, a complete event per frame on each, the steps
  // nested inside the infer event of their frame.
  const json trace = ReadJson(dir / "trace.json");
  ASSERT_TRUE(trace.contains("traceEvents"));
  ASSERT_TRUE(trace["traceEvents"].is_array());
  std::map<int, std::string> track_names;
  std::map<int, size_t> frame_events;
  std::map<int64_t, std::pair<double, double>> infer_span;  // window -> [ts, ts + dur]
  std::vector<json> layers;
  for (const json& e : trace["traceEvents"]) {
    ASSERT_TRUE(e.contains("ph") && e.contains("pid")) << e.dump();
    if (e["ph"] == "M" && e["name"] == "thread_name") {
      track_names[e["tid"].get<int>()] = e["args"]["name"].get<std::string>();
    } else if (e["ph"] == "X" && e["cat"] == "layer") {
      layers.push_back(e);
    } else if (e["ph"] == "X") {
      ASSERT_GE(e["dur"].get<double>(), 0) << e.dump();
      ++frame_events[e["tid"].get<int>()];
      if (e["cat"] == "infer") {
        const double ts = e["ts"].get<double>();
        infer_span[e["args"]["window"].get<int64_t>()] = {ts, ts + e["dur"].get<double>()};
      }
    }
  }
  EXPECT_EQ(track_names, (std::map<int, std::string>{
                             {1, "source"}, {2, "preprocess"}, {3, "infer"}, {4, "output"}}));
  for (int tid = 1; tid <= 4; ++tid) EXPECT_EQ(frame_events[tid], windows) << "tid " << tid;
  ASSERT_EQ(layers.size(), windows * steps);
  for (const json& e : layers) {
    EXPECT_EQ(e["tid"], 3);
    const auto span = infer_span.at(e["args"]["window"].get<int64_t>());
    const double ts = e["ts"].get<double>(), end = ts + e["dur"].get<double>();
    EXPECT_GE(ts, span.first - 0.011) << e.dump();  // timestamps are rounded to 0.01 us
    EXPECT_LE(end, span.second + 0.011) << e.dump();
  }

  // The plots decode as images.
  for (const char* png : {"latency_hist.png", "latency_series.png"}) {
    cv::Mat img = cv::imread((dir / png).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty()) << png;
    EXPECT_EQ(img.cols, 900) << png;
    EXPECT_EQ(img.rows, 500) << png;
  }
}

TEST(FrameProfiler, RingKeepsTheLastCapacityFramesOldestFirst) {
  auto model = DemoModel();
  ASSERT_NE(model, nullptr);
  SessionOptions so;
  so.max_height = kH;
  so.max_width = kW;
  auto session = Session::Create(model, so);
  ASSERT_TRUE(session.ok()) << session.message();
  FrameProfiler prof(3);
  prof.Prepare(**session, kH, kW);
  const size_t n = (*session)->steps().size() + 1;
  ASSERT_EQ(prof.steps().size() + 1, n);
  std::vector<int64_t> steps(n);
  for (int w = 0; w < 5; ++w) {
    FrameMeta m;
    m.window = w;
    m.capture_ns[1] = 1000 * w;
    for (int s = 0; s < 4; ++s) {
      m.stage_ns[s][0] = 1000 * w + 10 * s;
      m.stage_ns[s][1] = 1000 * w + 10 * s + 5;
    }
    for (size_t k = 0; k < n; ++k) steps[k] = 100 * w + static_cast<int64_t>(k);
    prof.Record(m, steps, /*miss=*/w == 4);
  }
  EXPECT_EQ(prof.recorded(), 5u);
  EXPECT_EQ(prof.size(), 3u);
  EXPECT_EQ(prof.overwritten(), 2u);
  for (size_t i = 0; i < 3; ++i) {
    const int w = static_cast<int>(i) + 2;
    EXPECT_EQ(prof.frame(i).window, w);
    EXPECT_EQ(prof.frame(i).stage_ns[2][1], 1000 * w + 25);
    EXPECT_TRUE(prof.frame(i).has_steps);
    EXPECT_EQ(prof.step_end_ns(i)[n - 1], 100 * w + static_cast<int64_t>(n - 1));
  }
  EXPECT_TRUE(prof.frame(2).miss);
  EXPECT_FALSE(prof.frame(1).miss);
  // A frame without step times (wrong count) is kept, marked as such.
  FrameMeta m;
  m.window = 9;
  prof.Record(m, std::span<const int64_t>(), false);
  EXPECT_FALSE(prof.frame(2).has_steps);
}

TEST(ProfiledPipeline, RecordsEveryFrameOnOneClockAndWritesValidReports) {
  auto model = DemoModel();
  ASSERT_NE(model, nullptr);
  const fs::path dir = TempDir("lib");
  CountingSource source(6);
  FrameProfiler prof(100);
  PipelineOptions o;
  o.out_dir = dir.string();
  o.write_png = false;
  o.progress = ProgressMode::kOff;
  o.budget_ms = 1e-6;  // every frame misses: the trace marks them
  o.profiler = &prof;
  const PipelineResult r = RunPipeline(model, &source, o);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  ASSERT_EQ(prof.recorded(), 6u);
  for (size_t i = 0; i < prof.size(); ++i) {
    const ProfiledFrame& f = prof.frame(i);
    EXPECT_EQ(f.window, static_cast<int64_t>(i));
    EXPECT_TRUE(f.miss);
    ASSERT_TRUE(f.has_steps);
    // One clock: every stage starts after the previous one ended, steps inside infer.
    for (int s = 0; s < 4; ++s) EXPECT_LE(f.stage_ns[s][0], f.stage_ns[s][1]) << s;
    for (int s = 1; s < 4; ++s) EXPECT_LE(f.stage_ns[s - 1][1], f.stage_ns[s][0]) << s;
    std::span<const int64_t> t = prof.step_end_ns(i);
    EXPECT_LE(f.stage_ns[2][0], t.front());
    EXPECT_LE(t.back(), f.stage_ns[2][1]);
    for (size_t k = 1; k < t.size(); ++k) EXPECT_LE(t[k - 1], t[k]);
  }
  ProfileReportInfo info;
  info.dir = dir.string();
  info.budget_ms = o.budget_ms;
  info.model_path = DemoModelPath();
  info.source = "counting";
  std::string table;
  auto files = WriteProfileReports(prof, info, &table);
  ASSERT_TRUE(files.ok()) << files.message();
  ExpectValidReports(dir, 6, prof.steps().size());
  EXPECT_NE(table.find("end to end"), std::string::npos) << table;
  EXPECT_NE(table.find("overhead"), std::string::npos) << table;
  EXPECT_NE(table.find("6 of 6 frames over"), std::string::npos) << table;
  const json trace = ReadJson(dir / "trace.json");
  size_t misses = 0;
  for (const json& e : trace["traceEvents"]) misses += e["name"] == "deadline miss";
  EXPECT_EQ(misses, 6u);
  fs::remove_all(dir);
}

TEST(ProfileReports, PlotTitlesNameTheModelIsaPrecisionSizeAndThreads) {
  auto model = DemoModel();
  ASSERT_NE(model, nullptr);
  const fs::path dir = TempDir("subtitle");
  CountingSource source(2);
  FrameProfiler prof(10);
  PipelineOptions o;
  o.out_dir = dir.string();
  o.write_png = false;
  o.progress = ProgressMode::kOff;
  o.threads = 2;
  o.profiler = &prof;
  const PipelineResult r = RunPipeline(model, &source, o);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  ProfileReportInfo info;
  info.model_path = DemoModelPath();
  info.precision = "fp32";
  const std::string sub = ProfilePlotSubtitle(prof, info);
  const std::string size = std::to_string(prof.height()) + "x" + std::to_string(prof.width());
  for (const std::string& part :
       {"model " + fs::path(DemoModelPath()).filename().string(), "ISA " + prof.isa(),
        std::string("fp32"), size + " (HxW)", std::string("2 threads")}) {
    EXPECT_NE(sub.find(part), std::string::npos) << "'" << part << "' missing in: " << sub;
  }
  EXPECT_FALSE(prof.isa().empty());
  fs::remove_all(dir);
}

// The budget line at every position across the plot: its label stays inside the plot and off
// the line (2 px wide), vertical (histogram) and horizontal (series).
TEST(ProfileReports, BudgetLineNeverCrossesItsOwnLabel) {
  const cv::Rect plot(80, 70, 790, 370);
  const std::string label = "budget 1234.5 ms";
  for (int x = plot.x; x <= plot.x + plot.width; ++x) {
    const cv::Rect box = LabelBesideVerticalLine(label, x, 2, plot);
    EXPECT_TRUE((box & cv::Rect(x - 1, plot.y, 3, plot.height)).empty()) << "x " << x;
    EXPECT_EQ(box & plot, box) << "x " << x;
  }
  for (int y = plot.y; y <= plot.y + plot.height; ++y) {
    const cv::Rect box = LabelBesideHorizontalLine(label, y, 2, plot);
    EXPECT_TRUE((box & cv::Rect(plot.x, y - 1, plot.width, 3)).empty()) << "y " << y;
    EXPECT_EQ(box & plot, box) << "y " << y;
  }
}

TEST(ProfileReports, NothingRecordedIsAnErrorNamingTheDirectory) {
  FrameProfiler prof(4);
  ProfileReportInfo info;
  info.dir = "/nonexistent/profile";
  auto files = WriteProfileReports(prof, info, nullptr);
  ASSERT_FALSE(files.ok());
  EXPECT_NE(files.message().find("/nonexistent/profile"), std::string::npos);
}

// A minimal valid report with the given stage and step p50s.
void WriteReport(const fs::path& path, double infer, double output, double conv1, double conv2) {
  json j;
  j["format"] = "sfrt-profile";
  j["version"] = 1;
  j["isa"] = "avx2";
  j["frames"] = {{"retained", 10}};
  j["stages"] = {{"infer", {{"p50", infer}}}, {"output", {{"p50", output}}}};
  j["steps"] = json::array(
      {json{{"name", "conv1"}, {"p50", conv1}}, json{{"name", "conv2"}, {"p50", conv2}}});
  std::ofstream(path) << j.dump();
}

TEST(ReportCompare, SortsByTheLargestAbsoluteChangeWithMsAndPercent) {
  const fs::path dir = TempDir("compare");
  WriteReport(dir / "a.json", 10.0, 2.0, 4.0, 3.0);
  WriteReport(dir / "b.json", 12.5, 1.0, 4.5, 3.0);
  auto out = CompareProfileFiles((dir / "a.json").string(), (dir / "b.json").string());
  ASSERT_TRUE(out.ok()) << out.message();
  std::istringstream lines(*out);
  std::string line;
  std::vector<std::string> rows;
  while (std::getline(lines, line)) {
    if (line.rfind("stage", 0) == 0 || line.rfind("layer", 0) == 0) rows.push_back(line);
  }
  ASSERT_EQ(rows.size(), 4u) << *out;
  // infer +2.5 (+25%), output -1.0 (-50%), conv1 +0.5 (+12.5%), conv2 0.
  EXPECT_NE(rows[0].find("infer"), std::string::npos) << rows[0];
  EXPECT_NE(rows[0].find("+2.500"), std::string::npos) << rows[0];
  EXPECT_NE(rows[0].find("+25.0"), std::string::npos) << rows[0];
  EXPECT_NE(rows[1].find("output"), std::string::npos) << rows[1];
  EXPECT_NE(rows[1].find("-1.000"), std::string::npos) << rows[1];
  EXPECT_NE(rows[1].find("-50.0"), std::string::npos) << rows[1];
  EXPECT_NE(rows[2].find("conv1"), std::string::npos) << rows[2];
  EXPECT_NE(rows[3].find("conv2"), std::string::npos) << rows[3];
  fs::remove_all(dir);
}

TEST(ReportCompare, RejectsFilesThatAreNotProfileReports) {
  const fs::path dir = TempDir("compare_bad");
  WriteReport(dir / "a.json", 1, 1, 1, 1);
  std::ofstream(dir / "summary.json") << R"({"frames": {"written": 3}})";
  std::ofstream(dir / "broken.json") << "{not json";
  auto other = CompareProfileFiles((dir / "a.json").string(), (dir / "summary.json").string());
  ASSERT_FALSE(other.ok());
  EXPECT_NE(other.message().find("summary.json' is not a profile report"), std::string::npos)
      << other.message();
  auto broken = CompareProfileFiles((dir / "broken.json").string(), (dir / "a.json").string());
  ASSERT_FALSE(broken.ok());
  EXPECT_NE(broken.message().find("broken.json' is not valid JSON"), std::string::npos)
      << broken.message();
  fs::remove_all(dir);
}

// ------------------------------------------------------------------ the sfrt binary end to end

struct CliRun {
  int exit_code = -1;
  std::string out, err;
};

CliRun RunSfrt(const std::string& args, const fs::path& dir, const std::string& env = "") {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd = env + (env.empty() ? "" : " ") + std::string(SFRT_BIN) + " " + args +
                          " > " + out.string() + " 2> " + err.string();
  const int status = std::system(cmd.c_str());
  CliRun r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = ReadText(out);
  r.err = ReadText(err);
  return r;
}

// Frames (pairs 0..pairs-1) and a replay profile next to them; `infer_stage` is the infer
// stage's mapping, `budget` is the budget line's value, `on_miss` the lines after it (from the
// on_miss key on) and `outputs` extra lines of the outputs mapping.
fs::path MakeReplayProfile(const fs::path& dir, int pairs, const std::string& infer_stage,
                           const std::string& budget,
                           const std::string& on_miss = "  on_miss: drop-next\n",
                           const std::string& outputs = "") {
  fs::create_directories(dir / "frames");
  for (int k = 0; k < pairs; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%03d.png", k);
    cv::imwrite((dir / "frames" / ("left_" + std::string(name))).string(), Noise(2 * k));
    cv::imwrite((dir / "frames" / ("right_" + std::string(name))).string(), Noise(2 * k + 1));
  }
  const fs::path profile = dir / "replay.yaml";
  std::ofstream(profile) << "version: 1\n"
                            "name: replay-test\n"
                            "replay:\n"
                            "  left: frames/left_*.png\n"
                            "  right: frames/right_*.png\n"
                            "  on_bad_frame: stop\n"
                            "model:\n"
                            "  file: "
                         << DemoModelPath()
                         << "\n"
                            "  input_height: 32\n"
                            "  input_width: 48\n"
                            "stages:\n"
                            "  infer: "
                         << infer_stage
                         << "\n"
                            "memory:\n"
                            "  prefault_arena: true\n"
                            "latency:\n"
                            "  budget_ms: "
                         << budget << "\n"
                         << on_miss
                         << "outputs:\n"
                            "  dir: out\n"
                            "  flow: true\n"
                            "  visualisation: false\n"
                         << outputs
                         << "logging:\n"
                            "  level: warn\n";
  return profile;
}

TEST(RunConfigCli, ReplayProfileWithProfilingWritesEveryReport) {
  const fs::path dir = TempDir("cli_profile");
  const fs::path profile = MakeReplayProfile(dir, 6, "{threads: 1}", "1000");
  const CliRun r = RunSfrt("run --config " + profile.string() + " --profile", dir);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  // Start banner: the options the profile set; final summary: what was applied.
  EXPECT_NE(r.out.find("--replay-left " + (dir / "frames/left_*.png").string() + "  (replay.left)"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("--size 32x48  (model.input_height/input_width)"), std::string::npos);
  EXPECT_NE(r.out.find("applied       memory.prefault_arena"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("applied       latency.on_miss drop-next"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("p99"), std::string::npos);
  EXPECT_NE(r.out.find("within the budget of 1000 ms"), std::string::npos) << r.out;
  EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
  auto model = DemoModel();
  ASSERT_NE(model, nullptr);
  SessionOptions so;
  so.max_height = kH;
  so.max_width = kW;
  auto session = Session::Create(model, so);
  ASSERT_TRUE(session.ok());
  ExpectValidReports(dir / "out" / "profile", 5, (*session)->steps().size());
  EXPECT_TRUE(fs::exists(dir / "out" / "summary.json"));
  EXPECT_TRUE(fs::exists(dir / "out" / "left_000000.pfm") ||
              !fs::is_empty(dir / "out"));  // flow files named by the replay's stems

  // Compare the run with itself: exit 0, every stage listed with a zero change.
  const fs::path json_path = dir / "out" / "profile" / "profile.json";
  const CliRun same =
      RunSfrt("report compare " + json_path.string() + " " + json_path.string(), dir);
  EXPECT_EQ(same.exit_code, 0) << same.err;
  EXPECT_NE(same.out.find("end_to_end"), std::string::npos) << same.out;
  EXPECT_NE(same.out.find("+0.000"), std::string::npos) << same.out;
  const CliRun bad = RunSfrt(
      "report compare " + json_path.string() + " " + (dir / "out" / "summary.json").string(), dir);
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("is not a profile report"), std::string::npos) << bad.err;
  // A profile directory stands for its profile.json; runs on other thread counts are flagged.
  nlohmann::json other = nlohmann::json::parse(std::ifstream(json_path));
  other["threads"] = other.value("threads", 1) + 1;
  fs::create_directories(dir / "other");
  std::ofstream(dir / "other" / "profile.json") << other.dump();
  const CliRun dirs = RunSfrt(
      "report compare " + (dir / "out" / "profile").string() + " " + (dir / "other").string(), dir);
  EXPECT_EQ(dirs.exit_code, 0) << dirs.err;
  EXPECT_NE(dirs.out.find("note: A and B differ in threads"), std::string::npos) << dirs.out;
  fs::remove_all(dir);
}

TEST(RunConfigCli, CommandLineOverridesTheProfileAndOverheadIsMeasured) {
  const fs::path dir = TempDir("cli_override");
  const fs::path profile = MakeReplayProfile(dir, 4, "{threads: 1}", "1000");
  const CliRun r = RunSfrt("run --config " + profile.string() + " --budget-ms 5000 --profile " +
                               (dir / "prof").string() + " --profile-overhead",
                           dir);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("override  latency.budget_ms (--budget-ms on the command line)"),
            std::string::npos)
      << r.out;
  const json j = ReadJson(dir / "prof" / "profile.json");
  EXPECT_EQ(j["deadline"]["budget_ms"].get<double>(), 5000);
  ASSERT_TRUE(j["overhead"]["ab"].is_object()) << j["overhead"].dump();
  EXPECT_EQ(j["overhead"]["ab"]["frames_with"], 3);
  EXPECT_EQ(j["overhead"]["ab"]["frames_without"], 6);  // two baseline runs
  EXPECT_NE(r.out.find("A/B in this process"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

TEST(RunConfigCli, FifoPriorityWithoutPermissionWarnsNamesTheFixAndRuns) {
  const fs::path dir = TempDir("cli_fifo");
  const fs::path profile = MakeReplayProfile(dir, 3, "{threads: 1, priority: 10}", "1000");
  // The capability seam: the run sees an unprivileged process even when the test runs as root.
  const CliRun r = RunSfrt("run --config " + profile.string(), dir, "SFRT_TEST_CAPABILITIES=none");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.err.find("sfrt run: warning: stages.infer.priority: SCHED_FIFO priority 10 cannot "
                       "be applied: the process lacks CAP_SYS_NICE"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("setcap cap_sys_nice+ep"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("not applied   stages.infer.priority SCHED_FIFO 10: "), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("frames      2"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

TEST(RunConfigCli, SmallerInputProfileIsAppliedAndLaterFramesRunAtTheFallbackSize) {
  const fs::path dir = TempDir("cli_smaller");
  // An impossible budget: every frame misses, so after the first the run switches to 16x24 and
  // stays there (recovery needs in-budget frames).
  const fs::path profile =
      MakeReplayProfile(dir, 10, "{threads: 1}", "0.001",
                        "  on_miss: smaller-input\n  fallback_height: 16\n  fallback_width: 24\n"
                        "  recover_after_frames: 5\n");
  const CliRun r = RunSfrt("run --config " + profile.string() + " --profile", dir);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("applied       latency.on_miss smaller-input 16x24 (full size again after "
                       "5 in-budget frames)"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find("not applied   latency.on_miss"), std::string::npos) << r.out;
  EXPECT_EQ(r.err.find("not implemented"), std::string::npos) << r.err;
  const json d = ReadJson(dir / "out" / "summary.json")["deadline"];
  EXPECT_EQ(d["on_miss"], "smaller-input");
  EXPECT_EQ(d["fallback_size"], json::array({16, 24}));
  EXPECT_EQ(d["recover_after_frames"], 5);
  EXPECT_EQ(d["fallback_entries"], 1);
  EXPECT_EQ(d["misses"], 9);
  // Frames already in the pipeline at the switch finish at the full size (at most one per
  // stage and queue slot); the rest run at the fallback size.
  const int at_fallback = d["frames_at_fallback_size"].get<int>();
  EXPECT_GE(at_fallback, 3);
  EXPECT_LE(at_fallback, 8);
  // Each frame's record says its size: frames.csv, the flow file's own header.
  std::istringstream csv(ReadText(dir / "out" / "profile" / "frames.csv"));
  std::string line;
  std::getline(csv, line);
  int csv_fallback = 0, rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    if (line.find(",16,24,") != std::string::npos) ++csv_fallback;
  }
  EXPECT_EQ(rows, 9);
  EXPECT_EQ(csv_fallback, at_fallback);
  int pfm_fallback = 0;
  for (const auto& e : fs::directory_iterator(dir / "out")) {
    if (e.path().extension() != ".pfm") continue;
    std::ifstream in(e.path());
    std::string magic, size;
    std::getline(in, magic);
    std::getline(in, size);
    if (size == "24 16") ++pfm_fallback;  // PFM: width height
  }
  EXPECT_EQ(pfm_fallback, at_fallback);
  EXPECT_EQ(
      ReadJson(dir / "out" / "profile" / "profile.json")["deadline"]["frames_at_fallback_size"],
      at_fallback);
  fs::remove_all(dir);
}

TEST(RunConfigCli, SummaryFalseWritesNoSummaryJson) {
  const fs::path dir = TempDir("cli_nosummary");
  const fs::path profile = MakeReplayProfile(dir, 3, "{threads: 1}", "1000",
                                             "  on_miss: count-only\n", "  summary: false\n");
  const CliRun r = RunSfrt("run --config " + profile.string(), dir);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("--no-summary  (outputs.summary)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("frames      2"), std::string::npos) << r.out;
  EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out" / "summary.json"));
  EXPECT_TRUE(fs::exists(dir / "out" / "left_000.pfm") || !fs::is_empty(dir / "out"));
  fs::remove_all(dir);
}

TEST(RunConfigCli, RecoverAfterFramesIsCheckedAndOnlyAllowedWithSmallerInput) {
  const fs::path dir = TempDir("cli_recover_check");
  const fs::path zero =
      MakeReplayProfile(dir, 2, "{threads: 1}", "40",
                        "  on_miss: smaller-input\n  fallback_height: 16\n  fallback_width: 24\n"
                        "  recover_after_frames: 0\n");
  const CliRun r = RunSfrt("config check " + zero.string(), dir);
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  // Line 20 of the generated profile, the value at column 25.
  EXPECT_NE(r.err.find(zero.string() + ":20:25: latency.recover_after_frames: "), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("1..100000"), std::string::npos) << r.err;
  const fs::path counted = MakeReplayProfile(dir, 2, "{threads: 1}", "40",
                                             "  on_miss: count-only\n  recover_after_frames: 5\n");
  const CliRun c = RunSfrt("config check " + counted.string(), dir);
  EXPECT_EQ(c.exit_code, 1) << c.out << c.err;
  EXPECT_NE(c.err.find("latency.recover_after_frames"), std::string::npos) << c.err;
  EXPECT_NE(c.err.find("only with on_miss: smaller-input"), std::string::npos) << c.err;
  fs::remove_all(dir);
}

TEST(RunConfigCli, InvalidProfileFailsWithFileLineColumnBeforeOpeningAnything) {
  const fs::path dir = TempDir("cli_invalid");
  const fs::path profile = MakeReplayProfile(dir, 3, "{threads: 1}", "-5");
  const CliRun r = RunSfrt("run --config " + profile.string() + " --profile", dir);
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  // budget_ms is on line 16 of the generated profile, its value at column 14.
  EXPECT_NE(r.err.find(profile.string() + ":16:14: latency.budget_ms: "), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("sfrt run: --config " + profile.string() + ": 1 error; nothing was opened"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir / "out")) << "the output directory must not be created";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sfrt::pipeline
