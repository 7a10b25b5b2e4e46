#include "synth/annotate.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/io/pfm.h"

namespace sfrt::synth {
namespace {

namespace fs = std::filesystem;

bool AllDigits(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// "0009" -> "0010", keeping the width.
std::string NextFrameName(const std::string& name) {
  long long n = std::strtoll(name.c_str(), nullptr, 10) + 1;
  std::string s = std::to_string(n);
  if (s.size() < name.size()) s.insert(0, name.size() - s.size(), '0');
  return s;
}

bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

Status CheckSize(const io::PfmImage& img, const io::PfmImage& ref, int channels,
                 const std::string& path, const std::string& ref_path) {
  if (img.channels != channels) {
    return Status::Error(path + ": has " + std::to_string(img.channels) + " channel(s), expected " +
                         std::to_string(channels));
  }
  if (img.height != ref.height || img.width != ref.width) {
    return Status::Error(path + ": is " + std::to_string(img.height) + "x" +
                         std::to_string(img.width) + " (HxW) but " + ref_path + " is " +
                         std::to_string(ref.height) + "x" + std::to_string(ref.width));
  }
  return Status::Ok();
}

}  // namespace

bool SubsetIntrinsics(const std::string& subset, Intrinsics* out) {
  Intrinsics k;
  if (subset == "flyingthings3d" || subset == "monkaa" || subset == "driving35mm") {
    k.focal = 1050;
  } else if (subset == "driving15mm") {
    k.focal = 450;
  } else {
    return false;
  }
  *out = k;
  return true;
}

Result<Intrinsics> ReadCameraJson(const std::string& path) {
  Result<std::string> text = io::ReadWholeFile(path);
  if (!text.ok()) return text.status();
  Intrinsics k;
  auto field = [&](const char* key, double* value) -> Status {
    const std::string quoted = std::string("\"") + key + "\"";
    size_t pos = text->find(quoted);
    if (pos == std::string::npos) return Status::Error(path + ": no field '" + key + "'");
    pos = text->find(':', pos + quoted.size());
    if (pos == std::string::npos) return Status::Error(path + ": field '" + key + "' has no value");
    ++pos;
    while (pos < text->size() && ((*text)[pos] == ' ' || (*text)[pos] == '\t')) ++pos;
    const char* begin = text->data() + pos;
    const char* end = text->data() + text->size();
    auto [ptr, ec] = std::from_chars(begin, end, *value);
    if (ec != std::errc() || ptr == begin || !std::isfinite(*value)) {
      return Status::Error(path + ": field '" + key + "' is not a number");
    }
    return Status::Ok();
  };
  for (auto [key, value] : {std::pair{"focal", &k.focal}, std::pair{"baseline", &k.baseline},
                            std::pair{"cx", &k.cx}, std::pair{"cy", &k.cy}}) {
    if (Status s = field(key, value); !s.ok()) return s;
  }
  if (k.focal <= 0 || k.baseline <= 0) {
    return Status::Error(path + ": focal and baseline must be positive");
  }
  return k;
}

size_t ComputeSceneFlow(const float* d0, const float* second, const float* flow, int flow_channels,
                        int height, int width, const Intrinsics& k, ConventionKind convention,
                        float* out) {
  const double fb = k.focal * k.baseline;
  const bool authors = convention == ConventionKind::kAuthorsPublished;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  size_t invalid = 0;
  for (int row = 0; row < height; ++row) {
    for (int col = 0; col < width; ++col) {
      const size_t i = static_cast<size_t>(row) * width + col;
      const double a = d0[i];
      // d1 = d0 + disparity_change (formula) or the next frame's disparity (authors).
      const double b = authors ? static_cast<double>(second[i]) : a + second[i];
      const double u = flow[i * flow_channels + 0];
      const double v = flow[i * flow_channels + 1];
      float* o = out + i * 3;
      if (!(a > 0) || !(b > 0) || !std::isfinite(a) || !std::isfinite(b) || !std::isfinite(u) ||
          !std::isfinite(v)) {
        o[0] = o[1] = o[2] = nan;
        ++invalid;
        continue;
      }
      // The pixel coordinate paired with cx (and u), and the one paired with cy (and v).
      const double px = authors ? row : col;
      const double py = authors ? col : row;
      const double z0 = fb / a;
      const double z1 = fb / b;
      const double x0 = (px - k.cx) * z0 / k.focal;
      const double y0 = (py - k.cy) * z0 / k.focal;
      const double x1 = (px + u - k.cx) * z1 / k.focal;
      const double y1 = (py + v - k.cy) * z1 / k.focal;
      o[0] = static_cast<float>(x1 - x0);
      o[1] = static_cast<float>(y1 - y0);
      o[2] = static_cast<float>(z1 - z0);
    }
  }
  return invalid;
}

Result<AnnotateSummary> AnnotateTree(
    const std::string& root, const std::string& out, const Intrinsics& k, ConventionKind convention,
    const std::function<void(const AnnotateFrameInfo&)>& on_frame) {
  const fs::path base(root);
  const fs::path disp_root = base / "disparity";
  std::error_code ec;
  if (!fs::is_directory(disp_root, ec)) {
    return Status::Error("dataset root '" + root + "' has no 'disparity' directory");
  }
  // Every <rel>/left/NNNN.pfm under disparity/.
  std::vector<fs::path> frames;
  for (auto it = fs::recursive_directory_iterator(disp_root, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    const fs::path& p = it->path();
    if (p.extension() == ".pfm" && p.parent_path().filename() == "left" &&
        AllDigits(p.stem().string()) && it->is_regular_file()) {
      frames.push_back(p);
    }
  }
  if (ec) return Status::Error("cannot list '" + disp_root.string() + "': " + ec.message());
  std::sort(frames.begin(), frames.end());

  AnnotateSummary summary;
  const bool authors = convention == ConventionKind::kAuthorsPublished;
  summary.frames_found = static_cast<int>(frames.size());
  for (size_t index = 0; index < frames.size(); ++index) {
    const fs::path& d0_path = frames[index];
    const fs::path rel = d0_path.parent_path().parent_path().lexically_relative(disp_root);
    const std::string name = d0_path.stem().string();
    const fs::path flow_path = base / "optical_flow" / rel / "into_future" / "left" /
                               ("OpticalFlowIntoFuture_" + name + "_L.pfm");
    const fs::path d1_path =
        authors ? d0_path.parent_path() / (NextFrameName(name) + ".pfm")
                : base / "disparity_change" / rel / "into_future" / "left" / (name + ".pfm");
    std::string missing;
    if (!IsFile(d1_path)) missing = d1_path.string();
    if (!IsFile(flow_path)) missing += (missing.empty() ? "" : " and ") + flow_path.string();
    if (!missing.empty()) {
      if (summary.frames_skipped == 0) {
        summary.first_skipped = d0_path.string() + ": missing " + missing;
      }
      ++summary.frames_skipped;
      continue;
    }
    Result<io::PfmImage> d0 = io::ReadPfm(d0_path.string());
    if (!d0.ok()) return d0.status();
    if (d0->channels != 1) {
      return Status::Error(d0_path.string() + ": has " + std::to_string(d0->channels) +
                           " channels, expected 1 (disparity)");
    }
    Result<io::PfmImage> second = io::ReadPfm(d1_path.string());
    if (!second.ok()) return second.status();
    if (Status s = CheckSize(*second, *d0, 1, d1_path.string(), d0_path.string()); !s.ok()) {
      return s;
    }
    Result<io::PfmImage> flow = io::ReadPfm(flow_path.string());
    if (!flow.ok()) return flow.status();
    if (Status s = CheckSize(*flow, *d0, 3, flow_path.string(), d0_path.string()); !s.ok()) {
      return s;
    }
    const size_t n = static_cast<size_t>(d0->height) * d0->width;
    std::vector<float> sf(n * 3);
    const size_t invalid = ComputeSceneFlow(d0->data.data(), second->data.data(), flow->data.data(),
                                            3, d0->height, d0->width, k, convention, sf.data());
    const fs::path out_dir = fs::path(out) / "scene_flow" / rel / "into_future" / "left";
    fs::create_directories(out_dir, ec);
    if (ec) {
      return Status::Error("cannot create directory '" + out_dir.string() + "': " + ec.message());
    }
    const std::string out_path = (out_dir / (name + ".pfm")).string();
    if (Status s = io::WritePfm(out_path, sf, d0->height, d0->width, 3); !s.ok()) return s;
    ++summary.frames_written;
    summary.pixels += n;
    summary.invalid_pixels += invalid;
    if (on_frame)
      on_frame(
          AnnotateFrameInfo{static_cast<int>(index), summary.frames_found, out_path, n, invalid});
  }
  return summary;
}

}  // namespace sfrt::synth
