#include "synth/dataset.h"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/io/pfm.h"

namespace sfrt::synth {
namespace {

namespace fs = std::filesystem;

std::string Number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out.push_back('\\');
      out.push_back(c);
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", static_cast<unsigned>(c));
      out += buf;
    } else {
      out.push_back(c);
    }
  }
  return out + "\"";
}

Status WriteText(const fs::path& path, const std::string& text) {
  return io::WriteFileAtomically(
      path.string(),
      std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
}

Status MakeDirs(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Status::Error("cannot create directory '" + dir.string() + "': " + ec.message());
  return Status::Ok();
}

Status WritePng(const fs::path& path, const std::vector<uint8_t>& bgr, int height, int width) {
  cv::Mat img(height, width, CV_8UC3, const_cast<uint8_t*>(bgr.data()));
  std::vector<uint8_t> bytes;
  if (!cv::imencode(".png", img, bytes)) {
    return Status::Error("cannot encode '" + path.string() + "' as PNG");
  }
  return io::WriteFileAtomically(path.string(), bytes);
}

// The value after `"key":` in a camera.json as sfrt synth writes it, up to the next ',', '}' or
// newline (strings keep their quotes); "" when the key is absent.
std::string JsonValue(const std::string& text, const std::string& key) {
  const std::string quoted = "\"" + key + "\"";
  size_t pos = text.find(quoted);
  if (pos == std::string::npos) return "";
  pos = text.find(':', pos + quoted.size());
  if (pos == std::string::npos) return "";
  pos = text.find_first_not_of(" \t", pos + 1);
  if (pos == std::string::npos) return "";
  const size_t end = text.find_first_of(",}\n", pos);
  std::string v = text.substr(pos, end == std::string::npos ? std::string::npos : end - pos);
  while (!v.empty() && (v.back() == ' ' || v.back() == '\t' || v.back() == '\r')) v.pop_back();
  return v;
}

constexpr char kGenerator[] = "\"sfrt synth\"";

// Whether `dir`/camera.json says sfrt synth wrote it; its text in *text.
bool WrittenBySynth(const fs::path& dir, std::string* text) {
  std::error_code ec;
  if (!fs::is_regular_file(dir / "camera.json", ec)) return false;
  Result<std::string> read = io::ReadWholeFile((dir / "camera.json").string());
  if (!read.ok()) return false;
  *text = std::move(read).value();
  return JsonValue(*text, "generator") == kGenerator;
}

// `path` without trailing separators, so that "<out>.partial-<pid>" is a sibling of it.
fs::path Trimmed(const std::string& path) {
  std::string p = path;
  while (p.size() > 1 && p.back() == '/') p.pop_back();
  return fs::path(p);
}

std::string CameraJson(const DatasetOptions& o) {
  const Camera& c = o.scene.camera;
  std::string s = "{\n";
  s += "  \"generator\": \"sfrt synth\",\n";
  s += "  \"layout\": \"scene flow datasets (frames_cleanpass, disparity, disparity_change, "
       "optical_flow, scene_flow)\",\n";
  s += "  \"focal\": " + Number(c.focal) + ",\n";
  s += "  \"baseline\": " + Number(c.baseline) + ",\n";
  s += "  \"cx\": " + Number(c.cx) + ",\n";
  s += "  \"cy\": " + Number(c.cy) + ",\n";
  s += "  \"width\": " + std::to_string(c.width) + ",\n";
  s += "  \"height\": " + std::to_string(c.height) + ",\n";
  s += "  \"seed\": " + std::to_string(o.seed) + ",\n";
  s += "  \"sequences\": " + std::to_string(o.sequences) + ",\n";
  s += "  \"frames\": " + std::to_string(o.scene.frames) + ",\n";
  s += "  \"objects\": " + std::to_string(o.scene.objects) + ",\n";
  s += std::string("  \"scene\": ") +
       (o.scene.preset == ScenePreset::kRobot ? "\"robot\"" : "\"room\"") + ",\n";
  if (o.scene.preset == ScenePreset::kRobot) {
    s += "  \"max_pitch_rate\": " + Number(o.scene.max_pitch_rate) + ",\n";
    s += "  \"max_speed\": " + Number(o.scene.max_speed) + ",\n";
  }
  s += "  \"textures\": " +
       (o.texture_dir.empty() ? std::string("\"procedural\"") : JsonString(o.texture_dir)) + ",\n";
  s += "  \"noise_sigma\": " + Number(o.noise_sigma) + ",\n";
  s += "  \"blur_sigma\": " + Number(o.blur_sigma) + ",\n";
  s += "  \"complete\": true\n";  // camera.json is written last: see WriteDataset
  s += "}\n";
  return s;
}

std::string CameraDataTxt(const DatasetOptions& o) {
  const std::string b = Number(o.scene.camera.baseline);
  std::string s;
  for (int f = 0; f < o.scene.frames; ++f) {
    s += "Frame " + std::to_string(f) + "\n";
    s += "L 1 0 0 0 0 -1 0 0 0 0 -1 0 0 0 0 1\n";
    s += "R 1 0 0 " + b + " 0 -1 0 0 0 0 -1 0 0 0 0 1\n\n";
  }
  return s;
}

}  // namespace

