#include "eval/evaluate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
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
      report->conventions[m].Merge(seq.conventions[m]);
    }
  }
}

MaskInputs FrameMasks::View() const {
  MaskInputs view;
  for (size_t i = 0; i < kMaskInputs; ++i) {
    view.values[i] = values[i].empty() ? nullptr : values[i].data();
    view.missing[i] = missing[i];
  }
  return view;
}

namespace {

// One mask input's PFM: absent (empty, `missing` set), or read and checked against the frame.
Result<std::optional<io::PfmImage>> ReadMaskFile(const std::string& root, const std::string& path,
                                                 int channels, int height, int width,
                                                 std::string* missing) {
  if (!IsFile(path)) {
    std::error_code ec;
    const fs::path relative = fs::relative(path, root, ec);
    *missing = "no " + (ec || relative.empty() ? path : relative.generic_string());
    return std::optional<io::PfmImage>();
  }
  Result<io::PfmImage> image = io::ReadPfm(path);
  if (!image.ok()) return image.status();
  if (image->channels < channels || image->height != height || image->width != width) {
    return Status::Error(path + ": " + std::to_string(image->height) + "x" +
                         std::to_string(image->width) + " with " + std::to_string(image->channels) +
                         " channel(s); the frame is " + std::to_string(height) + "x" +
                         std::to_string(width) + " and needs " + std::to_string(channels));
  }
  return std::optional<io::PfmImage>(std::move(image).value());
}

// f B / d, +infinity where d is not positive (no depth: every depth bound drops the pixel).
double DepthOf(double fb, double disparity) {
  return disparity > 0 && std::isfinite(disparity) ? fb / disparity
                                                   : std::numeric_limits<double>::infinity();
}

}  // namespace

Result<FrameMasks> LoadMaskInputs(const std::string& root, const FrameRef& frame, double focal,
                                  double baseline, int height, int width) {
  const GtInputs in = GtInputPaths(root, frame);
  std::string no_disparity, no_change, no_flow;
  Result<std::optional<io::PfmImage>> d0 =
      ReadMaskFile(root, in.disparity, 1, height, width, &no_disparity);
  if (!d0.ok()) return d0.status();
  Result<std::optional<io::PfmImage>> change =
      ReadMaskFile(root, in.change, 1, height, width, &no_change);
  if (!change.ok()) return change.status();
  Result<std::optional<io::PfmImage>> flow =
      ReadMaskFile(root, in.flow, 2, height, width, &no_flow);
  if (!flow.ok()) return flow.status();
  FrameMasks masks;
  const size_t pixels = static_cast<size_t>(height) * width;
  const double fb = focal * baseline;
  auto& [depth, next_depth, flow2d] = masks.values;
  masks.missing = {no_disparity, no_disparity.empty() ? no_change : no_disparity, no_flow};
  if (*d0) {
    depth.resize(pixels);
    for (size_t p = 0; p < pixels; ++p) depth[p] = DepthOf(fb, (*d0)->data[p]);
  }
  if (*d0 && *change) {
    next_depth.resize(pixels);
    for (size_t p = 0; p < pixels; ++p) {
      next_depth[p] = DepthOf(
          fb, static_cast<double>((*d0)->data[p]) + static_cast<double>((*change)->data[p]));
    }
  }
  if (*flow) {
    const size_t c = static_cast<size_t>((*flow)->channels);
    flow2d.resize(pixels);
    for (size_t p = 0; p < pixels; ++p) {
      flow2d[p] = std::hypot(static_cast<double>((*flow)->data[c * p]),
                             static_cast<double>((*flow)->data[c * p + 1]));
    }
  }
  return masks;
}

