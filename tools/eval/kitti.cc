#include "eval/kitti.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <vector>

#include "sfrt/pipeline/io/atomic_write.h"

namespace sfrt::eval {
namespace {

constexpr double kAbsThreshold = 3.0;   // px (the devkit's ABS_THRESH)
constexpr double kRelThreshold = 0.05;  // of the ground truth's magnitude (REL_THRESH)

Result<cv::Mat> ReadPng16(const std::string& path, int type, const char* what) {
  cv::Mat m = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (m.empty()) return Status::Error(path + ": cannot read the " + std::string(what) + " PNG");
  if (m.type() != type) {
    return Status::Error(path + ": a KITTI " + std::string(what) + " is a 16-bit PNG of " +
                         (type == CV_16UC1 ? "one channel" : "three channels") + "; this has " +
                         std::to_string(m.channels()) + " channel(s) of " +
                         (m.depth() == CV_16U  ? "16"
                          : m.depth() == CV_8U ? "8"
                                               : "other") +
                         " bits");
  }
  return m;
}

Status WritePng(const std::string& path, const cv::Mat& image) {
  std::vector<uint8_t> bytes;
  if (!cv::imencode(".png", image, bytes)) return Status::Error(path + ": cannot encode the PNG");
  return io::WriteFileAtomically(path, bytes);
}

uint16_t ToUint16(double v) {
  return static_cast<uint16_t>(std::clamp(v, 0.0, 65535.0));  // truncation, as the devkit's
}

// The smaller of two values, per component for flow vectors (u and v are filled each on its own).
float Smaller(float a, float b) { return std::min(a, b); }
cv::Vec2f Smaller(cv::Vec2f a, cv::Vec2f b) { return {std::min(a[0], b[0]), std::min(a[1], b[1])}; }

// The rows, then the ends of the columns, filled as the devkit fills them: `valid(y, x)` says
// which pixels have a value (read live: the column pass sees what the row pass filled);
// `get`/`set` read and write it.
template <typename Valid, typename Get, typename Set>
void FillGaps(int rows, int cols, Valid valid, Get get, Set set) {
  for (int y = 0; y < rows; ++y) {
    int gap = 0;
    for (int x = 0; x < cols; ++x) {
      if (!valid(y, x)) {
        ++gap;
        continue;
      }
      const int first = x - gap;
      if (gap > 0 && first > 0) {  // an interior gap: the smaller of its two neighbours
        const auto fill = Smaller(get(y, first - 1), get(y, x));
        for (int g = first; g < x; ++g) set(y, g, fill);
      }
      gap = 0;
    }
    int left = 0;
    while (left < cols && !valid(y, left)) ++left;
    if (left == cols) continue;
    for (int x = 0; x < left; ++x) set(y, x, get(y, left));
    int right = cols - 1;
    while (!valid(y, right)) --right;
    for (int x = right + 1; x < cols; ++x) set(y, x, get(y, right));
  }
  for (int x = 0; x < cols; ++x) {
    int top = 0;
    while (top < rows && !valid(top, x)) ++top;
    if (top == rows) continue;
    for (int y = 0; y < top; ++y) set(y, x, get(top, x));
    int bottom = rows - 1;
    while (!valid(bottom, x)) --bottom;
    for (int y = bottom + 1; y < rows; ++y) set(y, x, get(bottom, x));
  }
}

Result<std::array<double, 12>> ReadMatrix(const std::string& path, const std::string& key) {
  std::ifstream in(path);
  if (!in) return Status::Error(path + ": cannot read the calibration file");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key + ":", 0) != 0) continue;
    std::istringstream values(line.substr(key.size() + 1));
    std::array<double, 12> m{};
    for (double& v : m) {
      if (!(values >> v)) {
        return Status::Error(path + ": " + key + " does not hold 12 numbers (a 3x4 matrix)");
      }
    }
    return m;
  }
  return Status::Error(path + ": no " + key + " line (a KITTI calib_cam_to_cam file has one)");
}

