#include "eval/kitti_layout.h"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "eval/kitti.h"
#include "synth/render.h"

namespace sfrt::eval {
namespace {

namespace fs = std::filesystem;

constexpr const char* kFolders[] = {"image_2",  "image_3", "disp_occ_0",      "disp_occ_1",
                                    "flow_occ", "obj_map", "calib_cam_to_cam"};

Status WriteImage(const fs::path& path, const std::vector<uint8_t>& bgr, int h, int w) {
  const cv::Mat image(h, w, CV_8UC3, const_cast<uint8_t*>(bgr.data()));
  if (!cv::imwrite(path.string(), image)) return Status::Error(path.string() + ": cannot write");
  return Status::Ok();
}

// One scene's files: the pair (t, t+1) of rendered frames.
Status WriteScene(const fs::path& dir, const std::string& name, const synth::RenderedFrame& t,
                  const synth::RenderedFrame& next, const PinholeStereo& camera) {
  const int h = t.height;
  const int w = t.width;
  const std::string png = name + "_10.png";
  Status st = WriteImage(dir / "image_2" / png, t.left, h, w);
  if (st.ok()) st = WriteImage(dir / "image_3" / png, t.right, h, w);
  if (st.ok()) st = WriteImage(dir / "image_2" / (name + "_11.png"), next.left, h, w);
  if (st.ok()) st = WriteImage(dir / "image_3" / (name + "_11.png"), next.right, h, w);
  if (!st.ok()) return st;
  cv::Mat d0(h, w, CV_32F), d1(h, w, CV_32F), flow(h, w, CV_32FC3);
  cv::Mat objects(h, w, CV_8U, const_cast<uint8_t*>(t.object.data()));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      const float u = t.optical_flow[i * 3];
      const float v = t.optical_flow[i * 3 + 1];
      const bool inside = x + u >= 0 && x + u <= w - 1 && y + v >= 0 && y + v <= h - 1;
      d0.at<float>(y, x) = t.disparity[i];
      d1.at<float>(y, x) = inside ? t.disparity[i] + t.disparity_change[i] : kNoDisparity;
      flow.at<cv::Vec3f>(y, x) = inside ? cv::Vec3f(u, v, 1) : cv::Vec3f(0, 0, 0);
    }
  }
  st = WriteKittiDisparity((dir / "disp_occ_0" / png).string(), d0);
  if (st.ok()) st = WriteKittiDisparity((dir / "disp_occ_1" / png).string(), d1);
  if (st.ok()) st = WriteKittiFlow((dir / "flow_occ" / png).string(), flow);
  if (st.ok() && !cv::imwrite((dir / "obj_map" / png).string(), objects)) {
    st = Status::Error((dir / "obj_map" / png).string() + ": cannot write");
  }
  if (st.ok()) {
    st = WriteKittiCalibration((dir / "calib_cam_to_cam" / (name + ".txt")).string(), camera);
  }
  return st;
}

Status WriteTree(const synth::DatasetOptions& options, const fs::path& root,
                 const std::function<void(int, int)>& progress) {
  const fs::path dir = root / "training";
  for (const char* folder : kFolders) {
    std::error_code ec;
    fs::create_directories(dir / folder, ec);
    if (ec) return Status::Error((dir / folder).string() + ": " + ec.message());
  }
  const synth::Camera& c = options.scene.camera;
  const PinholeStereo camera{c.focal, c.baseline, c.cx, c.cy};
  const int total = options.sequences * (options.scene.frames - 1);
  int done = 0;
  for (int s = 0; s < options.sequences; ++s) {
    Result<synth::Scene> scene = synth::MakeDatasetScene(options, s);
    if (!scene.ok()) return scene.status();
    const synth::RenderOptions render = synth::MakeRenderOptions(options, s);
    synth::RenderedFrame previous = synth::RenderFrame(*scene, 0, render);
    for (int f = 1; f < options.scene.frames; ++f) {
      if (options.stop != nullptr && options.stop->load()) {
        return Status::Error("stopped by a signal after " + std::to_string(done) + " of " +
                             std::to_string(total) + " scenes");
      }
      synth::RenderedFrame next = synth::RenderFrame(*scene, f, render);
      char name[16];
      std::snprintf(name, sizeof(name), "%06d", done);
      if (Status st = WriteScene(dir, name, previous, next, camera); !st.ok()) return st;
      previous = std::move(next);
      ++done;
      if (progress) progress(done, total);
    }
  }
  return Status::Ok();
}

}  // namespace

Status WriteKittiLayout(const synth::DatasetOptions& options, const std::string& out_dir,
                        const std::function<void(int, int)>& progress) {
  if (options.scene.frames < 2) {
    return Status::Error("the KITTI layout pairs frames: --frames must be at least 2");
  }
  std::error_code ec;
  const fs::path out(out_dir);
  if (fs::exists(out, ec) && !(fs::is_directory(out, ec) && fs::is_empty(out, ec))) {
    return Status::Error("'" + out_dir + "' exists and is not an empty directory");
  }
  const fs::path tmp = out.string() + ".partial-" + std::to_string(::getpid());
  fs::remove_all(tmp, ec);
  Status st = WriteTree(options, tmp, progress);
  if (st.ok()) {
    fs::remove(out, ec);  // an empty directory
    fs::rename(tmp, out, ec);
    if (ec)
      st = Status::Error("cannot rename '" + tmp.string() + "' to '" + out_dir +
                         "': " + ec.message());
  }
  if (!st.ok()) {
    fs::remove_all(tmp, ec);
    return Status::Error(st.message() + "; the partial data set was removed");
  }
  return Status::Ok();
}

}  // namespace sfrt::eval