namespace {

// One frame's inputs: the ground truth, the four images (t left, t right, t+1 left, t+1 right)
// and the conventions' mask inputs.
struct FrameData {
  std::vector<float> truth;
  int height = 0, width = 0;
  std::string paths[4];
  cv::Mat images[4];
  FrameMasks masks;
};

Result<FrameData> LoadFrame(const std::string& root, const synth::Intrinsics& camera,
                            const FrameRef& f) {
  FrameData d;
  Result<std::vector<float>> gt = LoadGroundTruth(root, f, camera.focal, camera.baseline, camera.cx,
                                                  camera.cy, &d.height, &d.width);
  if (!gt.ok()) return gt.status();
  d.truth = std::move(gt).value();
  const std::string paths[4] = {Image(root, f.sequence, "left", f.frame),
                                Image(root, f.sequence, "right", f.frame),
                                Image(root, f.sequence, "left", f.next_frame),
                                Image(root, f.sequence, "right", f.next_frame)};
  for (int k = 0; k < 4; ++k) {
    d.paths[k] = paths[k];
    Result<cv::Mat> image = ReadImage(paths[k]);
    if (!image.ok()) return image.status();
    if (image->rows != d.height || image->cols != d.width) {
      return Status::Error(paths[k] + ": image is " + std::to_string(image->rows) + "x" +
                           std::to_string(image->cols) + " but its ground truth is " +
                           std::to_string(d.height) + "x" + std::to_string(d.width));
    }
    d.images[k] = std::move(image).value();
  }
  Result<FrameMasks> masks =
      LoadMaskInputs(root, f, camera.focal, camera.baseline, d.height, d.width);
  if (!masks.ok()) return masks.status();
  d.masks = std::move(masks).value();
  return d;
}

// The first frame sets the report's sizes; every other must have them.
Status CheckFrameSize(const EvalOptions& options, const FrameData& d, bool first,
                      EvalReport* report) {
  if (first) {
    report->height = d.height;
    report->width = d.width;
    report->model_height = options.model_height > 0 ? options.model_height : d.height;
    report->model_width = options.model_width > 0 ? options.model_width : d.width;
  } else if (d.height != report->height || d.width != report->width) {
    return Status::Error(d.paths[0] + ": frame is " + std::to_string(d.height) + "x" +
                         std::to_string(d.width) + " but the first frame is " +
                         std::to_string(report->height) + "x" + std::to_string(report->width) +
                         " (one image size per dataset)");
  }
  return Status::Ok();
}

// One method's prediction of one frame (nullptr: zero flow), scored over every pixel and under
// each convention.
void Score(SequenceResult* seq, int method, const float* pred, const FrameData& d) {
  const size_t pixels = static_cast<size_t>(d.height) * d.width;
  seq->methods[method].Add(pred, d.truth.data(), pixels);
  seq->conventions[method].Add(pred, d.truth.data(), d.masks.View(), pixels);
}

SequenceResult& SequenceOf(const FrameRef& f, Thresholds thresholds, EvalReport* report) {
  if (report->sequences.empty() || report->sequences.back().name != f.sequence) {
    report->sequences.push_back(SequenceResult{f.sequence, 0, {}, {}, {}});
    for (MetricsAccumulator& m : report->sequences.back().methods)
      m = MetricsAccumulator(thresholds);
  }
  return report->sequences.back();
}

}  // namespace

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
    Result<FrameData> d = LoadFrame(options.dataset, *camera, f);
    if (!d.ok()) return d.status();
    if (Status size = CheckFrameSize(options, *d, i == 0, &report); !size.ok()) return size;
    if (report.has_model && !runner) {
      Result<std::unique_ptr<ModelRunner>> started = StartModelRunner(
          options, camera->focal, camera->baseline, d->width, camera_json, &report);
      if (!started.ok()) return started.status();
      runner = std::move(started).value();
    }
    SequenceResult& seq = SequenceOf(f, options.thresholds, &report);
    if (runner) {
      const cv::Mat* ptrs[4] = {&d->images[0], &d->images[1], &d->images[2], &d->images[3]};
      Result<std::vector<float>> pred = runner->Run(ptrs);
      if (!pred.ok()) return Status::Error(d->paths[0] + ": model run failed: " + pred.message());
      Score(&seq, 0, pred->data(), *d);
    }
    Score(&seq, 1, nullptr, *d);
    if (options.classical) {
      std::vector<float> classical =
          ClassicalSceneFlow(d->images[0], d->images[1], d->images[2], d->images[3], rig);
      Score(&seq, 2, classical.data(), *d);
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

// A share's cell: "-" where the paper reports no such share.
std::string Share(double v) {
  if (std::isnan(v)) return "      -";
  char cell[16];
  std::snprintf(cell, sizeof(cell), "%7.4f", v);
  return cell;
}

// Each convention's overall metrics per method (eval/conventions.h); availability depends on the
// dataset only, so zero flow's (always scored) says it.
std::string ConventionsTable(const EvalReport& r) {
  char line[200];
  std::string out =
      "FlyingThings3D conventions (each paper's mask and share rules; sfrt eval --help):\n";
  std::snprintf(line, sizeof(line), "%-10s %-10s %8s %7s %7s %8s %10s %6s\n", "convention",
                "method", "EPE3D", "ACC.05", "ACC.10", "outliers", "pixels", "frames");
  out += line;
  for (int c = 0; c < kConventionCount; ++c) {
    const char* key = kConventions[c].key;
    const ConventionMetrics any = r.conventions[1][c].Metrics();
    if (!any.available) {
      out += std::string(key) + std::string(std::max<size_t>(1, 11 - std::strlen(key)), ' ') +
             "unavailable: " + any.unavailable + "\n";
      continue;
    }
    for (int m = 0; m < kMethodCount; ++m) {
      if (!MethodShown(r, m)) continue;
      const ConventionMetrics cm = r.conventions[m][c].Metrics();
      std::snprintf(line, sizeof(line), "%-10s %-10s %8.4f %s %s  %s %10llu %6llu\n", key,
                    kMethodNames[m], cm.epe3d, Share(cm.shares[0]).c_str(),
                    Share(cm.shares[1]).c_str(), Share(cm.shares[2]).c_str(),
                    static_cast<unsigned long long>(cm.valid_pixels),
                    static_cast<unsigned long long>(cm.frames));
      out += line;
    }
  }
  return out;
}

std::string ConventionJson(const Convention& c, const ConventionMetrics& m,
                           const std::string& indent) {
  std::ostringstream o;
  o << "{\n"
    << indent << "  \"name\": " << JsonString(c.name) << ",\n"
    << indent << "  \"mask\": " << JsonString(c.MaskWords()) << ",\n"
    << indent << "  \"available\": " << (m.available ? "true" : "false") << ",\n";
  if (!m.available) o << indent << "  \"reason\": " << JsonString(m.unavailable) << ",\n";
  const auto number = [&](double v) { return m.available ? JsonNumber(v) : std::string("null"); };
  o << indent << "  \"epe3d\": " << number(m.epe3d) << ",\n";
  for (int s = 0; s < kConventionShares; ++s) {
    o << indent << "  " << JsonString(kShareRules[s].key) << ": " << number(m.shares[s]) << ",\n";
  }
  o << indent << "  \"valid_pixels\": " << m.valid_pixels << ",\n"
    << indent << "  \"frames\": " << m.frames << "\n"
    << indent << "}";
  return o.str();
}

std::string ConventionsJson(const EvalReport& r, int method, const std::string& indent) {
  std::string out = "{";
  for (int c = 0; c < kConventionCount; ++c) {
    out += (c == 0 ? "\n" : ",\n") + indent + "  " + JsonString(kConventions[c].key) + ": " +
           ConventionJson(kConventions[c], r.conventions[method][c].Metrics(), indent + "  ");
  }
  return out + "\n" + indent + "}";
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
  if (!r.kitti) out += "\n" + ConventionsTable(r);
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
  if (!r.kitti) {
    o << ", \"conventions\": {";
    for (int c = 0; c < kConventionCount; ++c) {
      o << (c == 0 ? "" : ", ") << JsonString(kConventions[c].key) << ": "
        << JsonString(kConventions[c].Definition());
    }
    o << "}";
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
    if (!r.kitti) o << ",\n    \"conventions\": " << ConventionsJson(r, m, "    ");
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
