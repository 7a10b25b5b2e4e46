// Profile parsing and validation (sfrt/config/profile.h): the shipped profiles, the exact errors
// of every broken profile, defaults, and relative path resolution.
#include "sfrt/config/profile.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace sfrt::config {
namespace {

namespace fs = std::filesystem;

const std::string kSource = SFRT_SOURCE_DIR;
const std::string kFirmware = kSource + "/firmware-cfg";
const std::string kBroken = kSource + "/tests/firmware-cfg/broken";
const std::string kDemoModel = kSource + "/tools/demo/sceneednet-w16-demo.sfrt";
// What the shipped profiles run: the trained default model (issue 15).
const std::string kDefaultModel = kSource + "/models/sceneednet-default.sfrt";

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The "# expect: " lines of a broken profile, with {file} and {dir} substituted.
std::vector<std::string> ExpectedErrors(const std::string& path) {
  std::vector<std::string> out;
  std::istringstream in(ReadText(path));
  std::string line;
  const std::string prefix = "# expect: ";
  while (std::getline(in, line)) {
    if (line.rfind(prefix, 0) != 0) continue;
    std::string text = line.substr(prefix.size());
    for (const auto& [key, value] :
         {std::pair<std::string, std::string>{"{file}", path}, {"{dir}", kBroken}}) {
      for (size_t at = text.find(key); at != std::string::npos; at = text.find(key, at)) {
        text.replace(at, key.size(), value);
        at += value.size();
      }
    }
    out.push_back(text);
  }
  return out;
}

std::vector<std::string> ErrorLines(const ValidationReport& report) {
  std::vector<std::string> out;
  for (const Diagnostic& d : report.errors) out.push_back(d.ToString());
  return out;
}

// ------------------------------------------------------------------- shipped profiles

TEST(ShippedProfiles, ReplayDemoLoadsWithPathsResolvedAgainstItsDirectory) {
  ValidationReport report;
  auto p = LoadProfile(kFirmware + "/replay-demo.yaml", &report);
  ASSERT_TRUE(p.ok()) << p.message();
  EXPECT_TRUE(report.warnings.empty());
  EXPECT_EQ(p->source, SourceKind::kReplayGlobs);
  EXPECT_EQ(p->replay.left, kSource + "/tools/demo/robot-frames/left*.png");
  EXPECT_EQ(p->replay.right, kSource + "/tools/demo/robot-frames/right*.png");
  EXPECT_EQ(p->replay.on_bad_frame, camera::BadFramePolicy::kStop);
  EXPECT_EQ(p->model_file, kDefaultModel);
  EXPECT_EQ(p->input_height, 96);
  EXPECT_EQ(p->input_width, 128);
  EXPECT_TRUE(p->calibration.empty());
  EXPECT_EQ(p->stage(Stage::kInfer).threads, 2);
  EXPECT_FALSE(p->stage(Stage::kInfer).rt_priority.has_value());
  EXPECT_FALSE(p->memory_cap_mib.has_value());
  EXPECT_EQ(p->budget_ms, 1000);
  EXPECT_EQ(p->on_miss, MissAction::kCountOnly);
  EXPECT_EQ(p->output_dir, kSource + "/out/replay-demo");
  EXPECT_TRUE(p->visualisation);
  EXPECT_EQ(p->log_file, "");
}

TEST(ShippedProfiles, X86UsbStereoHasTwoCamerasAndRealTimeStages) {
  ValidationReport report;
  auto p = LoadProfile(kFirmware + "/x86-avx512-usb-stereo.yaml", &report);
  ASSERT_TRUE(p.ok()) << p.message();
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front().ToString();
  EXPECT_EQ(p->source, SourceKind::kStereoCameras);
  EXPECT_EQ(p->camera.left_device, "/dev/video0");
  EXPECT_EQ(p->camera.right_device, "/dev/video2");
  EXPECT_EQ(p->camera.pixel_format, PixelFormat::kMjpeg);
  EXPECT_EQ(p->camera.width, 640);
  EXPECT_EQ(p->camera.height, 480);
  EXPECT_EQ(p->camera.fps, 30);
  EXPECT_EQ(p->camera.pair_tolerance_ms, 8);
  EXPECT_EQ(p->model_file, kDefaultModel);
  EXPECT_EQ(p->input_height, 96);
  EXPECT_EQ(p->input_width, 128);
  ASSERT_EQ(p->calibration.size(), 1u);
  EXPECT_EQ(p->calibration[0], kFirmware + "/calib/usb-stereo-640x480.camchain.yaml");
  EXPECT_EQ(p->stage(Stage::kInfer).cpus, (std::vector<int>{0, 1}));
  EXPECT_EQ(p->stage(Stage::kSource).rt_priority, 50);
  EXPECT_FALSE(p->stage(Stage::kOutput).rt_priority.has_value());
  EXPECT_TRUE(p->mlockall);
  EXPECT_EQ(p->memory_cap_mib, 512);
  EXPECT_EQ(p->on_miss, MissAction::kDropNext);
  EXPECT_EQ(p->flow_format, FlowFormat::kNpy);
  EXPECT_EQ(p->output_dir, "/var/lib/sfrt/out");
}

TEST(ShippedProfiles, Aarch64SbsFallsBackToSmallerInput) {
  auto p = LoadProfile(kFirmware + "/aarch64-4core-sbs.yaml");
  ASSERT_TRUE(p.ok()) << p.message();
  EXPECT_EQ(p->source, SourceKind::kSbsCamera);
  EXPECT_EQ(p->camera.device, "/dev/video0");
  EXPECT_EQ(p->camera.order, SbsOrder::kLeftRight);
  EXPECT_EQ(p->camera.pixel_format, PixelFormat::kYuyv);
  EXPECT_EQ(p->camera.width, 1280);
  EXPECT_EQ(p->on_miss, MissAction::kSmallerInput);
  EXPECT_EQ(p->model_file, kDefaultModel);
  EXPECT_EQ(p->input_height, 96);
  EXPECT_EQ(p->input_width, 128);
  EXPECT_EQ(p->fallback_height, 72);
  EXPECT_EQ(p->fallback_width, 96);
  EXPECT_EQ(p->stage(Stage::kInfer).cpus, (std::vector<int>{2, 3}));
}

// -------------------------------------------------------------------- broken profiles

class BrokenProfile : public testing::TestWithParam<std::string> {};

TEST_P(BrokenProfile, FailsWithExactlyTheExpectedErrors) {
  const std::string path = kBroken + "/" + GetParam() + ".yaml";
  ASSERT_TRUE(fs::exists(path)) << path;
  const std::vector<std::string> want = ExpectedErrors(path);
  EXPECT_FALSE(want.empty()) << path << " has no '# expect:' lines";
  ValidationReport report;
  auto p = LoadProfile(path, &report);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(ErrorLines(report), want);
  if (want.empty()) return;
  // The Status is the first error, plus how many more there are.
  std::string message = want.front();
  if (want.size() == 2) message += " (and 1 more error)";
  if (want.size() > 2) message += " (and " + std::to_string(want.size() - 1) + " more errors)";
  EXPECT_EQ(p.message(), message);
}

INSTANTIATE_TEST_SUITE_P(
    Profiles, BrokenProfile,
    testing::Values("unknown_key", "wrong_type", "negative_budget", "missing_model",
                    "bad_model_file", "bad_calibration", "missing_calibration_file",
                    "priority_out_of_range", "bad_pixel_format", "missing_required", "two_sources",
                    "smaller_input_without_size", "syntax_error", "sbs_odd_width"),
    [](const testing::TestParamInfo<std::string>& param_info) { return param_info.param; });
// A calibration made at another resolution than the camera's is an error, as in sfrt run.
INSTANTIATE_TEST_SUITE_P(Calibration, BrokenProfile,
                         testing::Values("calibration_at_another_resolution"),
                         [](const testing::TestParamInfo<std::string>& param_info) {
                           return param_info.param;
                         });

// Every file in broken/ is listed above (a new one cannot be silently left out).
TEST(BrokenProfiles, EveryFileIsInTheParameterList) {
  const std::vector<std::string> listed = {"unknown_key",
                                           "wrong_type",
                                           "negative_budget",
                                           "missing_model",
                                           "bad_model_file",
                                           "bad_calibration",
                                           "missing_calibration_file",
                                           "priority_out_of_range",
                                           "bad_pixel_format",
                                           "missing_required",
                                           "two_sources",
                                           "smaller_input_without_size",
                                           "syntax_error",
                                           "sbs_odd_width",
                                           "calibration_at_another_resolution"};
  for (const auto& entry : fs::directory_iterator(kBroken)) {
    if (entry.path().extension() != ".yaml") continue;
    const std::string stem = entry.path().stem().string();
    EXPECT_NE(std::find(listed.begin(), listed.end(), stem), listed.end()) << stem;
  }
}

// ------------------------------------------------------------------------ unit tests

// A scratch directory removed at the end of the test.
class ProfileParser : public testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("sfrt_config_test_" + std::to_string(::getpid()) + "_" +
                                     testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Write(const std::string& rel, const std::string& text) {
    const fs::path p = dir_ / rel;
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
    return p.string();
  }

  // A valid replay profile body around `extra` (appended at the end).
  std::string Minimal(const std::string& extra = "") {
    return "version: 1\n"
           "replay:\n"
           "  left: " +
           kSource + "/tools/demo/frames/left*.png\n" + "  right: " + kSource +
           "/tools/demo/frames/right*.png\n" + "model:\n  file: " + kDemoModel +
           "\n  input_height: 128\n  input_width: 224\n"
           "latency:\n  budget_ms: 40\n"
           "outputs:\n  dir: out\n" +
           extra;
  }

  fs::path dir_;
};

TEST_F(ProfileParser, MinimalProfileGetsTheDocumentedDefaults) {
  auto p = LoadProfileFromString(Minimal(), (dir_ / "p.yaml").string());
  ASSERT_TRUE(p.ok()) << p.message();
  for (int s = 0; s < kStageCount; ++s) {
    EXPECT_EQ(p->stages[s].threads, 1);
    EXPECT_TRUE(p->stages[s].cpus.empty());
    EXPECT_FALSE(p->stages[s].rt_priority.has_value());
  }
  EXPECT_FALSE(p->mlockall);
  EXPECT_FALSE(p->prefault_arena);
  EXPECT_FALSE(p->memory_cap_mib.has_value());
  EXPECT_EQ(p->budget_percentile, 99);
  EXPECT_EQ(p->on_miss, MissAction::kCountOnly);
  EXPECT_TRUE(p->write_flow);
  EXPECT_EQ(p->flow_format, FlowFormat::kPfm);
  EXPECT_FALSE(p->visualisation);
  EXPECT_FALSE(p->video);
  EXPECT_TRUE(p->summary);
  EXPECT_EQ(p->log_level, LogLevel::kInfo);
  EXPECT_EQ(p->replay.on_bad_frame, camera::BadFramePolicy::kSkip);
  EXPECT_EQ(p->output_dir, (dir_ / "out").string());
}

TEST_F(ProfileParser, RelativePathsResolveAgainstTheProfileNotTheWorkingDirectory) {
  fs::create_directories(dir_ / "models");
  fs::copy_file(kDemoModel, dir_ / "models/m.sfrt");
  Write("frames/l0.png", "x");
  Write("frames/r0.png", "x");
  const std::string path = Write("deploy/p.yaml",
                                 "version: 1\n"
                                 "replay: {left: ../frames/l*.png, right: ../frames/r*.png}\n"
                                 "model: {file: ../models/m.sfrt, input_height: 64, "
                                 "input_width: 64}\n"
                                 "latency: {budget_ms: 10}\n"
                                 "outputs: {dir: run/out}\n"
                                 "logging: {file: ../log/sfrt.log}\n");
  const fs::path cwd = fs::current_path();
  fs::current_path("/");
  auto p = LoadProfile(path);
  fs::current_path(cwd);
  ASSERT_TRUE(p.ok()) << p.message();
  EXPECT_EQ(p->model_file, (dir_ / "models/m.sfrt").string());
  EXPECT_EQ(p->replay.left, (dir_ / "frames/l*.png").string());
  EXPECT_EQ(p->output_dir, (dir_ / "deploy/run/out").string());
  EXPECT_EQ(p->log_file, (dir_ / "log/sfrt.log").string());
  EXPECT_EQ(p->dir, (dir_ / "deploy").string());
}

TEST_F(ProfileParser, StereoPairToleranceDefaultsToHalfAFramePeriod) {
  const std::string text =
      "version: 1\n"
      "camera: {mode: stereo, left_device: /dev/video0, right_device: /dev/video1,\n"
      "         pixel_format: yuyv, width: 320, height: 240, fps: 25}\n"
      "model: {file: " +
      kDemoModel +
      ", input_height: 128, input_width: 224}\n"
      "latency: {budget_ms: 40}\n"
      "outputs: {dir: out}\n";
  ValidationReport report;
  auto p = LoadProfileFromString(text, (dir_ / "p.yaml").string(), &report);
  ASSERT_TRUE(p.ok()) << p.message();
  EXPECT_EQ(p->camera.pixel_format, PixelFormat::kYuyv);  // names are case-insensitive
  EXPECT_DOUBLE_EQ(p->camera.pair_tolerance_ms, 20.0);
  EXPECT_EQ(p->camera.buffer_count, 4);
  // Live cameras without calibration: valid, with a warning.
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_EQ(report.warnings[0].ToString(),
            (dir_ / "p.yaml").string() +
                ":1:1: calibration: not given: live frames go to the network unrectified");
}

TEST_F(ProfileParser, OldSourceStageNameCaptureIsReadWithAWarningAndNotBesideSource) {
  ValidationReport report;
  auto p = LoadProfileFromString(Minimal("stages:\n  capture: {priority: 50}\n"),
                                 (dir_ / "old.yaml").string(), &report);
  ASSERT_TRUE(p.ok()) << p.message();
  EXPECT_EQ(p->stage(Stage::kSource).rt_priority, 50);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_EQ(report.warnings[0].key, "stages.capture");
  EXPECT_EQ(report.warnings[0].problem, "is the old name of the source stage; write stages.source");

  auto both = LoadProfileFromString(
      Minimal("stages:\n  source: {priority: 50}\n  capture: {priority: 40}\n"),
      (dir_ / "both.yaml").string());
  ASSERT_FALSE(both.ok());
  EXPECT_NE(both.message().find("stages.capture: names the source stage a second time"),
            std::string::npos)
      << both.message();
}

TEST_F(ProfileParser, DuplicateKeyIsAnError) {
  const std::string path = (dir_ / "p.yaml").string();
  ValidationReport report;
  auto p =
      LoadProfileFromString(Minimal("memory: {mlockall: true, mlockall: false}\n"), path, &report);
  ASSERT_FALSE(p.ok());
  ASSERT_EQ(report.errors.size(), 1u);
  EXPECT_EQ(report.errors[0].ToString(),
            path + ":13:26: memory.mlockall: duplicate key (first given at line 13)");
}

TEST_F(ProfileParser, FallbackSizeMustBeSmallerThanTheInput) {
  const std::string path = (dir_ / "p.yaml").string();
  ValidationReport report;
  std::string text = Minimal();
  text.replace(text.find("  budget_ms: 40\n"), 16,
               "  budget_ms: 40\n  on_miss: smaller-input\n  fallback_height: 128\n"
               "  fallback_width: 224\n");
  auto p = LoadProfileFromString(text, path, &report);
  ASSERT_FALSE(p.ok());
  ASSERT_EQ(report.errors.size(), 1u);
  EXPECT_EQ(report.errors[0].ToString(),
            path +
                ":12:20: latency.fallback_height: fallback size 128x224 is not smaller than "
                "model input 128x224; allowed: at most the model input size in each dimension, "
                "and smaller in one");
}

TEST_F(ProfileParser, CpusListedTwiceAndOutOfRange) {
  const std::string path = (dir_ / "p.yaml").string();
  ValidationReport report;
  auto p =
      LoadProfileFromString(Minimal("stages:\n  infer: {cpus: [1, 1, 4096]}\n"), path, &report);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(ErrorLines(report),
            (std::vector<std::string>{
                path + ":14:21: stages.infer.cpus[1]: CPU 1 is listed twice",
                path + ":14:24: stages.infer.cpus[2]: out of range: 4096; allowed: integer "
                       "0..1023 (CPU number)"}));
}

TEST_F(ProfileParser, EmptyAndUnreadableFiles) {
  ValidationReport report;
  auto empty = LoadProfile(Write("empty.yaml", "# nothing\n"), &report);
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.message().find("empty.yaml:1:1: the profile is empty; allowed: a mapping"),
            std::string::npos)
      << empty.message();
  const std::string missing = (dir_ / "missing.yaml").string();
  auto none = LoadProfile(missing);
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.message(), missing + ": cannot read profile: No such file or directory");
  auto directory = LoadProfile(dir_.string());
  ASSERT_FALSE(directory.ok());
  EXPECT_EQ(directory.message(), dir_.string() + ": cannot read profile: is a directory");
}

