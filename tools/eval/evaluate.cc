#include "eval/evaluate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "eval/classical.h"
#include "eval/kitti_eval.h"
#include "eval/model_runner.h"
#include "eval/shards.h"
#include "sfrt/camera/image_file.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/io/pfm.h"
#include "sfrt/session.h"
#include "sfrt/vocabulary/stereo_input.h"
#include "synth/annotate.h"
#include "synth/dataset.h"

namespace sfrt::eval {
namespace {

namespace fs = std::filesystem;

std::string NextName(const std::string& stem) {
  std::string next = std::to_string(std::stoll(stem) + 1);
  if (next.size() < stem.size()) next.insert(0, stem.size() - next.size(), '0');
  return next;
}

bool AllDigits(const std::string& s) {
  return !s.empty() && s.size() <= 9 &&
         std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

std::string Image(const std::string& root, const std::string& seq, const char* side,
                  const std::string& frame) {
  return (fs::path(root) / "frames_cleanpass" / seq / side / (frame + ".png")).string();
}

std::string SceneFlowPath(const std::string& root, const FrameRef& f) {
  return (fs::path(root) / "scene_flow" / f.sequence / "into_future" / "left" / (f.frame + ".pfm"))
      .string();
}

struct GtInputs {
  std::string disparity, change, flow;
};

GtInputs GtInputPaths(const std::string& root, const FrameRef& f) {
  const fs::path r(root);
  return {
      (r / "disparity" / f.sequence / "left" / (f.frame + ".pfm")).string(),
      (r / "disparity_change" / f.sequence / "into_future" / "left" / (f.frame + ".pfm")).string(),
      (r / "optical_flow" / f.sequence / "into_future" / "left" /
       ("OpticalFlowIntoFuture_" + f.frame + "_L.pfm"))
          .string()};
}

bool IsFile(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

Result<cv::Mat> ReadImage(const std::string& path) {
  cv::Mat image;
  if (std::string why = camera::ReadImageFile(path, cv::IMREAD_COLOR, &image); !why.empty()) {
    return Status::Error(path + ": " + why);
  }
  if (image.type() != CV_8UC3) {
    return Status::Error(path + ": cannot be decoded as an 8-bit colour image");
  }
  return image;
}

std::string Fmt(double v, const char* format = "%.4f") {
  char buf[48];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

std::string JsonNumber(double v) {
  if (!std::isfinite(v)) return "null";
  return Fmt(v, "%.9g");
}

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out.push_back('\\');
      out.push_back(c);
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += "\\u00" + std::string(1, "0123456789abcdef"[(c >> 4) & 0xF]) +
             std::string(1, "0123456789abcdef"[c & 0xF]);
    } else {
      out.push_back(c);
    }
  }
  return out + "\"";
}

std::string MetricsJson(const FlowMetrics& m, int frames, const std::string& indent) {
  std::ostringstream o;
  o << "{\n"
    << indent << "  \"epe3d\": " << JsonNumber(m.epe3d) << ",\n"
    << indent << "  \"epe_x\": " << JsonNumber(m.epe_x) << ",\n"
    << indent << "  \"epe_y\": " << JsonNumber(m.epe_y) << ",\n"
    << indent << "  \"epe_z\": " << JsonNumber(m.epe_z) << ",\n"
    << indent << "  \"acc05\": " << JsonNumber(m.acc05) << ",\n"
    << indent << "  \"acc10\": " << JsonNumber(m.acc10) << ",\n"
    << indent << "  \"outliers\": " << JsonNumber(m.outliers) << ",\n"
    << indent << "  \"valid_pixels\": " << m.valid_pixels << ",\n"
    << indent << "  \"frames\": " << frames;
  return o.str();
}

// The sequences of `frames` (sorted by sequence), once each.
std::vector<std::string> SequencesOf(const std::vector<FrameRef>& frames) {
  std::vector<std::string> units;
  for (const FrameRef& f : frames) {
    if (units.empty() || units.back() != f.sequence) units.push_back(f.sequence);
  }
  return units;
}

// The frames of the sequences `shard` takes from `list`.
std::vector<FrameRef> FramesOfShard(const std::vector<FrameRef>& frames, const WorkList& list,
                                    const ShardSpec& shard) {
  std::vector<FrameRef> mine;
  for (const FrameRef& f : frames) {
    const size_t k = static_cast<size_t>(
        std::lower_bound(list.units.begin(), list.units.end(), f.sequence) - list.units.begin());
    if (InShard(k, shard)) mine.push_back(f);
  }
  return mine;
}

}  // namespace

Result<std::vector<FrameRef>> ListEvalFrames(const std::string& root) {
  const fs::path frames_dir = fs::path(root) / "frames_cleanpass";
  std::error_code ec;
  if (!fs::is_directory(frames_dir, ec)) {
    return Status::Error("dataset root '" + root + "' has no 'frames_cleanpass' directory");
  }
  std::vector<FrameRef> frames;
  std::string first_missing;
  std::set<std::string> sequences;
  for (const fs::directory_entry& e : fs::directory_iterator(frames_dir, ec)) {
    if (e.is_directory()) sequences.insert(e.path().filename().string());
  }
  for (const std::string& seq : sequences) {
    const fs::path left = frames_dir / seq / "left";
    if (!fs::is_directory(left, ec)) continue;
    std::set<std::string> stems;
    for (const fs::directory_entry& e : fs::directory_iterator(left, ec)) {
      if (e.path().extension() == ".png" && AllDigits(e.path().stem().string())) {
        stems.insert(e.path().stem().string());
      }
    }
    for (const std::string& stem : stems) {
      FrameRef f{seq, stem, NextName(stem)};
      if (stems.count(f.next_frame) == 0) continue;  // the last frame: no t+1 images
      std::string missing;
      for (const std::string& p :
           {Image(root, seq, "right", f.frame), Image(root, seq, "right", f.next_frame)}) {
        if (!IsFile(p)) missing = p;
      }
      if (missing.empty() && !IsFile(SceneFlowPath(root, f))) {
        const GtInputs in = GtInputPaths(root, f);
        for (const std::string& p : {in.disparity, in.change, in.flow}) {
          if (!IsFile(p)) missing = p;
        }
        if (!missing.empty()) missing = SceneFlowPath(root, f) + " (nor " + missing + ")";
      }
      if (!missing.empty()) {
        if (first_missing.empty()) first_missing = missing;
        continue;
      }
      frames.push_back(std::move(f));
    }
  }
  if (frames.empty()) {
    return Status::Error(
        "dataset root '" + root + "': no frame has images at t and t+1 and ground truth at t" +
        (first_missing.empty() ? std::string() : " (first missing: " + first_missing + ")"));
  }
  return frames;
}

Result<std::vector<float>> LoadGroundTruth(const std::string& root, const FrameRef& frame,
                                           double focal, double baseline, double cx, double cy,
                                           int* height, int* width) {
  const std::string sf = SceneFlowPath(root, frame);
  if (IsFile(sf)) {
    Result<io::PfmImage> gt = io::ReadPfm(sf);
    if (!gt.ok()) return gt.status();
    if (gt->channels != 3) {
      return Status::Error(sf + ": " + std::to_string(gt->channels) +
                           " channel(s); scene flow has 3");
    }
    *height = gt->height;
    *width = gt->width;
    return std::move(gt->data);
  }
  const GtInputs in = GtInputPaths(root, frame);
  Result<io::PfmImage> d0 = io::ReadPfm(in.disparity);
  if (!d0.ok()) return d0.status();
  Result<io::PfmImage> change = io::ReadPfm(in.change);
  if (!change.ok()) return change.status();
  Result<io::PfmImage> flow = io::ReadPfm(in.flow);
  if (!flow.ok()) return flow.status();
  if (d0->channels != 1 || change->channels != 1 || flow->channels != 3 ||
      change->height != d0->height || change->width != d0->width || flow->height != d0->height ||
      flow->width != d0->width) {
    return Status::Error(in.disparity + ", " + in.change + ", " + in.flow +
                         ": sizes or channel counts do not match (1, 1 and 3 channels)");
  }
  synth::Intrinsics k{focal, baseline, cx, cy};
  std::vector<float> out(static_cast<size_t>(d0->height) * d0->width * 3);
  synth::ComputeSceneFlow(d0->data.data(), change->data.data(), flow->data.data(), 3, d0->height,
                          d0->width, k, synth::ConventionKind::kFormula, out.data());
  *height = d0->height;
  *width = d0->width;
  return out;
}

void DefaultModelSize(const ModelMetadata& meta, int* height, int* width) {
  if (meta.training == TrainingState::kTrained && meta.input.traced_height > 0) {
    *height = meta.input.traced_height;
    *width = meta.input.traced_width;
  }
}

EvalReport NewReport(const EvalOptions& options) {
  EvalReport report;
  report.thresholds = options.thresholds;
  for (MetricsAccumulator& m : report.overall) m = MetricsAccumulator(options.thresholds);
  report.dataset = options.dataset;
  report.model_path = options.model_path;
  report.has_model = !options.model_path.empty() || options.model != nullptr;
  report.has_classical = options.classical;
  report.depth = options.depth;
  return report;
}

void MergeSequences(EvalReport* report) {
  for (const SequenceResult& seq : report->sequences) {
    for (int m = 0; m < kMethodCount; ++m) {
      report->overall[m].Merge(seq.methods[m]);
      report->kitti_counts[m].Merge(seq.kitti[m]);
    }
  }
}

Result<EvalReport> RunEvaluation(const EvalOptions& options,
                                 const std::function<void(const EvalProgress&)>& progress) {
  if (IsKittiLayout(options.dataset)) return RunKittiEvaluation(options, progress);
  EvalReport report = NewReport(options);

  if (Status complete = synth::CheckDatasetComplete(options.dataset); !complete.ok()) {
    return complete;
  }
  const std::string camera_json = (fs::path(options.dataset) / "camera.json").string();
  Result<synth::Intrinsics> camera = synth::ReadCameraJson(camera_json);
  if (!camera.ok()) return camera.status();
  report.focal = camera->focal;
  report.baseline = camera->baseline;
  report.cx = camera->cx;
  report.cy = camera->cy;

  Result<std::vector<FrameRef>> listed = ListEvalFrames(options.dataset);
  if (!listed.ok()) return listed.status();
  std::vector<FrameRef> frames = std::move(listed).value();
  if (options.max_frames > 0 && static_cast<int>(frames.size()) > options.max_frames) {
    frames.resize(static_cast<size_t>(options.max_frames));
  }
  report.list = MakeWorkList(SequencesOf(frames));
  if (options.shard) frames = FramesOfShard(frames, report.list, *options.shard);

  std::unique_ptr<ModelRunner> runner;
  const PinholeStereo rig{camera->focal, camera->baseline, camera->cx, camera->cy};
  for (size_t i = 0; i < frames.size(); ++i) {
    const FrameRef& f = frames[i];
    if (progress) progress(EvalProgress{static_cast<int>(i), static_cast<int>(frames.size()), &f});
    int h = 0;
    int w = 0;
    Result<std::vector<float>> gt = LoadGroundTruth(
        options.dataset, f, camera->focal, camera->baseline, camera->cx, camera->cy, &h, &w);
    if (!gt.ok()) return gt.status();
    cv::Mat images[4];
    const std::string paths[4] = {Image(options.dataset, f.sequence, "left", f.frame),
                                  Image(options.dataset, f.sequence, "right", f.frame),
                                  Image(options.dataset, f.sequence, "left", f.next_frame),
                                  Image(options.dataset, f.sequence, "right", f.next_frame)};
    for (int k = 0; k < 4; ++k) {
      Result<cv::Mat> image = ReadImage(paths[k]);
      if (!image.ok()) return image.status();
      if (image->rows != h || image->cols != w) {
        return Status::Error(paths[k] + ": image is " + std::to_string(image->rows) + "x" +
                             std::to_string(image->cols) + " but its ground truth is " +
                             std::to_string(h) + "x" + std::to_string(w));
      }
      images[k] = std::move(image).value();
    }
    if (i == 0) {
      report.height = h;
      report.width = w;
      report.model_height = options.model_height > 0 ? options.model_height : h;
      report.model_width = options.model_width > 0 ? options.model_width : w;
    } else if (h != report.height || w != report.width) {
      return Status::Error(paths[0] + ": frame is " + std::to_string(h) + "x" + std::to_string(w) +
                           " but the first frame is " + std::to_string(report.height) + "x" +
                           std::to_string(report.width) + " (one image size per dataset)");
    }
    if (report.has_model && !runner) {
      Result<std::unique_ptr<ModelRunner>> created =
          ModelRunner::Create(options.model_path, report.model_height, report.model_width, options);
      if (!created.ok()) return created.status();
      runner = std::move(created).value();
      const ModelMetadata& meta = runner->metadata();
      report.model_name = meta.name;
      report.model_training = meta.training;
      // The camera the model sees is the dataset's scaled to the model's input size.
      const double sx = static_cast<double>(report.model_width) / w;
      const std::string mismatch =
          CompareCameras(meta.camera, camera->focal * sx, camera->baseline, report.model_height,
                         report.model_width, camera_json);
      if (!mismatch.empty()) {
        if (!options.allow_camera_mismatch) {
          return Status::Error(mismatch +
                               "; evaluate on data from the model's camera, or pass "
                               "--allow-camera-mismatch to score it anyway");
        }
        report.camera_note = mismatch + ": its predictions are in its own camera's units";
      }
    }
    if (report.sequences.empty() || report.sequences.back().name != f.sequence) {
      report.sequences.push_back(SequenceResult{f.sequence, 0, {}, {}});
      for (MetricsAccumulator& m : report.sequences.back().methods) {
        m = MetricsAccumulator(options.thresholds);
      }
    }
    SequenceResult& seq = report.sequences.back();
    const size_t pixels = static_cast<size_t>(h) * w;
    if (runner) {
      const cv::Mat* ptrs[4] = {&images[0], &images[1], &images[2], &images[3]};
      Result<std::vector<float>> pred = runner->Run(ptrs);
      if (!pred.ok()) return Status::Error(paths[0] + ": model run failed: " + pred.message());
      seq.methods[0].Add(pred->data(), gt->data(), pixels);
    }
    seq.methods[1].Add(nullptr, gt->data(), pixels);
    if (options.classical) {
      std::vector<float> classical =
          ClassicalSceneFlow(images[0], images[1], images[2], images[3], rig);
      seq.methods[2].Add(classical.data(), gt->data(), pixels);
    }
    ++seq.frames;
    ++report.frames;
  }
  MergeSequences(&report);
  if (runner) report.isa = IsaName(runner->isa());
  if (options.shard) {
    if (Status st = SetShardProvenance(options, &report); !st.ok()) return st;
  }
  if (progress) progress(EvalProgress{report.frames, report.frames, nullptr});
  return report;
}

namespace {

bool MethodShown(const EvalReport& r, int m) {
  return (m != 0 || r.has_model) && (m != 2 || r.has_classical);
}

std::string Row(const std::string& scope, const char* method, const FlowMetrics& m) {
  char line[200];
  std::snprintf(line, sizeof(line), "%-10s %-10s %8.4f %8.4f %8.4f %8.4f %7.4f %7.4f %8.4f\n",
                scope.c_str(), method, m.epe3d, m.epe_x, m.epe_y, m.epe_z, m.acc05, m.acc10,
                m.outliers);
  return line;
}

}  // namespace

std::string FormatTable(const EvalReport& r) {
  std::string out;
  char head[200];
  std::snprintf(head, sizeof(head), "%-10s %-10s %8s %8s %8s %8s %7s %7s %8s\n", "sequence",
                "method", "EPE3D", "EPE_X", "EPE_Y", "EPE_Z", "ACC.05", "ACC.10", "outliers");
  out += head;
  for (const SequenceResult& seq : r.sequences) {
    if (r.kitti) break;  // one row per scene would be hundreds; the JSON has them
    for (int m = 0; m < kMethodCount; ++m) {
      if (MethodShown(r, m)) out += Row(seq.name, kMethodNames[m], seq.methods[m].Metrics());
    }
  }
  for (int m = 0; m < kMethodCount; ++m) {
    if (MethodShown(r, m)) out += Row("overall", kMethodNames[m], r.overall[m].Metrics());
  }
  if (r.kitti) out += "\n" + FormatKittiTable(r);
  return out;
}

std::string FormatJson(const EvalReport& r) {
  std::ostringstream o;
  o << "{\n  \"dataset\": " << JsonString(r.dataset) << ",\n";
  o << "  \"model\": " << (r.has_model ? JsonString(r.model_path) : "null") << ",\n";
  o << "  \"model_name\": " << (r.has_model ? JsonString(r.model_name) : "null") << ",\n";
  o << "  \"camera\": {\"focal\": " << JsonNumber(r.focal)
    << ", \"baseline\": " << JsonNumber(r.baseline) << ", \"cx\": " << JsonNumber(r.cx)
    << ", \"cy\": " << JsonNumber(r.cy) << "},\n";
  o << "  \"camera_note\": " << JsonString(r.camera_note) << ",\n";
  o << "  \"image_size\": [" << r.height << ", " << r.width << "],\n";
  o << "  \"model_size\": [" << r.model_height << ", " << r.model_width << "],\n";
  o << "  \"frames\": " << r.frames << ",\n";
  o << "  \"units\": \"scene units of the dataset's camera (baseline " << JsonNumber(r.baseline)
    << ")\",\n";
  o << "  \"definitions\": {\"epe3d\": \"mean |pred - gt|\", \"epe_x\": \"mean |pred_x - gt_x|\"";
  for (const ShareRule& rule : kShareRules) {
    o << ", " << JsonString(rule.key) << ": " << JsonString(rule.Definition(r.thresholds));
  }
  o << "},\n";
  o << "  \"thresholds\": " << JsonString(ThresholdsName(r.thresholds)) << ",\n";
  o << "  \"layout\": " << (r.kitti ? "\"kitti\"" : "\"scene flow\"") << ",\n";
  o << "  \"gt_median_motion\": " << JsonNumber(r.overall[1].Metrics().gt_median);
  for (int m = 0; m < kMethodCount; ++m) {
    if (!MethodShown(r, m)) continue;
    o << ",\n  \"" << kMethodNames[m]
      << "\": " << MetricsJson(r.overall[m].Metrics(), r.frames, "  ");
    if (r.kitti)
      o << ",\n    \"kitti\": " << KittiJson(r.kitti_counts[m], DepthLabel(r, m), "    ");
    o << ",\n    \"sequences\": {";
    for (size_t s = 0; s < r.sequences.size(); ++s) {
      const SequenceResult& seq = r.sequences[s];
      o << (s == 0 ? "\n" : ",\n") << "      " << JsonString(seq.name) << ": "
        << MetricsJson(seq.methods[m].Metrics(), seq.frames, "      ") << "\n      }";
    }
    o << "\n    }\n  }";
  }
  if (r.shard) o << ",\n  " << ShardJson(r);
  o << "\n}\n";
  return o.str();
}

}  // namespace sfrt::eval
