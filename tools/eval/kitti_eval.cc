#include "eval/kitti_eval.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "eval/classical.h"
#include "eval/model_runner.h"
#include "eval/shards.h"
#include "sfrt/camera/image_file.h"

namespace sfrt::eval {
namespace {

namespace fs = std::filesystem;

fs::path KittiDir(const std::string& root) {
  std::error_code ec;
  const fs::path training = fs::path(root) / "training";
  return fs::is_directory(training / "image_2", ec) ? training : fs::path(root);
}

// One scene: the four images (left t, right t, left t+1, right t+1), the ground truth and the
// camera.
struct KittiScene {
  std::string name;  // "000123"
  cv::Mat images[4];
  cv::Mat d0, d1, flow, objects;
  PinholeStereo camera;
  std::string calibration;  // the file the camera came from
};

bool IsSceneName(const std::string& file) {
  return file.size() == 13 && file.compare(6, 7, "_10.png") == 0 &&
         std::all_of(file.begin(), file.begin() + 6, [](char c) { return c >= '0' && c <= '9'; });
}

Result<std::vector<std::string>> ListKittiScenes(const fs::path& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir / "image_2", ec)) {
    const std::string file = e.path().filename().string();
    if (IsSceneName(file)) names.push_back(file.substr(0, 6));
  }
  std::sort(names.begin(), names.end());
  if (names.empty()) {
    return Status::Error((dir / "image_2").string() +
                         ": no scene (NNNNNN_10.png) in this KITTI layout");
  }
  return names;
}

Result<cv::Mat> ReadColour(const fs::path& path) {
  cv::Mat image;
  if (std::string why = camera::ReadImageFile(path.string(), cv::IMREAD_COLOR, &image);
      !why.empty()) {
    return Status::Error(path.string() + ": " + why);
  }
  return image;
}

// Every map of the scene has the size of its left image at t; the error names the file.
Status CheckSceneSizes(const KittiScene& s, const fs::path& dir) {
  const std::pair<const cv::Mat*, std::string> maps[] = {
      {&s.images[1], "image_3/" + s.name + "_10.png"},
      {&s.images[2], "image_2/" + s.name + "_11.png"},
      {&s.images[3], "image_3/" + s.name + "_11.png"},
      {&s.d0, "disp_occ_0/" + s.name + "_10.png"},
      {&s.d1, "disp_occ_1/" + s.name + "_10.png"},
      {&s.flow, "flow_occ/" + s.name + "_10.png"},
      {&s.objects, "obj_map/" + s.name + "_10.png"}};
  for (const auto& [m, file] : maps) {
    if (m->size() != s.images[0].size()) {
      return Status::Error((dir / file).string() + " is " + std::to_string(m->rows) + "x" +
                           std::to_string(m->cols) + " but image_2/" + s.name + "_10.png is " +
                           std::to_string(s.images[0].rows) + "x" +
                           std::to_string(s.images[0].cols));
    }
  }
  return Status::Ok();
}

Result<KittiScene> ReadKittiScene(const fs::path& dir, const std::string& name) {
  KittiScene s;
  s.name = name;
  const std::string png = name + "_10.png";
  const fs::path images[4] = {dir / "image_2" / png, dir / "image_3" / png,
                              dir / "image_2" / (name + "_11.png"),
                              dir / "image_3" / (name + "_11.png")};
  for (int i = 0; i < 4; ++i) {
    Result<cv::Mat> image = ReadColour(images[i]);
    if (!image.ok()) return image.status();
    s.images[i] = *image;
  }
  Result<cv::Mat> d0 = ReadKittiDisparity((dir / "disp_occ_0" / png).string());
  if (!d0.ok()) return d0.status();
  Result<cv::Mat> d1 = ReadKittiDisparity((dir / "disp_occ_1" / png).string());
  if (!d1.ok()) return d1.status();
  Result<cv::Mat> flow = ReadKittiFlow((dir / "flow_occ" / png).string());
  if (!flow.ok()) return flow.status();
  s.d0 = *d0;
  s.d1 = *d1;
  s.flow = *flow;
  std::error_code ec;
  const fs::path objects = dir / "obj_map" / png;
  if (fs::exists(objects, ec)) {
    Result<cv::Mat> map = ReadKittiObjectMap(objects.string());
    if (!map.ok()) return map.status();
    s.objects = *map;
  } else {
    s.objects = cv::Mat(s.images[0].size(), CV_8U, cv::Scalar(0));
  }
  if (Status sizes = CheckSceneSizes(s, dir); !sizes.ok()) return sizes;
  s.calibration = (dir / "calib_cam_to_cam" / (name + ".txt")).string();
  Result<PinholeStereo> camera = ReadKittiCalibration(s.calibration);
  if (!camera.ok()) return camera.status();
  s.camera = *camera;
  return s;
}