// One value through the devkit's encodings and back (what a PNG holds and the devkit reads).
uint16_t EncodeDisparity(float d) {
  return d > 0 && std::isfinite(d) ? ToUint16(std::max(d * 256.0, 1.0)) : 0;
}
float DecodeDisparity(uint16_t v) { return v == 0 ? kNoDisparity : static_cast<float>(v / 256.0); }
// (u, v, valid) <-> the PNG's B, G, R as OpenCV holds them: valid, v, u.
cv::Vec3w EncodeFlow(const cv::Vec3f& f) {
  const bool valid = f[2] > 0 && std::isfinite(f[0]) && std::isfinite(f[1]);
  return valid ? cv::Vec3w(1, ToUint16(f[1] * 64.0 + 32768.0), ToUint16(f[0] * 64.0 + 32768.0))
               : cv::Vec3w(0, 0, 0);
}
cv::Vec3f DecodeFlow(const cv::Vec3w& bgr) {
  return bgr[0] > 0 ? cv::Vec3f(static_cast<float>((bgr[2] - 32768.0) / 64.0),
                                static_cast<float>((bgr[1] - 32768.0) / 64.0), 1.0f)
                    : cv::Vec3f(0, 0, 0);
}

}  // namespace

Result<cv::Mat> ReadKittiDisparity(const std::string& path) {
  Result<cv::Mat> png = ReadPng16(path, CV_16UC1, "disparity map");
  if (!png.ok()) return png.status();
  cv::Mat d(png->size(), CV_32F);
  for (int y = 0; y < d.rows; ++y) {
    for (int x = 0; x < d.cols; ++x) {
      d.at<float>(y, x) = DecodeDisparity(png->at<uint16_t>(y, x));
    }
  }
  return d;
}

Status WriteKittiDisparity(const std::string& path, const cv::Mat& disparity) {
  cv::Mat png(disparity.size(), CV_16UC1);
  for (int y = 0; y < png.rows; ++y) {
    for (int x = 0; x < png.cols; ++x) {
      png.at<uint16_t>(y, x) = EncodeDisparity(disparity.at<float>(y, x));
    }
  }
  return WritePng(path, png);
}

Result<cv::Mat> ReadKittiFlow(const std::string& path) {
  Result<cv::Mat> png = ReadPng16(path, CV_16UC3, "flow map");
  if (!png.ok()) return png.status();
  cv::Mat flow(png->size(), CV_32FC3);
  for (int y = 0; y < flow.rows; ++y) {
    for (int x = 0; x < flow.cols; ++x) {
      flow.at<cv::Vec3f>(y, x) = DecodeFlow(png->at<cv::Vec3w>(y, x));
    }
  }
  return flow;
}

Status WriteKittiFlow(const std::string& path, const cv::Mat& flow) {
  cv::Mat png(flow.size(), CV_16UC3);
  for (int y = 0; y < png.rows; ++y) {
    for (int x = 0; x < png.cols; ++x) {
      png.at<cv::Vec3w>(y, x) = EncodeFlow(flow.at<cv::Vec3f>(y, x));
    }
  }
  return WritePng(path, png);
}

KittiEstimate AsSubmitted(const KittiEstimate& e) {
  KittiEstimate out{e.disparity0.clone(), e.disparity1.clone(), e.flow.clone()};
  for (cv::Mat* d : {&out.disparity0, &out.disparity1}) {
    d->forEach<float>([](float& v, const int*) { v = DecodeDisparity(EncodeDisparity(v)); });
  }
  out.flow.forEach<cv::Vec3f>([](cv::Vec3f& f, const int*) { f = DecodeFlow(EncodeFlow(f)); });
  return out;
}

Result<cv::Mat> ReadKittiObjectMap(const std::string& path) {
  cv::Mat m = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (m.empty()) return Status::Error(path + ": cannot read the object map PNG");
  return m;
}

Result<PinholeStereo> ReadKittiCalibration(const std::string& path) {
  Result<std::array<double, 12>> p2 = ReadMatrix(path, "P_rect_02");
  if (!p2.ok()) return p2.status();
  Result<std::array<double, 12>> p3 = ReadMatrix(path, "P_rect_03");
  if (!p3.ok()) return p3.status();
  PinholeStereo camera;
  camera.focal = (*p2)[0];
  camera.cx = (*p2)[2];
  camera.cy = (*p2)[6];
  if (!(camera.focal > 0)) {
    return Status::Error(path + ": P_rect_02's focal length is " + std::to_string(camera.focal) +
                         "; expected a positive number of pixels");
  }
  camera.baseline = ((*p2)[3] - (*p3)[3]) / camera.focal;
  if (!(camera.baseline > 0)) {
    return Status::Error(path + ": the baseline (P_rect_02(0,3) - P_rect_03(0,3)) / f is " +
                         std::to_string(camera.baseline) + "; expected the right camera to the " +
                         "left camera's right (a positive baseline)");
  }
  return camera;
}

