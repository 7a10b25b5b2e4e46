// Deployment profiles: one YAML file per deployment (firmware-cfg/*.yaml), parsed and validated
// into a plain DeploymentProfile that `sfrt run --config` consumes. firmware-cfg/README.md is the
// reference of every key; this header is the contract for code.
//
// Loading checks everything a deployment depends on before any camera is touched:
//  * the YAML syntax, unknown keys (with a did-you-mean from the known keys), value types,
//    ranges and enumerations, required keys and combinations (exactly one source, the fallback
//    size of on_miss: smaller-input, ...);
//  * files: the model file exists and loads (sfrt::Model::LoadFile, weights CRC checked), the
//    calibration file(s) exist and parse (sfrt::camera::ReadStereoCalibration), replay inputs
//    exist (dataset directory, video file, at least one file per glob).
// Every problem is reported in one pass, each as one line
//   file:line:column: <key path>: <problem>; allowed: <values or range>
// (line and column 1-based, pointing at the offending value, or at the key for unknown keys, or
// at the enclosing mapping for missing keys; "; allowed: ..." only when there is a set or range).
//
// Relative paths in a profile resolve against the directory of the profile file, so a profile
// means the same thing whatever the working directory. Device paths (/dev/...) must be absolute.
//
// Thread-safety: the functions are reentrant; they share no state.
#pragma once

#include <array>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "sfrt/camera/stereo_source.h"
#include "sfrt/config/vocabulary.h"
#include "sfrt/status.h"

namespace sfrt::config {

inline constexpr int kProfileVersion = 1;  // the only `version:` this build reads

enum class PixelFormat { kYuyv, kMjpeg, kGrey, kNv12, kBgr24, kRgb24 };
enum class SourceKind {
  kStereoCameras,  // two V4L2 devices, paired by timestamp
  kSbsCamera,      // one V4L2 device delivering left and right side by side
  kReplayDataset,  // a Scene Flow / KITTI dataset root (layout detected by the reader)
  kReplayGlobs,    // left and right directories or glob patterns, sorted by name
  kReplayVideo,    // a side-by-side stereo video file
};
enum class SbsOrder { kLeftRight, kRightLeft };  // which half is the left image

// Canonical spellings as written in profiles ("MJPEG", "left-right"), and the source kinds as the
// profile summary names them ("stereo cameras", "side-by-side camera", ...).
inline constexpr std::array<const char*, 6> kPixelFormatNames = {"YUYV", "MJPEG", "GREY",
                                                                 "NV12", "BGR24", "RGB24"};
inline constexpr std::array<const char*, 5> kSourceKindNames = {
    "stereo cameras", "side-by-side camera", "replay dataset", "replay left/right frames",
    "replay side-by-side video"};
inline constexpr std::array<const char*, 2> kSbsOrderNames = {"left-right", "right-left"};
constexpr const char* PixelFormatName(PixelFormat f) {
  return vocabulary::NameOf(kPixelFormatNames, f);
}
constexpr const char* SourceKindName(SourceKind k) {
  return vocabulary::NameOf(kSourceKindNames, k);
}
constexpr const char* SbsOrderName(SbsOrder o) { return vocabulary::NameOf(kSbsOrderNames, o); }

// camera: (live capture). width/height are the device frame; for a side-by-side camera the full
// frame, both halves.
struct CameraSettings {
  std::string left_device;   // kStereoCameras
  std::string right_device;  // kStereoCameras
  std::string device;        // kSbsCamera
  SbsOrder order = SbsOrder::kLeftRight;
  PixelFormat pixel_format = PixelFormat::kYuyv;
  int width = 0;
  int height = 0;
  double fps = 0;
  int buffer_count = 4;
  double pair_tolerance_ms = 0;  // kStereoCameras; default: half a frame period
};

// replay: (recorded files).
struct ReplaySettings {
  std::string dataset;  // kReplayDataset: absolute
  std::string left;     // kReplayGlobs: directory or glob, absolute
  std::string right;
  std::string video;  // kReplayVideo: absolute
  SbsOrder video_order = SbsOrder::kLeftRight;
  camera::BadFramePolicy on_bad_frame = camera::BadFramePolicy::kSkip;  // "skip", "stop"
  bool loop = false;
};

struct StageSettings {
  int threads = 1;
  std::vector<int> cpus;           // affinity; empty: any CPU
  std::optional<int> rt_priority;  // SCHED_FIFO 1..99; nullopt: SCHED_OTHER ("none")
};

struct DeploymentProfile {
  std::string path;  // the profile file as given
  std::string dir;   // its directory, absolute: base of relative paths
  int version = kProfileVersion;
  std::string name;
  std::string description;