TEST_F(ProfileParser, TopLevelMustBeAMapping) {
  const std::string path = (dir_ / "p.yaml").string();
  auto p = LoadProfileFromString("- a\n- b\n", path);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.message().rfind(path + ":1:1: expected a mapping of keys, got a list", 0), 0u)
      << p.message();
}

TEST_F(ProfileParser, SummaryNamesEverySetting) {
  auto p = LoadProfile(kFirmware + "/aarch64-4core-sbs.yaml");
  ASSERT_TRUE(p.ok()) << p.message();
  // Rows are "  <label><at least two spaces><value>".
  std::map<std::string, std::string> rows;
  std::istringstream in(FormatProfileSummary(*p));
  std::string line;
  while (std::getline(in, line)) {
    ASSERT_EQ(line.rfind("  ", 0), 0u) << line;
    const size_t gap = line.find("  ", 2);
    ASSERT_NE(gap, std::string::npos) << line;
    rows[line.substr(2, gap - 2)] = line.substr(line.find_first_not_of(' ', gap));
  }
  const std::map<std::string, std::string> want = {
      {"name", "aarch64-4core-sbs"},
      {"source", "side-by-side camera /dev/video0 (left-right)"},
      {"capture", "YUYV 480x1280 (HxW) at 30 fps, 4 buffers"},
      {"calibration", kFirmware + "/calib/sbs-stereo-1280x480.camchain.yaml"},
      {"model", kDefaultModel + " at 96x128 (HxW)"},
      {"stage source", "1 thread, CPUs 0, SCHED_FIFO 50"},
      {"stage preprocess", "1 thread, CPUs 1, SCHED_FIFO 45"},
      {"stage infer", "2 threads, CPUs 2,3, SCHED_FIFO 40"},
      {"stage output", "1 thread, CPUs 1, SCHED_OTHER"},
      {"memory", "mlockall on, arena prefault on, cap 768 MiB"},
      {"latency", "p99 <= 150 ms; on miss smaller-input 72x96"},
      {"outputs", "/var/lib/sfrt/out: flow pfm, visualisation off, video off, summary on"},
      {"logging", "warn to /var/log/sfrt/sfrt.log"}};
  EXPECT_EQ(rows, want);
}

TEST(EditDistance, CountsAnAdjacentTranspositionAsOneEdit) {
  EXPECT_EQ(EditDistance("pixel_fromat", "pixel_format"), 1);
  EXPECT_EQ(EditDistance("fps", "fps"), 0);
  EXPECT_EQ(EditDistance("", "abc"), 3);
  EXPECT_EQ(EditDistance("kitten", "sitting"), 3);
}

}  // namespace
}  // namespace sfrt::config
