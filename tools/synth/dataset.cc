#include "synth/dataset.h"

#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "sfrt/io/atomic_write.h"
#include "sfrt/io/pfm.h"

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
  return tools::WriteFileAtomically(
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
  return tools::WriteFileAtomically(path.string(), bytes);
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
  s += "  \"textures\": " +
       (o.texture_dir.empty() ? std::string("\"procedural\"") : JsonString(o.texture_dir)) + ",\n";
  s += "  \"noise_sigma\": " + Number(o.noise_sigma) + ",\n";
  s += "  \"blur_sigma\": " + Number(o.blur_sigma) + "\n";
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

Status WriteDataset(const DatasetOptions& options, const std::string& out_dir,
                    const std::function<void(const DatasetProgress&)>& progress) {
  const fs::path root(out_dir);
  if (Status s = MakeDirs(root); !s.ok()) return s;
  if (Status s = WriteText(root / "camera.json", CameraJson(options)); !s.ok()) return s;

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
      RenderedFrame fr = RenderFrame(*scene, f, render);
      const std::string name = FrameName(f);
      Status st = WritePng(images / "left" / (name + ".png"), fr.left, h, w);
      if (st.ok()) st = WritePng(images / "right" / (name + ".png"), fr.right, h, w);
      if (st.ok()) st = tools::WritePfm((disp / (name + ".pfm")).string(), fr.disparity, h, w, 1);
      if (st.ok()) {
        st = tools::WritePfm((dchange / (name + ".pfm")).string(), fr.disparity_change, h, w, 1);
      }
      if (st.ok()) {
        st = tools::WritePfm((flow / ("OpticalFlowIntoFuture_" + name + "_L.pfm")).string(),
                             fr.optical_flow, h, w, 3);
      }
      if (st.ok()) st = tools::WritePfm((sflow / (name + ".pfm")).string(), fr.scene_flow, h, w, 3);
      if (!st.ok()) return st;
      p.sequence = s;
      p.frame = f;
      ++p.frames_done;
      if (progress) progress(p);
    }
  }
  return Status::Ok();
}

}  // namespace sfrt::synth