Status WriteKittiCalibration(const std::string& path, const PinholeStereo& c) {
  std::ostringstream o;
  o.precision(12);
  auto row = [&](const char* key, double tx) {
    o << key << ": " << c.focal << " 0 " << c.cx << " " << tx << " 0 " << c.focal << " " << c.cy
      << " 0 0 0 1 0\n";
  };
  row("P_rect_02", 0.0);
  row("P_rect_03", -c.focal * c.baseline);
  const std::string text = o.str();
  return io::WriteFileAtomically(
      path, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
}

void InterpolateDisparity(cv::Mat* d) {
  FillGaps(
      d->rows, d->cols, [&](int y, int x) { return d->at<float>(y, x) > 0; },
      [&](int y, int x) { return d->at<float>(y, x); },
      [&](int y, int x, float v) { d->at<float>(y, x) = v; });
}

void InterpolateFlow(cv::Mat* flow) {
  FillGaps(
      flow->rows, flow->cols, [&](int y, int x) { return flow->at<cv::Vec3f>(y, x)[2] > 0; },
      [&](int y, int x) {
        const cv::Vec3f f = flow->at<cv::Vec3f>(y, x);
        return cv::Vec2f(f[0], f[1]);
      },
      [&](int y, int x, cv::Vec2f v) { flow->at<cv::Vec3f>(y, x) = cv::Vec3f(v[0], v[1], 1.0f); });
}

KittiEstimate ProjectSceneFlow(const cv::Mat& disparity0, const float* scene_flow,
                               const PinholeStereo& c) {
  KittiEstimate e;
  e.disparity0 = disparity0.clone();
  e.disparity1 = cv::Mat(disparity0.size(), CV_32F, cv::Scalar(kNoDisparity));
  e.flow = cv::Mat(disparity0.size(), CV_32FC3, cv::Scalar(0, 0, 0));
  const double fb = c.focal * c.baseline;
  for (int y = 0; y < disparity0.rows; ++y) {
    for (int x = 0; x < disparity0.cols; ++x) {
      const float d0 = disparity0.at<float>(y, x);
      const float* f = scene_flow + (static_cast<size_t>(y) * disparity0.cols + x) * 3;
      if (!(d0 > 0) || !std::isfinite(f[0]) || !std::isfinite(f[1]) || !std::isfinite(f[2])) {
        continue;
      }
      const double z0 = fb / d0;
      const double x1 = (x - c.cx) * z0 / c.focal + f[0];
      const double y1 = (y - c.cy) * z0 / c.focal + f[1];
      const double z1 = z0 + f[2];
      if (!(z1 > 0)) continue;
      e.disparity1.at<float>(y, x) = static_cast<float>(fb / z1);
      e.flow.at<cv::Vec3f>(y, x) =
          cv::Vec3f(static_cast<float>(c.focal * x1 / z1 + c.cx - x),
                    static_cast<float>(c.focal * y1 / z1 + c.cy - y), 1.0f);
    }
  }
  return e;
}

std::vector<float> KittiGroundTruthSceneFlow(const cv::Mat& d0, const cv::Mat& d1,
                                             const cv::Mat& flow, const PinholeStereo& c) {
  std::vector<float> out(static_cast<size_t>(d0.rows) * d0.cols * 3,
                         std::numeric_limits<float>::quiet_NaN());
  const double fb = c.focal * c.baseline;
  for (int y = 0; y < d0.rows; ++y) {
    for (int x = 0; x < d0.cols; ++x) {
      const float a = d0.at<float>(y, x);
      const float b = d1.at<float>(y, x);
      const cv::Vec3f f = flow.at<cv::Vec3f>(y, x);
      if (!(a > 0) || !(b > 0) || !(f[2] > 0)) continue;
      const double z0 = fb / a;
      const double z1 = fb / b;
      float* o = &out[(static_cast<size_t>(y) * d0.cols + x) * 3];
      o[0] = static_cast<float>((x + f[0] - c.cx) * z1 / c.focal - (x - c.cx) * z0 / c.focal);
      o[1] = static_cast<float>((y + f[1] - c.cy) * z1 / c.focal - (y - c.cy) * z0 / c.focal);
      o[2] = static_cast<float>(z1 - z0);
    }
  }
  return out;
}

bool DisparityOutlier(float estimate, float truth) {
  const double err = std::fabs(static_cast<double>(estimate) - truth);
  return err > kAbsThreshold && err / std::fabs(static_cast<double>(truth)) > kRelThreshold;
}

bool FlowOutlier(float du, float dv, float truth_u, float truth_v) {
  const double err = std::hypot(static_cast<double>(du), static_cast<double>(dv));
  const double mag = std::hypot(static_cast<double>(truth_u), static_cast<double>(truth_v));
  return err > kAbsThreshold && err / mag > kRelThreshold;
}

void KittiCounts::Add(const cv::Mat& gt_d0, const cv::Mat& gt_d1, const cv::Mat& gt_flow,
                      const cv::Mat& object_map, const KittiEstimate& e) {
  for (int y = 0; y < gt_d0.rows; ++y) {
    for (int x = 0; x < gt_d0.cols; ++x) {
      const int r = object_map.at<uint8_t>(y, x) > 0 ? 1 : 0;
      const float t0 = gt_d0.at<float>(y, x);
      const float t1 = gt_d1.at<float>(y, x);
      const cv::Vec3f tf = gt_flow.at<cv::Vec3f>(y, x);
      const cv::Vec3f ef = e.flow.at<cv::Vec3f>(y, x);
      const bool has[3] = {t0 > 0, t1 > 0, tf[2] > 0};
      // An estimate with no value even after filling is as far off as the devkit's -1.
      const bool bad[3] = {
          has[0] && DisparityOutlier(e.disparity0.at<float>(y, x), t0),
          has[1] && DisparityOutlier(e.disparity1.at<float>(y, x), t1),
          has[2] && (!(ef[2] > 0) || FlowOutlier(ef[0] - tf[0], ef[1] - tf[1], tf[0], tf[1]))};
      for (int m = 0; m < 3; ++m) {
        pixels_[m][r] += has[m];
        outliers_[m][r] += bad[m];
      }
      if (has[0] && has[1] && has[2]) {
        pixels_[3][r] += 1;
        outliers_[3][r] += bad[0] || bad[1] || bad[2];
      }
    }
  }
}

void KittiCounts::Merge(const KittiCounts& other) {
  for (int m = 0; m < kKittiMaps; ++m) {
    for (int r = 0; r < 2; ++r) {
      pixels_[m][r] += other.pixels_[m][r];
      outliers_[m][r] += other.outliers_[m][r];
    }
  }
}

uint64_t KittiCounts::pixels(KittiMap map, KittiRegion region) const {
  return pixels_[static_cast<int>(map)][static_cast<int>(region)];
}

uint64_t KittiCounts::outliers(KittiMap map, KittiRegion region) const {
  return outliers_[static_cast<int>(map)][static_cast<int>(region)];
}

nlohmann::json KittiCounts::State() const { return {{"pixels", pixels_}, {"outliers", outliers_}}; }

Result<KittiCounts> KittiCounts::FromState(const nlohmann::json& state) {
  KittiCounts c;
  for (auto [key, table] : {std::pair{"pixels", &c.pixels_}, std::pair{"outliers", &c.outliers_}}) {
    const bool shaped = state.is_object() && state.contains(key) && state[key].is_array() &&
                        state[key].size() == kKittiMaps;
    if (!shaped) return Status::Error(std::string("kitti ") + key + ": expected 4 [bg, fg] pairs");
    for (int m = 0; m < kKittiMaps; ++m) {
      const nlohmann::json& pair = state[key][m];
      if (!pair.is_array() || pair.size() != 2 || !pair[0].is_number_unsigned() ||
          !pair[1].is_number_unsigned()) {
        return Status::Error(std::string("kitti ") + key + ": expected 4 [bg, fg] pairs of counts");
      }
      (*table)[m] = {pair[0].get<uint64_t>(), pair[1].get<uint64_t>()};
    }
  }
  return c;
}

double KittiCounts::Percent(KittiMap map, KittiRegion region) const {
  return 100.0 * static_cast<double>(outliers(map, region)) /
         static_cast<double>(std::max<uint64_t>(pixels(map, region), 1));
}

double KittiCounts::PercentAll(KittiMap map) const {
  const uint64_t n = pixels(map, KittiRegion::kBackground) + pixels(map, KittiRegion::kForeground);
  const uint64_t o =
      outliers(map, KittiRegion::kBackground) + outliers(map, KittiRegion::kForeground);
  return 100.0 * static_cast<double>(o) / static_cast<double>(std::max<uint64_t>(n, 1));
}

}  // namespace sfrt::eval