// The estimate filled as the devkit fills it, then counted.
// The estimate with the devkit's filling of missing values (a submission holds a value at every
// pixel); it is scored as the devkit reads it back (AsSubmitted).
KittiEstimate Filled(KittiEstimate e) {
  InterpolateDisparity(&e.disparity0);
  InterpolateDisparity(&e.disparity1);
  InterpolateFlow(&e.flow);
  return e;
}

// The estimate in the devkit's encodings: out/disp_0, out/disp_1, out/flow (NNNNNN_10.png).
Status WriteSubmission(const std::string& out, const std::string& scene, const KittiEstimate& e) {
  const std::string png = scene + "_10.png";
  const fs::path dir(out);
  Status st = WriteKittiDisparity((dir / "disp_0" / png).string(), e.disparity0);
  if (st.ok()) st = WriteKittiDisparity((dir / "disp_1" / png).string(), e.disparity1);
  if (st.ok()) st = WriteKittiFlow((dir / "flow" / png).string(), e.flow);
  return st;
}

Status MakeSubmissionDirs(const std::string& out) {
  for (const char* sub : {"disp_0", "disp_1", "flow"}) {
    std::error_code ec;
    fs::create_directories(fs::path(out) / sub, ec);
    if (ec) {
      return Status::Error("--write-submission: cannot create '" + (fs::path(out) / sub).string() +
                           "': " + ec.message());
    }
  }
  return Status::Ok();
}

// The model, made at the first scene (its size: the asked one, else the first scene's), with
// the camera check against the first scene's camera scaled to the model's width.
Status StartModel(const EvalOptions& options, const KittiScene& s, EvalReport* report,
                  std::unique_ptr<ModelRunner>* runner) {
  report->model_height = options.model_height > 0 ? options.model_height : s.images[0].rows;
  report->model_width = options.model_width > 0 ? options.model_width : s.images[0].cols;
  Result<std::unique_ptr<ModelRunner>> created = StartModelRunner(
      options, s.camera.focal, s.camera.baseline, s.images[0].cols, s.calibration, report);
  if (!created.ok()) return created.status();
  *runner = std::move(created).value();
  return Status::Ok();
}

// The three methods on one scene.
Status ScoreScene(const EvalOptions& options, const KittiScene& s, ModelRunner* runner,
                  SequenceResult* seq) {
  const size_t pixels = s.images[0].total();
  const std::vector<float> truth = KittiGroundTruthSceneFlow(s.d0, s.d1, s.flow, s.camera);
  const bool stereo = options.depth == DepthSource::kStereo || options.classical;
  const cv::Mat own = stereo ? ClassicalDisparity(s.images[0], s.images[1]) : cv::Mat();
  const cv::Mat& depth = options.depth == DepthSource::kGroundTruth ? s.d0 : own;
  if (runner != nullptr) {
    const cv::Mat* ptrs[4] = {&s.images[0], &s.images[1], &s.images[2], &s.images[3]};
    Result<std::vector<float>> pred = runner->Run(ptrs);
    if (!pred.ok()) return Status::Error(s.name + ": model run failed: " + pred.message());
    seq->methods[0].Add(pred->data(), truth.data(), pixels);
    const KittiEstimate e = Filled(ProjectSceneFlow(depth, pred->data(), s.camera));
    seq->kitti[0].Add(s.d0, s.d1, s.flow, s.objects, AsSubmitted(e));
    if (!options.submission_dir.empty()) {
      if (Status st = WriteSubmission(options.submission_dir, s.name, e); !st.ok()) return st;
    }
  }
  const std::vector<float> zero(pixels * 3, 0.0f);
  seq->methods[1].Add(nullptr, truth.data(), pixels);
  seq->kitti[1].Add(s.d0, s.d1, s.flow, s.objects,
                    AsSubmitted(Filled(ProjectSceneFlow(depth, zero.data(), s.camera))));
  if (options.classical) {
    const std::vector<float> flow =
        ClassicalSceneFlow(s.images[0], s.images[1], s.images[2], s.images[3], s.camera);
    seq->methods[2].Add(flow.data(), truth.data(), pixels);
    seq->kitti[2].Add(s.d0, s.d1, s.flow, s.objects,
                      AsSubmitted(Filled(ProjectSceneFlow(own, flow.data(), s.camera))));
  }
  return Status::Ok();
}

std::string Percent(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

}  // namespace

bool IsKittiLayout(const std::string& root) {
  std::error_code ec;
  const fs::path dir = KittiDir(root);
  return fs::is_directory(dir / "image_2", ec) && fs::is_directory(dir / "disp_occ_0", ec);
}