std::string SequenceName(int sequence) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%04d", sequence);
  return buf;
}

std::string FrameName(int frame) { return SequenceName(frame); }

Result<Scene> MakeDatasetScene(const DatasetOptions& options, int sequence) {
  TextureSource source;
  if (!options.texture_dir.empty()) {
    Result<std::vector<std::string>> files = ListTextureImages(options.texture_dir);
    if (!files.ok()) return files.status();
    source = TextureSource(std::move(files).value());
  }
  return MakeRandomScene(options.scene, options.seed, sequence, source);
}

RenderOptions MakeRenderOptions(const DatasetOptions& options, int sequence) {
  RenderOptions r;
  r.noise_sigma = options.noise_sigma;
  r.blur_sigma = options.blur_sigma;
  r.noise_seed = MixSeed(options.seed, static_cast<uint64_t>(sequence), 0x701CE);
  r.threads = options.threads;
  return r;
}

namespace {

// Writes the whole data set into `root` (a new directory), camera.json last.
Status WriteTree(const DatasetOptions& options, const fs::path& root,
                 const std::function<void(const DatasetProgress&)>& progress) {
  if (Status s = MakeDirs(root); !s.ok()) return s;

  TextureSource source;
  if (!options.texture_dir.empty()) {
    Result<std::vector<std::string>> files = ListTextureImages(options.texture_dir);
    if (!files.ok()) return files.status();
    source = TextureSource(std::move(files).value());
  }
  const int h = options.scene.camera.height;
  const int w = options.scene.camera.width;
  DatasetProgress p;
  p.frames_total = options.sequences * options.scene.frames;
  for (int s = 0; s < options.sequences; ++s) {
    Result<Scene> scene = MakeRandomScene(options.scene, options.seed, s, source);
    if (!scene.ok()) return scene.status();
    const std::string seq = SequenceName(s);
    const fs::path images = root / "frames_cleanpass" / seq;
    const fs::path disp = root / "disparity" / seq / "left";
    const fs::path dchange = root / "disparity_change" / seq / "into_future" / "left";
    const fs::path flow = root / "optical_flow" / seq / "into_future" / "left";
    const fs::path sflow = root / "scene_flow" / seq / "into_future" / "left";
    const fs::path camera_data = root / "camera_data" / seq;
    for (const fs::path& dir :
         {images / "left", images / "right", disp, dchange, flow, sflow, camera_data}) {
      if (Status st = MakeDirs(dir); !st.ok()) return st;
    }
    if (Status st = WriteText(camera_data / "camera_data.txt", CameraDataTxt(options)); !st.ok()) {
      return st;
    }
    const RenderOptions render = MakeRenderOptions(options, s);
    for (int f = 0; f < options.scene.frames; ++f) {
      if (options.stop != nullptr && options.stop->load()) {
        return Status::Error("stopped by a signal after " + std::to_string(p.frames_done) + " of " +
                             std::to_string(p.frames_total) + " frames");
      }
      RenderedFrame fr = RenderFrame(*scene, f, render);
      const std::string name = FrameName(f);
      Status st = WritePng(images / "left" / (name + ".png"), fr.left, h, w);
      if (st.ok()) st = WritePng(images / "right" / (name + ".png"), fr.right, h, w);
      if (st.ok()) st = io::WritePfm((disp / (name + ".pfm")).string(), fr.disparity, h, w, 1);
      if (st.ok()) {
        st = io::WritePfm((dchange / (name + ".pfm")).string(), fr.disparity_change, h, w, 1);
      }
      if (st.ok()) {
        st = io::WritePfm((flow / ("OpticalFlowIntoFuture_" + name + "_L.pfm")).string(),
                          fr.optical_flow, h, w, 3);
      }
      if (st.ok()) st = io::WritePfm((sflow / (name + ".pfm")).string(), fr.scene_flow, h, w, 3);
      if (!st.ok()) return st;
      p.sequence = s;
      p.frame = f;
      ++p.frames_done;
      if (progress) progress(p);
    }
  }
  return WriteText(root / "camera.json", CameraJson(options));
}

// Renames the finished tree `tmp` to `out`, replacing an existing data set there only now.
Status MoveIntoPlace(const fs::path& tmp, const fs::path& out) {
  std::error_code ec;
  const bool occupied = fs::exists(out, ec) && !fs::is_empty(out, ec);
  if (!occupied) {  // rename(2) replaces an empty directory
    if (::rename(tmp.c_str(), out.c_str()) != 0) {
      return Status::Error("cannot rename '" + tmp.string() + "' to '" + out.string() +
                           "': " + std::strerror(errno));
    }
    return Status::Ok();
  }
  const fs::path old = out.string() + ".old-" + std::to_string(::getpid());
  fs::remove_all(old, ec);
  if (::rename(out.c_str(), old.c_str()) != 0) {
    return Status::Error("cannot move the data set being replaced, '" + out.string() + "', to '" +
                         old.string() + "': " + std::strerror(errno));
  }
  if (::rename(tmp.c_str(), out.c_str()) != 0) {
    const int err = errno;
    (void)::rename(old.c_str(), out.c_str());
    return Status::Error("cannot rename '" + tmp.string() + "' to '" + out.string() +
                         "': " + std::strerror(err));
  }
  fs::remove_all(old, ec);
  if (ec) {
    return Status::Error("wrote '" + out.string() +
                         "' but cannot remove the data set it replaced, '" + old.string() +
                         "': " + ec.message());
  }
  return Status::Ok();
}

}  // namespace

