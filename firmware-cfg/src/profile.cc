// Profile parsing and validation. The YAML is walked once; every check reports into a
// ValidationReport and parsing continues, so one pass finds every problem.
#include "sfrt/config/profile.h"

#include <glob.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <ostream>
#include <set>
#include <sstream>
#include <utility>

#include "sfrt/camera/calibration.h"
#include "sfrt/config/limits.h"
#include "sfrt/model.h"
#include "text.h"

namespace sfrt::config {

namespace fs = std::filesystem;

std::string Diagnostic::ToString() const {
  std::string out = file;
  if (line > 0) out += ":" + std::to_string(line) + ":" + std::to_string(column);
  out += ": ";
  if (!key.empty()) out += key + ": ";
  out += problem;
  if (!allowed.empty()) out += "; allowed: " + allowed;
  return out;
}

// Optimal string alignment distance: insertions, deletions, substitutions and adjacent
// transpositions each cost 1 ("pixel_fromat" is 1 from "pixel_format").
int EditDistance(const std::string& a, const std::string& b) {
  const size_t n = a.size();
  const size_t m = b.size();
  std::vector<std::vector<int>> d(n + 1, std::vector<int>(m + 1, 0));
  for (size_t i = 0; i <= n; ++i) d[i][0] = static_cast<int>(i);
  for (size_t j = 0; j <= m; ++j) d[0][j] = static_cast<int>(j);
  for (size_t i = 1; i <= n; ++i) {
    for (size_t j = 1; j <= m; ++j) {
      const int cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[n][m];
}

namespace {

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// The closest candidate when it is close enough to be a plausible typo; "" otherwise.
std::string Suggest(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  int best_distance = 1 << 30;
  const std::string lower = Lower(word);
  for (const std::string& c : candidates) {
    const int dist = EditDistance(lower, Lower(c));
    if (dist < best_distance) {
      best_distance = dist;
      best = c;
    }
  }
  const int limit = std::max(2, static_cast<int>(word.size()) / 3);
  return best_distance <= limit ? best : "";
}

struct Pos {
  int line = 0;
  int column = 0;
};

Pos PosOf(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  if (mark.is_null()) return {};
  return {mark.line + 1, mark.column + 1};
}

// One key's value with where to point at it.
struct Field {
  bool present = false;
  YAML::Node node;
  std::string path;
  Pos pos;      // the value, or the key when the value has no position (an empty value)
  Pos key_pos;  // the key
};

std::string Describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Null:
      return "no value";
    case YAML::NodeType::Map:
      return "a mapping";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Scalar:
      return "'" + node.Scalar() + "'";
    default:
      return "nothing";
  }
}

bool IsQuoted(const YAML::Node& node) { return node.Tag() == "!"; }

class Checker {
 public:
  Checker(std::string file, ValidationReport* report) : file_(std::move(file)), report_(report) {}

  void Error(Pos pos, const std::string& key, const std::string& problem,
             const std::string& allowed = "") {
    report_->errors.push_back({file_, pos.line, pos.column, key, problem, allowed});
  }
  void Warning(Pos pos, const std::string& key, const std::string& problem,
               const std::string& allowed = "") {
    report_->warnings.push_back({file_, pos.line, pos.column, key, problem, allowed});
  }

  const std::string& file() const { return file_; }

 private:
  std::string file_;
  ValidationReport* report_;
};

std::string Child(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// A mapping with a fixed set of keys. Unknown and duplicate keys are reported on construction.
class MapView {
 public:
  MapView(Checker& checker, const Field& field, std::vector<std::string> known)
      : checker_(checker), path_(field.path), anchor_(field.key_pos), known_(std::move(known)) {
    if (!field.present) return;
    if (!field.node.IsMap()) {
      checker_.Error(field.pos, path_, "expected a mapping of keys, got " + Describe(field.node),
                     Join(known_));
      return;
    }
    if (anchor_.line == 0) anchor_ = PosOf(field.node);
    for (auto it = field.node.begin(); it != field.node.end(); ++it) {
      const YAML::Node key = it->first;
      const Pos key_pos = PosOf(key);
      if (!key.IsScalar()) {
        checker_.Error(key_pos, path_, "a key must be a plain name, got " + Describe(key),
                       Join(known_));
        continue;
      }
      const std::string name = key.Scalar();
      const std::string child = Child(path_, name);
      if (std::find(known_.begin(), known_.end(), name) == known_.end()) {
        std::string problem = "unknown key";
        const std::string suggestion = Suggest(name, known_);
        if (!suggestion.empty()) problem += " (did you mean '" + suggestion + "'?)";
        checker_.Error(key_pos, child, problem, Join(known_));
        continue;
      }
      if (entries_.count(name) != 0) {
        checker_.Error(key_pos, child,
                       "duplicate key (first given at line " +
                           std::to_string(entries_[name].key_pos.line) + ")");
        continue;
      }
      Field f;
      f.present = true;
      f.node = it->second;
      f.path = child;
      f.key_pos = key_pos;
      f.pos = PosOf(it->second);
      if (f.pos.line == 0 || it->second.IsNull()) f.pos = key_pos;
      entries_[name] = f;
    }
  }

  // The field (present == false when absent; its positions then point at the enclosing key).
  Field Get(const std::string& name) const {
    auto it = entries_.find(name);
    if (it != entries_.end()) return it->second;
    Field f;
    f.path = Child(path_, name);
    f.pos = anchor_;
    f.key_pos = anchor_;
    return f;
  }
  bool Has(const std::string& name) const { return entries_.count(name) != 0; }

  Field Require(const std::string& name, const std::string& allowed = "") const {
    Field f = Get(name);
    if (!f.present) checker_.Error(anchor_, f.path, "required key is missing", allowed);
    return f;
  }

  // Reports `name` as not applicable ("only with mode: side-by-side").
  void Forbid(const std::string& name, const std::string& why) const {
    if (!Has(name)) return;
    const Field f = Get(name);
    checker_.Error(f.key_pos, f.path, "not used here: " + why);
  }

 private:
  Checker& checker_;
  std::string path_;
  Pos anchor_;
  std::vector<std::string> known_;
  std::map<std::string, Field> entries_;
};

// ---------------------------------------------------------------- scalar readers
// Each returns nullopt after reporting when the value is absent-but-required, of the wrong type
// or out of range; callers keep the default then.

std::optional<long long> ReadInt(Checker& c, const Field& f, long long lo, long long hi,
                                 const std::string& unit = "") {
  if (!f.present) return std::nullopt;
  const std::string allowed = "integer " + std::to_string(lo) + ".." + std::to_string(hi) +
                              (unit.empty() ? "" : " " + unit);
  if (!f.node.IsScalar() || IsQuoted(f.node)) {
    c.Error(f.pos, f.path,
            "expected an integer, got " + (IsQuoted(f.node) ? "the string " : std::string()) +
                Describe(f.node),
            allowed);
    return std::nullopt;
  }
  const std::string& text = f.node.Scalar();
  long long v = 0;
  const char* end = text.data() + text.size();
  auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (text.empty() || ec != std::errc() || ptr != end) {
    c.Error(f.pos, f.path, "expected an integer, got " + Describe(f.node), allowed);
    return std::nullopt;
  }
  if (v < lo || v > hi) {
    c.Error(f.pos, f.path, "out of range: " + text, allowed);
    return std::nullopt;
  }
  return v;
}

// An integer within a limit of the shared table (limits.h), described as the table says.
std::optional<long long> ReadInt(Checker& c, const Field& f, const IntRange& range) {
  std::string unit = range.unit;
  if (range.note[0] != '\0') unit += (unit.empty() ? "(" : " (") + std::string(range.note) + ")";
  return ReadInt(c, f, range.lo, range.hi, unit);
}

struct Range {
  double lo;
  bool lo_open;  // lo itself not allowed
  double hi;
  std::string unit;
  std::string Text() const {
    std::string t = lo_open ? "> " + FormatNumber(lo) + " and <= " + FormatNumber(hi)
                            : FormatNumber(lo) + ".." + FormatNumber(hi);
    if (!unit.empty()) t += " " + unit;
    return t;
  }
};

std::optional<double> ReadNumber(Checker& c, const Field& f, const Range& range) {
  if (!f.present) return std::nullopt;
  const std::string allowed = "number " + range.Text();
  if (!f.node.IsScalar() || IsQuoted(f.node)) {
    c.Error(f.pos, f.path,
            "expected a number, got " + (IsQuoted(f.node) ? "the string " : std::string()) +
                Describe(f.node),
            allowed);
    return std::nullopt;
  }
  const std::string& text = f.node.Scalar();
  double v = 0;
  if (!ParseFiniteNumber(text, &v)) {
    c.Error(f.pos, f.path, "expected a number, got " + Describe(f.node), allowed);
    return std::nullopt;
  }
  if ((range.lo_open ? v <= range.lo : v < range.lo) || v > range.hi) {
    c.Error(f.pos, f.path, "out of range: " + text, allowed);
    return std::nullopt;
  }
  return v;
}

std::optional<bool> ReadBool(Checker& c, const Field& f) {
  if (!f.present) return std::nullopt;
  if (f.node.IsScalar() && !IsQuoted(f.node)) {
    const std::string v = Lower(f.node.Scalar());
    if (v == "true" || v == "yes" || v == "on") return true;
    if (v == "false" || v == "no" || v == "off") return false;
  }
  c.Error(f.pos, f.path, "expected true or false, got " + Describe(f.node), "true, false");
  return std::nullopt;
}

std::optional<std::string> ReadString(Checker& c, const Field& f, const std::string& what) {
  if (!f.present) return std::nullopt;
  if (!f.node.IsScalar() || f.node.Scalar().empty()) {
    c.Error(f.pos, f.path, "expected " + what + ", got " + Describe(f.node));
    return std::nullopt;
  }
  return f.node.Scalar();
}

template <typename E>
std::optional<E> ReadEnum(Checker& c, const Field& f,
                          const std::vector<std::pair<std::string, E>>& table) {
  if (!f.present) return std::nullopt;
  std::vector<std::string> names;
  for (const auto& [name, value] : table) names.push_back(name);
  if (f.node.IsScalar()) {
    const std::string v = Lower(f.node.Scalar());
    for (const auto& [name, value] : table) {
      if (Lower(name) == v) return value;
    }
    std::string problem = "unknown value " + Describe(f.node);
    const std::string suggestion = Suggest(f.node.Scalar(), names);
    if (!suggestion.empty()) problem += " (did you mean '" + suggestion + "'?)";
    c.Error(f.pos, f.path, problem, Join(names));
    return std::nullopt;
  }
  c.Error(f.pos, f.path, "expected one of the names, got " + Describe(f.node), Join(names));
  return std::nullopt;
}

// The same for a vocabulary declared with its names beside it (sfrt/vocabulary/names.h).
template <typename E, size_t N>
std::optional<E> ReadEnum(Checker& c, const Field& f, const std::array<const char*, N>& names) {
  std::vector<std::pair<std::string, E>> table;
  for (size_t i = 0; i < N; ++i) table.emplace_back(names[i], static_cast<E>(i));
  return ReadEnum<E>(c, f, table);
}

// "none" or an integer in lo..hi. Returns {present-and-valid, value}.
std::optional<std::optional<long long>> ReadNoneOrInt(Checker& c, const Field& f, long long lo,
                                                      long long hi, const std::string& unit) {
  if (!f.present) return std::nullopt;
  if (f.node.IsScalar() && Lower(f.node.Scalar()) == "none") {
    return std::optional<long long>();
  }
  const std::string allowed = "none, or integer " + std::to_string(lo) + ".." + std::to_string(hi) +
                              (unit.empty() ? "" : " " + unit);
  if (!f.node.IsScalar() || IsQuoted(f.node)) {
    c.Error(f.pos, f.path, "expected none or an integer, got " + Describe(f.node), allowed);
    return std::nullopt;
  }
  const std::string& text = f.node.Scalar();
  long long v = 0;
  const char* end = text.data() + text.size();
  auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (text.empty() || ec != std::errc() || ptr != end) {
    c.Error(f.pos, f.path, "expected none or an integer, got " + Describe(f.node), allowed);
    return std::nullopt;
  }
  if (v < lo || v > hi) {
    c.Error(f.pos, f.path, "out of range: " + text, allowed);
    return std::nullopt;
  }
  return std::optional<long long>(v);
}

std::string Resolve(const std::string& dir, const std::string& path) {
  fs::path p(path);
  if (p.is_relative()) p = fs::path(dir) / p;
  return p.lexically_normal().string();
}

bool IsRegularFile(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

bool IsDirectory(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

// Number of regular files a glob pattern matches.
size_t CountGlobMatches(const std::string& pattern) {
  glob_t g;
  std::memset(&g, 0, sizeof(g));
  size_t count = 0;
  if (glob(pattern.c_str(), 0, nullptr, &g) == 0) {
    for (size_t i = 0; i < g.gl_pathc; ++i) {
      if (IsRegularFile(g.gl_pathv[i])) ++count;
    }
  }
  globfree(&g);
  return count;
}

size_t CountFilesIn(const std::string& dir) {
  size_t count = 0;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (entry.is_regular_file(ec)) ++count;
  }
  return count;
}

// ------------------------------------------------------------------------- sections

const std::vector<std::string> kTopKeys = {"version", "name",        "description", "camera",
                                           "replay",  "calibration", "model",       "stages",
                                           "memory",  "latency",     "outputs",     "logging"};

class Parser {
 public:
  Parser(Checker& checker, DeploymentProfile& profile) : c_(checker), p_(profile) {}

  void Parse(const YAML::Node& root) {
    Field top;
    top.present = true;
    top.node = root;
    top.pos = PosOf(root);
    top.key_pos = top.pos.line > 0 ? top.pos : Pos{1, 1};
    if (root.IsNull()) {
      c_.Error({1, 1}, "", "the profile is empty", "a mapping with keys " + Join(kTopKeys));
      return;
    }
    MapView m(c_, top, kTopKeys);
    if (!root.IsMap()) return;

    const Field version = m.Require("version", "1");
    if (auto v = ReadInt(c_, version, 1, 1000)) {
      if (*v != kProfileVersion) {
        c_.Error(version.pos, "version", "unsupported profile version " + std::to_string(*v),
                 std::to_string(kProfileVersion));
      }
    }
    if (auto v = ReadString(c_, m.Get("name"), "a name")) p_.name = *v;
    if (auto v = ReadString(c_, m.Get("description"), "a text")) p_.description = *v;

    const bool has_camera = m.Has("camera");
    const bool has_replay = m.Has("replay");
    if (has_camera && has_replay) {
      c_.Error(m.Get("replay").key_pos, "replay", "both 'camera' and 'replay' are given",
               "exactly one of camera, replay");
    } else if (!has_camera && !has_replay) {
      c_.Error(top.key_pos, "camera", "no source: neither 'camera' nor 'replay' is given",
               "exactly one of camera, replay");
    }
    if (has_camera) ParseCamera(m.Get("camera"));
    if (has_replay && !has_camera) ParseReplay(m.Get("replay"));

    ParseCalibration(m.Get("calibration"), has_camera && !has_replay);
    ParseModel(m.Require("model", "a mapping with file, input_height, input_width"));
    ParseStages(m.Get("stages"));
    ParseMemory(m.Get("memory"));
    ParseLatency(m.Require("latency", "a mapping with budget_ms (required), percentile, on_miss"));
    ParseOutputs(m.Require(
        "outputs",
        "a mapping with dir (required), flow, flow_format, visualisation, video, summary"));
    ParseLogging(m.Get("logging"));
  }

 private:
  std::string ReadPath(const Field& f, const std::string& what) {
    auto v = ReadString(c_, f, what);
    return v ? Resolve(p_.dir, *v) : std::string();
  }

  std::string ReadDevice(const Field& f) {
    auto v = ReadString(c_, f, "a device path");
    if (!v) return "";
    if (v->empty() || (*v)[0] != '/') {
      c_.Error(f.pos, f.path, "not an absolute device path: '" + *v + "'",
               "an absolute path such as /dev/video0 or /dev/v4l/by-path/...");
      return "";
    }
    return *v;
  }

  void ParseCamera(const Field& field) {
    MapView m(c_, field,
              {"mode", "left_device", "right_device", "device", "order", "pixel_format", "width",
               "height", "fps", "buffer_count", "pair_tolerance_ms"});
    if (!field.node.IsMap()) return;
    CameraSettings& cam = p_.camera;
    const std::vector<std::pair<std::string, SourceKind>> modes = {
        {"stereo", SourceKind::kStereoCameras}, {"side-by-side", SourceKind::kSbsCamera}};
    const Field mode_field = m.Require("mode", "stereo, side-by-side");
    const auto mode = ReadEnum(c_, mode_field, modes);
    if (mode) p_.source = *mode;
    if (mode == SourceKind::kStereoCameras) {
      cam.left_device =
          ReadDevice(m.Require("left_device", "an absolute device path such as /dev/video0"));
      cam.right_device =
          ReadDevice(m.Require("right_device", "an absolute device path such as /dev/video2"));
      if (!cam.left_device.empty() && cam.left_device == cam.right_device) {
        c_.Error(m.Get("right_device").pos, m.Get("right_device").path,
                 "the same device as left_device: '" + cam.left_device + "'",
                 "two different devices");
      }
      m.Forbid("device", "a single side-by-side device needs mode: side-by-side");
      m.Forbid("order", "order applies to mode: side-by-side");
    } else if (mode == SourceKind::kSbsCamera) {
      cam.device = ReadDevice(m.Require("device", "an absolute device path such as /dev/video0"));
      if (auto v = ReadEnum<SbsOrder>(c_, m.Get("order"), kSbsOrderNames)) cam.order = *v;
      m.Forbid("left_device", "two devices need mode: stereo");
      m.Forbid("right_device", "two devices need mode: stereo");
      m.Forbid("pair_tolerance_ms", "one side-by-side device needs no pairing");
    }
    const Field fmt_field = m.Require("pixel_format", "YUYV, MJPEG, GREY, NV12, BGR24, RGB24");
    const auto fmt = ReadEnum<PixelFormat>(c_, fmt_field, kPixelFormatNames);
    if (fmt) cam.pixel_format = *fmt;
    const Field width = m.Require("width", "integer " + RangeText(kFrameSide));
    const Field height = m.Require("height", "integer " + RangeText(kFrameSide));
    if (auto v = ReadInt(c_, width, kFrameSide)) cam.width = static_cast<int>(*v);
    if (auto v = ReadInt(c_, height, kFrameSide)) cam.height = static_cast<int>(*v);
    if (cam.width > 0 && cam.width % 2 != 0) {
      if (mode == SourceKind::kSbsCamera) {
        c_.Error(width.pos, width.path,
                 "a side-by-side frame must split into two halves: " + std::to_string(cam.width) +
                     " is odd",
                 "an even width");
      } else if (fmt == PixelFormat::kYuyv || fmt == PixelFormat::kNv12) {
        c_.Error(width.pos, width.path,
                 std::string(PixelFormatName(*fmt)) + " needs an even width, got " +
                     std::to_string(cam.width),
                 "an even width");
      }
    }
    if (fmt == PixelFormat::kNv12 && cam.height > 0 && cam.height % 2 != 0) {
      c_.Error(height.pos, height.path,
               "NV12 needs an even height, got " + std::to_string(cam.height), "an even height");
    }
    if (auto v = ReadNumber(c_, m.Require("fps", "number > 0 and <= 1000 frames per second"),
                            {0, true, 1000, "frames per second"})) {
      cam.fps = *v;
    }
    if (auto v = ReadInt(c_, m.Get("buffer_count"), kCameraBuffers)) {
      cam.buffer_count = static_cast<int>(*v);
    }
    if (mode == SourceKind::kStereoCameras) {
      if (auto v = ReadNumber(c_, m.Get("pair_tolerance_ms"), {0, true, 1000, "ms"})) {
        cam.pair_tolerance_ms = *v;
      } else if (cam.fps > 0) {
        cam.pair_tolerance_ms = 500.0 / cam.fps;  // half a frame period
      }
    }
  }

  void ParseReplay(const Field& field) {
    MapView m(c_, field, {"dataset", "left", "right", "video", "order", "on_bad_frame", "loop"});
    if (!field.node.IsMap()) return;
    ReplaySettings& r = p_.replay;
    const bool dataset = m.Has("dataset");
    const bool globs = m.Has("left") || m.Has("right");
    const bool video = m.Has("video");
    const int given = int{dataset} + int{globs} + int{video};
    const std::string one_of = "exactly one of dataset, left + right, video";
    if (given == 0) {
      c_.Error(field.key_pos, field.path, "no replay input given", one_of);
      return;
    }
    if (given > 1) {
      c_.Error(field.key_pos, field.path, "more than one replay input given", one_of);
      return;
    }
    if (dataset) {
      p_.source = SourceKind::kReplayDataset;
      const Field f = m.Get("dataset");
      r.dataset = ReadPath(f, "a dataset directory");
      if (!r.dataset.empty() && !IsDirectory(r.dataset)) {
        c_.Error(f.pos, f.path, "dataset directory does not exist: '" + r.dataset + "'");
      }
    } else if (globs) {
      p_.source = SourceKind::kReplayGlobs;
      const Field lf = m.Require("left", "a directory or glob pattern");
      const Field rf = m.Require("right", "a directory or glob pattern");
      r.left = ReadPath(lf, "a directory or glob pattern");
      r.right = ReadPath(rf, "a directory or glob pattern");
      const size_t nl = CheckFrames(lf, r.left);
      const size_t nr = CheckFrames(rf, r.right);
      if (nl > 0 && nr > 0 && nl != nr) {
        c_.Warning(rf.pos, rf.path,
                   "left has " + std::to_string(nl) + " files but right has " + std::to_string(nr) +
                       "; frames are paired by sorted name");
      }
    } else {
      p_.source = SourceKind::kReplayVideo;
      const Field f = m.Get("video");
      r.video = ReadPath(f, "a video file");
      if (!r.video.empty() && !IsRegularFile(r.video)) {
        c_.Error(f.pos, f.path, "video file does not exist: '" + r.video + "'");
      }
      if (auto v = ReadEnum<SbsOrder>(c_, m.Get("order"), kSbsOrderNames)) r.video_order = *v;
    }
    if (!video) m.Forbid("order", "order applies to a side-by-side video");
    if (auto v = ReadEnum<camera::BadFramePolicy>(c_, m.Get("on_bad_frame"),
                                                  vocabulary::kFailurePolicyNames)) {
      r.on_bad_frame = *v;
    }
    if (auto v = ReadBool(c_, m.Get("loop"))) r.loop = *v;
  }

  // Files a replay directory or glob provides (0 after reporting when there are none).
  size_t CheckFrames(const Field& f, const std::string& resolved) {
    if (resolved.empty()) return 0;
    if (IsDirectory(resolved)) {
      const size_t n = CountFilesIn(resolved);
      if (n == 0) c_.Error(f.pos, f.path, "directory has no files: '" + resolved + "'");
      return n;
    }
    const size_t n = CountGlobMatches(resolved);
    if (n == 0) {
      c_.Error(f.pos, f.path, "no file matches '" + resolved + "'",
               "an existing directory or a glob pattern matching frame files");
    }
    return n;
  }

  void ParseCalibration(const Field& f, bool live_camera) {
    if (!f.present) {
      if (live_camera) {
        c_.Warning(f.key_pos, "calibration",
                   "not given: live frames go to the network unrectified");
      }
      return;
    }
    std::vector<Field> items;
    if (f.node.IsScalar()) {
      items.push_back(f);
    } else if (f.node.IsSequence() && f.node.size() >= 1 && f.node.size() <= 2) {
      for (size_t i = 0; i < f.node.size(); ++i) {
        Field item;
        item.present = true;
        item.node = f.node[i];
        item.path = f.path + "[" + std::to_string(i) + "]";
        item.pos = PosOf(item.node);
        if (item.pos.line == 0) item.pos = f.pos;
        item.key_pos = f.key_pos;
        items.push_back(item);
      }
    } else {
      c_.Error(f.pos, f.path, "expected a file or a list of two files, got " + Describe(f.node),
               "one file (Kalibr camchain, OpenCV YAML) or two (ROS camera_info left, right)");
      return;
    }
    bool all_exist = true;
    for (const Field& item : items) {
      const std::string path = ReadPath(item, "a calibration file");
      if (path.empty()) {
        all_exist = false;
        continue;
      }
      if (!IsRegularFile(path)) {
        c_.Error(item.pos, item.path, "calibration file does not exist: '" + path + "'");
        all_exist = false;
      }
      p_.calibration.push_back(path);
    }
    if (!all_exist) return;
    auto calib = sfrt::camera::ReadStereoCalibration(p_.calibration);
    if (!calib.ok()) {
      c_.Error(f.pos, f.path, "bad calibration: " + calib.message(),
               "ROS camera_info pair, Kalibr camchain, OpenCV FileStorage (camera/sources)");
      return;
    }
    const cv::Size size = calib->image_size;
    if (live_camera && size.width > 0 && p_.camera.width > 0) {
      const int w = p_.source == SourceKind::kSbsCamera ? p_.camera.width / 2 : p_.camera.width;
      // An error, not a warning: sfrt run refuses it too (StereoRectifier::Create), since
      // rectification maps made for another resolution would warp every frame wrongly.
      if (size.width != w || size.height != p_.camera.height) {
        c_.Error(f.pos, f.path,
                 calib->source + ": calibrated at " + std::to_string(size.height) + "x" +
                     std::to_string(size.width) + " (HxW) but the camera delivers " +
                     std::to_string(p_.camera.height) + "x" + std::to_string(w) + " (HxW) per eye",
                 "a calibration made at the camera's resolution (recalibrate, or set "
                 "camera.width and camera.height to the calibrated size)");
      }
    }
  }

  void ParseModel(const Field& field) {
    MapView m(c_, field, {"file", "input_height", "input_width"});
    if (!field.present || !field.node.IsMap()) return;
    const Field file = m.Require("file", "a .sfrt model file");
    p_.model_file = ReadPath(file, "a model file (.sfrt)");
    if (!p_.model_file.empty()) {
      if (!IsRegularFile(p_.model_file)) {
        c_.Error(file.pos, file.path, "model file does not exist: '" + p_.model_file + "'");
      } else {
        auto model = sfrt::Model::LoadFile(p_.model_file);
        if (!model.ok()) {
          c_.Error(file.pos, file.path, "model file does not load: " + model.message());
        }
      }
    }
    const std::string side = "integer " + RangeText(kInputSide);
    if (auto v = ReadInt(c_, m.Require("input_height", side), kInputSide)) {
      p_.input_height = static_cast<int>(*v);
    }
    if (auto v = ReadInt(c_, m.Require("input_width", side), kInputSide)) {
      p_.input_width = static_cast<int>(*v);
    }
  }

  void ParseStages(const Field& field) {
    std::vector<std::string> names;
    for (int s = 0; s < kStageCount; ++s) names.push_back(StageName(static_cast<Stage>(s)));
    std::vector<std::string> keys = names;
    keys.push_back(kOldSourceStageName);
    MapView m(c_, field, keys);
    if (!field.present || !field.node.IsMap()) return;
    for (int s = 0; s < kStageCount; ++s) {
      Field sf = m.Get(names[s]);
      if (s == static_cast<int>(Stage::kSource)) {
        const Field old = m.Get(kOldSourceStageName);
        if (old.present && sf.present) {
          c_.Error(old.key_pos, "stages." + std::string(kOldSourceStageName),
                   "names the source stage a second time (beside stages.source)", "");
        } else if (old.present) {
          c_.Warning(old.key_pos, "stages." + std::string(kOldSourceStageName),
                     "is the old name of the source stage; write stages.source", "");
          sf = old;
        }
      }
      if (!sf.present) continue;
      MapView sm(c_, sf, {"threads", "cpus", "priority"});
      if (!sf.node.IsMap()) continue;
      StageSettings& st = p_.stages[s];
      if (auto v = ReadInt(c_, sm.Get("threads"), kThreads)) {
        st.threads = static_cast<int>(*v);
      }
      if (auto v = ReadNoneOrInt(c_, sm.Get("priority"), 1, 99, "(SCHED_FIFO)")) {
        if (v->has_value()) st.rt_priority = static_cast<int>(**v);
      }
      ReadCpus(sm.Get("cpus"), &st.cpus);
    }
  }

  void ReadCpus(const Field& f, std::vector<int>* cpus) {
    if (!f.present) return;
    const std::string allowed = "a list of CPU numbers 0..1023, e.g. [0, 1]";
    if (!f.node.IsSequence()) {
      c_.Error(f.pos, f.path, "expected a list, got " + Describe(f.node), allowed);
      return;
    }
    for (size_t i = 0; i < f.node.size(); ++i) {
      Field item;
      item.present = true;
      item.node = f.node[i];
      item.path = f.path + "[" + std::to_string(i) + "]";
      item.pos = PosOf(item.node);
      if (item.pos.line == 0) item.pos = f.pos;
      if (auto v = ReadInt(c_, item, 0, 1023, "(CPU number)")) {
        if (std::find(cpus->begin(), cpus->end(), *v) != cpus->end()) {
          c_.Error(item.pos, item.path, "CPU " + std::to_string(*v) + " is listed twice");
        } else {
          cpus->push_back(static_cast<int>(*v));
        }
      }
    }
  }

  void ParseMemory(const Field& field) {
    MapView m(c_, field, {"mlockall", "prefault_arena", "cap_mib"});
    if (!field.present || !field.node.IsMap()) return;
    if (auto v = ReadBool(c_, m.Get("mlockall"))) p_.mlockall = *v;
    if (auto v = ReadBool(c_, m.Get("prefault_arena"))) p_.prefault_arena = *v;
    if (auto v = ReadNoneOrInt(c_, m.Get("cap_mib"), 16, 1 << 24, "MiB")) p_.memory_cap_mib = *v;
  }

  void ParseLatency(const Field& field) {
    MapView m(c_, field,
              {"budget_ms", "percentile", "on_miss", "fallback_height", "fallback_width",
               "recover_after_frames"});
    if (!field.present || !field.node.IsMap()) return;
    if (auto v = ReadNumber(c_, m.Require("budget_ms", "number > 0 and <= 60000 ms"),
                            {0, true, 60000, "ms"})) {
      p_.budget_ms = *v;
    }
    if (auto v = ReadNumber(c_, m.Get("percentile"), {50, false, 100, "(percent)"})) {
      p_.budget_percentile = *v;
    }
    const auto miss = ReadEnum<MissAction>(c_, m.Get("on_miss"), kMissActionNames);
    if (miss) p_.on_miss = *miss;
    if (miss == MissAction::kSmallerInput) {
      const std::string side = "integer " + RangeText(kInputSide);
      const Field fh = m.Require("fallback_height", side + ", below input_height");
      const Field fw = m.Require("fallback_width", side + ", below input_width");
      if (auto v = ReadInt(c_, fh, kInputSide)) p_.fallback_height = static_cast<int>(*v);
      if (auto v = ReadInt(c_, fw, kInputSide)) p_.fallback_width = static_cast<int>(*v);
      if (auto v = ReadInt(c_, m.Get("recover_after_frames"), 1, 100000, "frames")) {
        p_.recover_after_frames = static_cast<int>(*v);
      }
      if (p_.fallback_height > 0 && p_.fallback_width > 0 && p_.input_height > 0 &&
          p_.input_width > 0 &&
          (p_.fallback_height > p_.input_height || p_.fallback_width > p_.input_width ||
           (p_.fallback_height == p_.input_height && p_.fallback_width == p_.input_width))) {
        c_.Error(fh.pos, fh.path,
                 "fallback size " + std::to_string(p_.fallback_height) + "x" +
                     std::to_string(p_.fallback_width) + " is not smaller than model input " +
                     std::to_string(p_.input_height) + "x" + std::to_string(p_.input_width),
                 "at most the model input size in each dimension, and smaller in one");
      }
    } else {
      m.Forbid("fallback_height", "only with on_miss: smaller-input");
      m.Forbid("fallback_width", "only with on_miss: smaller-input");
      m.Forbid("recover_after_frames", "only with on_miss: smaller-input");
    }
  }

  void ParseOutputs(const Field& field) {
    MapView m(c_, field, {"dir", "flow", "flow_format", "visualisation", "video", "summary"});
    if (!field.present || !field.node.IsMap()) return;
    p_.output_dir = ReadPath(m.Require("dir", "an output directory"), "an output directory");
    if (auto v = ReadBool(c_, m.Get("flow"))) p_.write_flow = *v;
    if (auto v = ReadEnum<FlowFormat>(c_, m.Get("flow_format"), kFlowFormatNames)) {
      p_.flow_format = *v;
    }
    if (auto v = ReadBool(c_, m.Get("visualisation"))) p_.visualisation = *v;
    if (auto v = ReadBool(c_, m.Get("video"))) p_.video = *v;
    if (auto v = ReadBool(c_, m.Get("summary"))) p_.summary = *v;
  }

  void ParseLogging(const Field& field) {
    MapView m(c_, field, {"level", "file"});
    if (!field.present || !field.node.IsMap()) return;
    if (auto v = ReadEnum<LogLevel>(c_, m.Get("level"), kLogLevelNames)) {
      p_.log_level = *v;
    }
    if (m.Has("file")) p_.log_file = ReadPath(m.Get("file"), "a log file path");
  }

  Checker& c_;
  DeploymentProfile& p_;
};

Result<DeploymentProfile> Finish(DeploymentProfile profile, ValidationReport& report,
                                 ValidationReport* out) {
  // Report in file order, whatever order the sections were checked in.
  auto by_position = [](const Diagnostic& a, const Diagnostic& b) {
    return a.line != b.line ? a.line < b.line : a.column < b.column;
  };
  std::stable_sort(report.errors.begin(), report.errors.end(), by_position);
  std::stable_sort(report.warnings.begin(), report.warnings.end(), by_position);
  if (out != nullptr) *out = report;
  if (report.ok()) return profile;
  std::string message = report.errors.front().ToString();
  if (report.errors.size() > 1) {
    const size_t more = report.errors.size() - 1;
    message += " (and " + std::to_string(more) + " more error" + (more > 1 ? "s" : "") + ")";
  }
  return Status::Error(message);
}

}  // namespace

namespace {

// Where the first NUL byte or invalid UTF-8 sequence is, as "line L, column C" (1-based, column in
// bytes); "" for text.
std::string FindBinary(const std::string& text, std::string* what) {
  int line = 1;
  size_t line_start = 0;
  for (size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    size_t len = 1;
    bool bad = c == 0;
    if (c >= 0x80) {
      len = (c & 0xE0) == 0xC0 ? 2 : (c & 0xF0) == 0xE0 ? 3 : (c & 0xF8) == 0xF0 ? 4 : 0;
      bad = len == 0 || c == 0xC0 || c == 0xC1 || c > 0xF4 || i + len > text.size();
      for (size_t k = 1; !bad && k < len; ++k) {
        bad = (static_cast<unsigned char>(text[i + k]) & 0xC0) != 0x80;
      }
    }
    if (bad) {
      *what = c == 0 ? "a NUL byte" : "invalid UTF-8";
      return "line " + std::to_string(line) + ", column " + std::to_string(i - line_start + 1);
    }
    if (c == '\n') {
      ++line;
      line_start = i + 1;
    }
    i += len;
  }
  return "";
}

// The first tab in the indentation of a line at or before `last_line` (1-based), or {0, 0}.
Pos FindIndentationTab(const std::string& text, int last_line) {
  int line = 1;
  size_t start = 0;
  while (start <= text.size() && (last_line <= 0 || line <= last_line)) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    for (size_t i = start; i < end && (text[i] == ' ' || text[i] == '\t'); ++i) {
      if (text[i] == '\t') return {line, static_cast<int>(i - start) + 1};
    }
    if (end == text.size()) break;
    start = end + 1;
    ++line;
  }
  return {};
}

}  // namespace

void PrintErrors(const std::vector<Diagnostic>& errors, std::ostream& out) {
  const size_t shown = std::min(errors.size(), kMaxPrintedErrors);
  for (size_t i = 0; i < shown; ++i) out << errors[i].ToString() << "\n";
  if (errors.size() > shown) {
    const size_t more = errors.size() - shown;
    out << "... and " << more << " more error" << (more == 1 ? "" : "s") << " (the first "
        << kMaxPrintedErrors << " are shown)\n";
  }
}

Result<DeploymentProfile> LoadProfileFromString(const std::string& yaml, const std::string& path,
                                                ValidationReport* report) {
  ValidationReport local;
  Checker checker(path, &local);
  DeploymentProfile profile;
  profile.path = path;
  std::error_code ec;
  fs::path dir = fs::path(path).parent_path();
  profile.dir = fs::absolute(dir.empty() ? fs::path(".") : dir, ec).lexically_normal().string();
  if (profile.dir.size() > 1 && profile.dir.back() == '/') profile.dir.pop_back();
  if (yaml.size() > kMaxProfileBytes) {
    checker.Error({}, "",
                  "the profile is " + std::to_string(yaml.size()) + " bytes; the limit is " +
                      std::to_string(kMaxProfileBytes) + " bytes (1 MiB)");
    return Finish(std::move(profile), local, report);
  }
  std::string binary_what;
  if (const std::string where = FindBinary(yaml, &binary_what); !where.empty()) {
    checker.Error({}, "",
                  "a binary file, not a YAML profile (" + binary_what + " at " + where + ")");
    return Finish(std::move(profile), local, report);
  }
  try {
    const YAML::Node root = YAML::Load(yaml);
    Parser(checker, profile).Parse(root);
  } catch (const YAML::Exception& e) {
    // Syntax errors (and anything yaml-cpp rejects) stop the walk: the tree is unusable.
    Pos pos;
    if (!e.mark.is_null()) pos = {e.mark.line + 1, e.mark.column + 1};
    if (const Pos tab = FindIndentationTab(yaml, pos.line); tab.line > 0) {
      checker.Error(tab, "", "a tab in the indentation; YAML indents with spaces only");
    } else {
      checker.Error(pos, "", "YAML syntax error: " + e.msg);
    }
  }
  return Finish(std::move(profile), local, report);
}

Result<DeploymentProfile> LoadProfile(const std::string& path, ValidationReport* report) {
  std::ifstream in(path, std::ios::binary);
  if (!in || IsDirectory(path)) {
    ValidationReport local;
    const char* why = IsDirectory(path) ? "is a directory" : std::strerror(errno);
    local.errors.push_back({path, 0, 0, "", std::string("cannot read profile: ") + why, ""});
    return Finish(DeploymentProfile{}, local, report);
  }
  // At most one byte over the limit is read (the file may be a pipe or a device, with no size).
  std::string text(kMaxProfileBytes + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<size_t>(in.gcount()));
  if (text.size() > kMaxProfileBytes) {
    ValidationReport local;
    std::error_code ec;
    const std::uintmax_t size = fs::is_regular_file(path, ec) ? fs::file_size(path, ec) : 0;
    const std::string how_big = size > 0 && !ec
                                    ? std::to_string(size) + " bytes"
                                    : "more than " + std::to_string(kMaxProfileBytes) + " bytes";
    local.errors.push_back({path, 0, 0, "",
                            "the profile is " + how_big + "; the limit is " +
                                std::to_string(kMaxProfileBytes) +
                                " bytes (1 MiB); nothing was parsed",
                            ""});
    return Finish(DeploymentProfile{}, local, report);
  }
  return LoadProfileFromString(text, path, report);
}

}  // namespace sfrt::config