Result<EvalReport> RunKittiEvaluation(const EvalOptions& options,
                                      const std::function<void(const EvalProgress&)>& progress) {
  EvalReport report = NewReport(options);
  report.kitti = true;
  const fs::path dir = KittiDir(options.dataset);
  Result<std::vector<std::string>> names = ListKittiScenes(dir);
  if (!names.ok()) return names.status();
  if (options.max_frames > 0 && static_cast<int>(names->size()) > options.max_frames) {
    names->resize(static_cast<size_t>(options.max_frames));
  }
  report.list = MakeWorkList(*names);
  if (!options.submission_dir.empty() && report.has_model) {
    if (Status st = MakeSubmissionDirs(options.submission_dir); !st.ok()) return st;
  }
  // The first scene of the list sets the image and model size and the camera of the report, in
  // every shard alike.
  Result<KittiScene> first = ReadKittiScene(dir, report.list.units[0]);
  if (!first.ok()) return first.status();
  report.height = first->images[0].rows;
  report.width = first->images[0].cols;
  report.focal = first->camera.focal;
  report.baseline = first->camera.baseline;
  report.cx = first->camera.cx;
  report.cy = first->camera.cy;
  std::unique_ptr<ModelRunner> runner;
  if (report.has_model) {
    if (Status st = StartModel(options, *first, &report, &runner); !st.ok()) return st;
    report.isa = IsaName(runner->isa());
  }
  std::vector<std::string> mine;
  for (size_t k = 0; k < report.list.units.size(); ++k) {
    if (!options.shard || InShard(k, *options.shard)) mine.push_back(report.list.units[k]);
  }
  for (size_t i = 0; i < mine.size(); ++i) {
    const FrameRef ref{mine[i], mine[i], mine[i]};
    if (progress) progress(EvalProgress{static_cast<int>(i), static_cast<int>(mine.size()), &ref});
    Result<KittiScene> scene = ReadKittiScene(dir, mine[i]);
    if (!scene.ok()) return scene.status();
    SequenceResult seq{mine[i], 1, {}, {}, {}};
    for (MetricsAccumulator& m : seq.methods) m = MetricsAccumulator(options.thresholds);
    if (Status st = ScoreScene(options, *scene, runner.get(), &seq); !st.ok()) return st;
    report.sequences.push_back(std::move(seq));
    ++report.frames;
  }
  MergeSequences(&report);
  if (options.shard) {
    if (Status st = SetShardProvenance(options, &report); !st.ok()) return st;
  }
  if (progress) progress(EvalProgress{report.frames, report.frames, nullptr});
  return report;
}

std::string DepthLabel(const EvalReport& report, int method) {
  if (method == 2) return "stereo (its own)";
  return report.depth == DepthSource::kGroundTruth ? "gt (oracle)" : "stereo";
}

std::string KittiJson(const KittiCounts& c, const std::string& depth, const std::string& indent) {
  std::ostringstream o;
  o << "{\n" << indent << "  \"depth\": \"" << depth << "\"";
  for (int m = 0; m < kKittiMaps; ++m) {
    const KittiMap map = static_cast<KittiMap>(m);
    o << ",\n"
      << indent << "  \"" << kKittiMapNames[m]
      << "\": {\"bg\": " << Percent(c.Percent(map, KittiRegion::kBackground))
      << ", \"fg\": " << Percent(c.Percent(map, KittiRegion::kForeground))
      << ", \"all\": " << Percent(c.PercentAll(map)) << "}";
  }
  o << ",\n" << indent << "  \"counts\": {";
  for (int m = 0; m < kKittiMaps; ++m) {
    const KittiMap map = static_cast<KittiMap>(m);
    o << (m ? ", " : "") << "\"" << kKittiMapNames[m] << "\": {\"pixels\": ["
      << c.pixels(map, KittiRegion::kBackground) << ", " << c.pixels(map, KittiRegion::kForeground)
      << "], \"outliers\": [" << c.outliers(map, KittiRegion::kBackground) << ", "
      << c.outliers(map, KittiRegion::kForeground) << "]}";
  }
  o << "}\n" << indent << "}";
  return o.str();
}

std::string FormatKittiTable(const EvalReport& r) {
  std::string out =
      "KITTI outliers, % of the pixels with ground truth (> 3 px and > 5%; SF: any of D1, D2, "
      "Fl)\n";
  char line[200];
  std::snprintf(line, sizeof(line), "%-10s %-17s %7s %7s %7s %7s %7s %7s\n", "method", "depth",
                "D1-all", "D2-all", "Fl-all", "SF-bg", "SF-fg", "SF-all");
  out += line;
  for (int m = 0; m < kMethodCount; ++m) {
    if ((m == 0 && !r.has_model) || (m == 2 && !r.has_classical)) continue;
    const KittiCounts& c = r.kitti_counts[m];
    std::snprintf(line, sizeof(line), "%-10s %-17s %7.2f %7.2f %7.2f %7.2f %7.2f %7.2f\n",
                  kMethodNames[m], DepthLabel(r, m).c_str(), c.PercentAll(KittiMap::kD1),
                  c.PercentAll(KittiMap::kD2), c.PercentAll(KittiMap::kFl),
                  c.Percent(KittiMap::kSf, KittiRegion::kBackground),
                  c.Percent(KittiMap::kSf, KittiRegion::kForeground), c.PercentAll(KittiMap::kSf));
    out += line;
  }
  return out;
}

}  // namespace sfrt::eval