Destination ClassifyDestination(const std::string& out_dir) {
  const fs::path out = Trimmed(out_dir);
  std::error_code ec;
  const fs::file_status st = fs::status(out, ec);  // follows a symbolic link
  if (!fs::exists(st)) return Destination::kAbsent;
  if (!fs::is_directory(st)) return Destination::kNotADirectory;
  if (fs::is_empty(out, ec)) return Destination::kEmptyDirectory;
  std::string text;
  return WrittenBySynth(out, &text) ? Destination::kSynthDataset : Destination::kOtherDirectory;
}

Status WriteDataset(const DatasetOptions& options, const std::string& out_dir, bool replace,
                    const std::function<void(const DatasetProgress&)>& progress) {
  if (out_dir.empty()) return Status::Error("the data set needs an output directory name");
  fs::path out = Trimmed(out_dir);
  switch (ClassifyDestination(out_dir)) {
    case Destination::kAbsent:
    case Destination::kEmptyDirectory:
      break;
    case Destination::kSynthDataset:
      if (!replace) return Status::Error("'" + out_dir + "' is not empty (it holds a data set)");
      break;
    case Destination::kOtherDirectory:
      return Status::Error("'" + out_dir +
                           "' is not empty and is not a data set sfrt synth wrote (no camera.json "
                           "with \"generator\": \"sfrt synth\"); it is never replaced");
    case Destination::kNotADirectory:
      return Status::Error("'" + out_dir + "' exists and is not a directory");
  }
  std::error_code ec;
  if (fs::is_symlink(out, ec)) {  // the data set goes where the link points; the link survives
    const fs::path target = fs::canonical(out, ec);
    if (!ec) out = target;
  }
  if (out.has_parent_path()) {
    if (Status s = MakeDirs(out.parent_path()); !s.ok()) return s;
  }
  const fs::path tmp = out.string() + ".partial-" + std::to_string(::getpid());
  fs::remove_all(tmp, ec);  // left by an earlier process that had this pid and was killed
  Status s = WriteTree(options, tmp, progress);
  if (s.ok()) s = MoveIntoPlace(tmp, out);
  if (!s.ok()) {
    fs::remove_all(tmp, ec);
    return Status::Error(s.message() + "; the partial data set was removed, '" + out_dir +
                         "' is as it was");
  }
  return Status::Ok();
}

Status CheckDatasetComplete(const std::string& dir) {
  std::string text;
  if (!WrittenBySynth(Trimmed(dir), &text)) return Status::Ok();
  if (JsonValue(text, "complete") == "true") return Status::Ok();
  return Status::Error("data set '" + dir +
                       "' is incomplete: its camera.json (sfrt synth) has no \"complete\": true, "
                       "which sfrt synth writes last, so its generation failed or was interrupted "
                       "(or an sfrt older than this marker wrote it); generate it again");
}

}  // namespace sfrt::synth