  SourceKind source = SourceKind::kReplayGlobs;
  CameraSettings camera;  // when source is kStereoCameras or kSbsCamera
  ReplaySettings replay;  // when source is a kReplay* kind

  std::vector<std::string> calibration;  // 0, 1 or 2 absolute paths (empty: no rectification)

  std::string model_file;  // absolute
  int input_height = 0;
  int input_width = 0;

  StageSettings stages[kStageCount];  // indexed by Stage
  const StageSettings& stage(Stage s) const { return stages[static_cast<int>(s)]; }

  bool mlockall = false;
  bool prefault_arena = false;
  std::optional<long long> memory_cap_mib;  // nullopt: no cap

  double budget_ms = 0;
  double budget_percentile = 99;
  MissAction on_miss = MissAction::kCountOnly;
  int fallback_height = 0;  // on_miss == kSmallerInput
  int fallback_width = 0;
  int recover_after_frames = 30;  // on_miss == kSmallerInput: in-budget frames before full size

  std::string output_dir;  // absolute
  bool write_flow = true;
  FlowFormat flow_format = FlowFormat::kPfm;
  bool visualisation = false;
  bool video = false;
  bool summary = true;

  LogLevel log_level = LogLevel::kInfo;
  std::string log_file;  // absolute; empty: stderr
};

struct Diagnostic {
  std::string file;
  int line = 0;         // 1-based; 0 when the position is unknown (e.g. an unreadable file)
  int column = 0;       // 1-based
  std::string key;      // dotted path: "latency.budget_ms", "stages.infer.cpus[1]"
  std::string problem;  // "must be > 0, got -5"
  std::string allowed;  // "> 0 (milliseconds)", "YUYV, MJPEG, ..."; may be empty
  // file:line:column: key: problem; allowed: allowed
  std::string ToString() const;
};

struct ValidationReport {
  std::vector<Diagnostic> errors;
  std::vector<Diagnostic>
      warnings;  // valid but questionable (e.g. live cameras without calibration)
  bool ok() const { return errors.empty(); }
};

// Parses and validates `path`. A file over kMaxProfileBytes (limits.h) is refused with its size
// before anything is parsed; a binary file (a NUL byte or invalid UTF-8) is refused as binary; a
// tab in the indentation is reported as such, with its line and column. `report` (optional)
// receives every error and warning. On failure the Status is one line: the first error, plus "(and
// N more errors)" when there are more.
Result<DeploymentProfile> LoadProfile(const std::string& path, ValidationReport* report = nullptr);

// Same checks on YAML held in memory; `path` names it in diagnostics and its directory is the
// base of relative paths.
Result<DeploymentProfile> LoadProfileFromString(const std::string& yaml, const std::string& path,
                                                ValidationReport* report = nullptr);

// Prints `errors` one a line (Diagnostic::ToString), at most kMaxPrintedErrors (limits.h) of
// them, then "... and N more errors (the first 50 are shown)".
void PrintErrors(const std::vector<Diagnostic>& errors, std::ostream& out);

// A multi-line human summary of a valid profile (what `sfrt config check` prints after OK).
std::string FormatProfileSummary(const DeploymentProfile& profile);

// Edit distance used for did-you-mean (exposed for tests).
int EditDistance(const std::string& a, const std::string& b);

}  // namespace sfrt::config
