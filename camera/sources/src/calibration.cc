// Calibration readers, all on yaml-cpp (never cv::FileStorage); its exceptions stop here.
#include "sfrt/camera/calibration.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/calib3d.hpp>
#include <set>
#include <sstream>
#include <system_error>

namespace sfrt::camera {
namespace {

std::string Num(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

// A short rendering of a YAML node for error messages.
std::string Show(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "null";
  YAML::Emitter e;
  e << YAML::Flow << node;
  std::string text = e.c_str();
  if (text.size() > 60) text = text.substr(0, 57) + "...";
  return "'" + text + "'";
}

Status CheckReadable(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Status::Error(path + ": calibration file does not exist or is not a regular file");
  }
  return Status::Ok();
}

// A calibration file is a few kilobytes; anything past this is not one (and is not parsed).
constexpr std::uintmax_t kMaxCalibrationFileBytes = 1 << 20;

// Reads a whole calibration file, refusing files over kMaxCalibrationFileBytes.
Result<std::string> ReadCalibrationText(const std::string& path) {
  if (Status s = CheckReadable(path); !s.ok()) return s;
  std::error_code ec;
  const std::uintmax_t bytes = std::filesystem::file_size(path, ec);
  if (ec) return Status::Error(path + ": cannot read calibration file (" + ec.message() + ")");
  if (bytes > kMaxCalibrationFileBytes) {
    return Status::Error(path + ": calibration file is " + std::to_string(bytes) +
                         " bytes; the limit is " + std::to_string(kMaxCalibrationFileBytes));
  }
  std::ifstream in(path, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in && !in.eof()) return Status::Error(path + ": cannot read calibration file");
  return text;
}

Result<YAML::Node> LoadYaml(const std::string& path) {
  Result<std::string> text = ReadCalibrationText(path);
  if (!text.ok()) return text.status();
  try {
    YAML::Node root = YAML::Load(*text);
    if (!root.IsMap()) return Status::Error(path + ": top level is not a YAML mapping");
    return root;
  } catch (const YAML::Exception& e) {
    return Status::Error(path + ": not valid YAML (" + std::string(e.what()) + ")");
  }
}

// Reads key `name` (a path like "cam1.T_cn_cnm1" for messages) as a double.
Result<double> GetDouble(const std::string& file, const std::string& name, const YAML::Node& node) {
  if (!node.IsDefined()) return Status::Error(file + ": missing key '" + name + "'");
  if (!node.IsScalar()) {
    return Status::Error(file + ": key '" + name + "' value " + Show(node) + " is not a number");
  }
  try {
    double v = node.as<double>();
    if (!std::isfinite(v)) {
      return Status::Error(file + ": key '" + name + "' value " + Show(node) + " is not finite");
    }
    return v;
  } catch (const YAML::Exception&) {
    return Status::Error(file + ": key '" + name + "' value " + Show(node) + " is not a number");
  }
}

// A flat list of numbers; expected_sizes empty = any length.
Result<std::vector<double>> GetList(const std::string& file, const std::string& name,
                                    const YAML::Node& node, const std::set<size_t>& sizes) {
  if (!node.IsDefined()) return Status::Error(file + ": missing key '" + name + "'");
  if (!node.IsSequence()) {
    return Status::Error(file + ": key '" + name + "' value " + Show(node) + " is not a list");
  }
  std::vector<double> out;
  for (size_t i = 0; i < node.size(); ++i) {
    Result<double> v = GetDouble(file, name + "[" + std::to_string(i) + "]", node[i]);
    if (!v.ok()) return v.status();
    out.push_back(*v);
  }
  if (!sizes.empty() && !sizes.count(out.size())) {
    std::string expected;
    for (size_t s : sizes) expected += (expected.empty() ? "" : " or ") + std::to_string(s);
    return Status::Error(file + ": key '" + name + "' has " + std::to_string(out.size()) +
                         " values, expected " + expected);
  }
  return out;
}

Result<int> GetPositiveInt(const std::string& file, const std::string& name,
                           const YAML::Node& node) {
  Result<double> v = GetDouble(file, name, node);
  if (!v.ok()) return v.status();
  if (*v < 1 || *v > 1e6 || *v != std::floor(*v)) {
    return Status::Error(file + ": key '" + name + "' value " + Num(*v) +
                         " is not a positive whole number");
  }
  return static_cast<int>(*v);
}

Status CheckIntrinsics(const std::string& file, const std::string& name, const cv::Matx33d& K) {
  if (!(K(0, 0) > 0) || !(K(1, 1) > 0)) {
    return Status::Error(file + ": key '" + name + "' has focal lengths " + Num(K(0, 0)) + ", " +
                         Num(K(1, 1)) + "; both must be positive");
  }
  if (K(1, 0) != 0 || K(2, 0) != 0 || K(2, 1) != 0 || K(2, 2) != 1) {
    return Status::Error(file + ": key '" + name +
                         "' is not an upper-triangular camera matrix with K[2][2] = 1");
  }
  return Status::Ok();
}

Status CheckRotation(const std::string& file, const std::string& name, const cv::Matx33d& R) {
  const cv::Matx33d should_be_eye = R.t() * R;
  const double err = cv::norm(should_be_eye - cv::Matx33d::eye(), cv::NORM_INF);
  if (err > 1e-3 || cv::determinant(R) < 0) {
    return Status::Error(file + ": key '" + name + "' is not a rotation matrix (|R^T R - I| = " +
                         Num(err) + ", det = " + Num(cv::determinant(R)) + ")");
  }
  return Status::Ok();
}

// ---- ROS camera_info ----

struct RosCamera {
  cv::Size size;
  cv::Matx33d K;
  cv::Mat D;
  cv::Matx33d R;
  cv::Matx34d P;
};

Result<std::vector<double>> RosMatrix(const std::string& file, const YAML::Node& root,
                                      const std::string& key, int rows, int cols) {
  const YAML::Node node = root[key];
  if (!node.IsDefined()) return Status::Error(file + ": missing key '" + key + "'");
  if (!node.IsMap()) {
    return Status::Error(file + ": key '" + key + "' value " + Show(node) +
                         " is not a mapping with rows, cols and data");
  }
  if (rows > 0) {
    for (const auto& [field, want] : {std::pair<const char*, int>{"rows", rows}, {"cols", cols}}) {
      if (node[field].IsDefined()) {
        Result<double> v = GetDouble(file, key + "." + field, node[field]);
        if (!v.ok()) return v.status();
        if (*v != want) {
          return Status::Error(file + ": key '" + key + "." + field + "' value " + Num(*v) +
                               ", expected " + std::to_string(want));
        }
      }
    }
    return GetList(file, key + ".data", node["data"], {static_cast<size_t>(rows * cols)});
  }
  return GetList(file, key + ".data", node["data"], {});
}

Result<RosCamera> ReadRosCamera(const std::string& file) {
  Result<YAML::Node> root = LoadYaml(file);
  if (!root.ok()) return root.status();
  RosCamera cam;
  Result<int> w = GetPositiveInt(file, "image_width", (*root)["image_width"]);
  if (!w.ok()) return w.status();
  Result<int> h = GetPositiveInt(file, "image_height", (*root)["image_height"]);
  if (!h.ok()) return h.status();
  cam.size = cv::Size(*w, *h);
  Result<std::vector<double>> k = RosMatrix(file, *root, "camera_matrix", 3, 3);
  if (!k.ok()) return k.status();
  cam.K = cv::Matx33d(k->data());
  if (Status s = CheckIntrinsics(file, "camera_matrix", cam.K); !s.ok()) return s;

  std::string model;
  if ((*root)["distortion_model"].IsDefined() && !(*root)["distortion_model"].IsNull()) {
    if (!(*root)["distortion_model"].IsScalar()) {
      return Status::Error(file + ": key 'distortion_model' value " +
                           Show((*root)["distortion_model"]) + " is not a string");
    }
    model = (*root)["distortion_model"].as<std::string>();
  }
  if (model == "plumb_bob" || model == "rational_polynomial") {
    Result<std::vector<double>> d = RosMatrix(file, *root, "distortion_coefficients", 0, 0);
    if (!d.ok()) return d.status();
    const size_t want = model == "plumb_bob" ? 5 : 8;
    if (d->size() != want) {
      return Status::Error(file + ": key 'distortion_coefficients.data' has " +
                           std::to_string(d->size()) + " values but distortion_model '" + model +
                           "' needs " + std::to_string(want));
    }
    cam.D = cv::Mat(1, static_cast<int>(d->size()), CV_64F, d->data()).clone();
  } else if (!model.empty() && model != "none") {
    return Status::Error(file + ": key 'distortion_model' value '" + model +
                         "' is not supported (plumb_bob, rational_polynomial, none)");
  }
  Result<std::vector<double>> r = RosMatrix(file, *root, "rectification_matrix", 3, 3);
  if (!r.ok()) return r.status();
  cam.R = cv::Matx33d(r->data());
  if (Status s = CheckRotation(file, "rectification_matrix", cam.R); !s.ok()) return s;
  Result<std::vector<double>> p = RosMatrix(file, *root, "projection_matrix", 3, 4);
  if (!p.ok()) return p.status();
  cam.P = cv::Matx34d(p->data());
  if (!(cam.P(0, 0) > 0) || !(cam.P(1, 1) > 0)) {
    return Status::Error(file + ": key 'projection_matrix' has focal lengths " + Num(cam.P(0, 0)) +
                         ", " + Num(cam.P(1, 1)) + "; both must be positive");
  }
  return cam;
}

// ---- OpenCV FileStorage (YAML), read with yaml-cpp ----
//
// cv::FileStorage is never given a calibration file: its parsers crash on damaged input (OpenCV
// 4.6 dereferences NULL in FileStorage::open on the 10-byte XML `<?xml ion=`, found by
// fuzz_calibration). The YAML flavour OpenCV writes is read here with yaml-cpp instead, and XML is
// refused with a message saying how to convert it.

// Calibration matrices are at most 3x4 and distortion vectors 1x14; anything larger is damage.
constexpr int kMaxMatrixSide = 64;
struct FsFile {
  std::string path;
  YAML::Node root;  // a mapping
};

Result<FsFile> LoadOpenCvYaml(const std::string& path) {
  Result<std::string> text = ReadCalibrationText(path);
  if (!text.ok()) return text.status();
  std::string& t = *text;
  size_t start = t.rfind("\xEF\xBB\xBF", 0) == 0 ? 3 : 0;  // UTF-8 byte order mark
  start = std::min(t.find_first_not_of(" \t\r\n", start), t.size());
  if (t.compare(start, 1, "<") == 0) {
    return Status::Error(path +
                         ": OpenCV XML calibration files are not read (OpenCV's XML parser is not "
                         "safe on damaged files); save it as OpenCV YAML (cv::FileStorage with a "
                         ".yml name)");
  }
  // OpenCV writes the directive "%YAML:1.0", which is not YAML: blank that line (keeping the line
  // numbers of yaml-cpp's messages right).
  if (t.compare(start, 6, "%YAML:") == 0) {
    const size_t end = std::min(t.find('\n', start), t.size());
    std::fill(t.begin() + static_cast<std::ptrdiff_t>(start),
              t.begin() + static_cast<std::ptrdiff_t>(end), ' ');
  }
  FsFile f;
  f.path = path;
  try {
    f.root = YAML::Load(t);
  } catch (const YAML::Exception& e) {
    return Status::Error(path + ": not valid OpenCV YAML (" + std::string(e.what()) + ")");
  }
  if (!f.root.IsMap()) {
    return Status::Error(path + ": top level of the OpenCV YAML file is not a mapping");
  }
  return f;
}

std::string Shape(const cv::Mat& m) {
  return std::to_string(m.rows) + "x" + std::to_string(m.cols);
}

// An opencv-matrix mapping (rows, cols, dt, data) as a 1-channel CV_64F matrix.
Result<cv::Mat> ParseFsMatrix(const std::string& file, const std::string& key,
                              const YAML::Node& node) {
  const Status not_matrix = Status::Error(file + ": key '" + key +
                                          "' is not an OpenCV matrix (opencv-matrix with rows, "
                                          "cols, dt, data)");
  if (!node.IsMap() || !node["rows"].IsDefined() || !node["cols"].IsDefined() ||
      !node["data"].IsDefined()) {
    return not_matrix;
  }
  Result<int> rows = GetPositiveInt(file, key + ".rows", node["rows"]);
  if (!rows.ok()) return rows.status();
  Result<int> cols = GetPositiveInt(file, key + ".cols", node["cols"]);
  if (!cols.ok()) return cols.status();
  if (*rows > kMaxMatrixSide || *cols > kMaxMatrixSide) {
    return Status::Error(file + ": key '" + key + "' is " + std::to_string(*rows) + "x" +
                         std::to_string(*cols) + "; a calibration matrix is at most " +
                         std::to_string(kMaxMatrixSide) + "x" + std::to_string(kMaxMatrixSide));
  }
  // dt: an optional channel count and one element type letter ("d", "f", "3d", ...).
  const YAML::Node dt = node["dt"];
  if (dt.IsDefined()) {
    const std::string type = dt.IsScalar() ? dt.Scalar() : "";
    size_t digits = 0;
    while (digits < type.size() && digits < 3 &&
           std::isdigit(static_cast<unsigned char>(type[digits]))) {
      ++digits;
    }
    const bool valid =
        type.size() == digits + 1 && std::string("ucwsifdh").find(type.back()) != std::string::npos;
    if (!valid) {
      return Status::Error(file + ": key '" + key + ".dt' value " + Show(dt) +
                           " is not an OpenCV element type (u, c, w, s, i, f, d, h)");
    }
    const int channels = digits == 0 ? 1 : std::stoi(type.substr(0, digits));
    if (channels != 1) {
      return Status::Error(file + ": key '" + key + "' has " + std::to_string(channels) +
                           " channels, expected 1");
    }
  }
  Result<std::vector<double>> data =
      GetList(file, key + ".data", node["data"], {static_cast<size_t>(*rows * *cols)});
  if (!data.ok()) return data.status();
  return cv::Mat(*rows, *cols, CV_64F, data->data()).clone();
}

Result<cv::Mat> FsMatrix(const std::vector<FsFile>& files, const std::vector<std::string>& names,
                         bool required, std::string* found_in, std::string* found_key) {
  const FsFile* where = nullptr;
  std::string key;
  for (const FsFile& f : files) {
    for (const std::string& n : names) {
      if (!f.root[n].IsDefined()) continue;
      if (where != nullptr) {
        return Status::Error(f.path + ": key '" + n + "' is also given as '" + key + "' in " +
                             where->path + "; give it once");
      }
      where = &f;
      key = n;
    }
  }
  if (where == nullptr) {
    if (!required) return cv::Mat();
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "'" : "' or '") + n;
    std::string paths;
    for (const FsFile& f : files) paths += (paths.empty() ? "" : ", ") + f.path;
    return Status::Error(paths + ": missing key " + list + "'");
  }
  *found_in = where->path;
  *found_key = key;
  return ParseFsMatrix(where->path, key, where->root[key]);
}

Result<cv::Matx33d> FsIntrinsics(const std::vector<FsFile>& files, const char* k, const char* m) {
  std::string file, key;
  Result<cv::Mat> mat = FsMatrix(files, {k, m}, true, &file, &key);
  if (!mat.ok()) return mat.status();
  if (mat->rows != 3 || mat->cols != 3) {
    return Status::Error(file + ": key '" + key + "' is " + Shape(*mat) + ", expected 3x3");
  }
  cv::Matx33d K;
  for (int i = 0; i < 9; ++i) K.val[i] = mat->at<double>(i);
  if (Status s = CheckIntrinsics(file, key, K); !s.ok()) return s;
  return K;
}

Result<cv::Mat> FsDistortion(const std::vector<FsFile>& files, const char* name) {
  std::string file, key;
  Result<cv::Mat> mat = FsMatrix(files, {name}, true, &file, &key);
  if (!mat.ok()) return mat.status();
  const int n = static_cast<int>(mat->total());
  if ((mat->rows != 1 && mat->cols != 1) || !(n == 4 || n == 5 || n == 8 || n == 12 || n == 14)) {
    return Status::Error(file + ": key '" + key + "' is " + Shape(*mat) +
                         ", expected 1xN or Nx1 with N in {4, 5, 8, 12, 14}");
  }
  return mat->reshape(1, 1).clone();
}

Result<cv::Size> FsImageSize(const std::vector<FsFile>& files) {
  for (const FsFile& f : files) {
    for (const char* key : {"image_size", "imageSize"}) {
      const YAML::Node node = f.root[key];
      if (!node.IsDefined()) continue;
      const Status bad =
          Status::Error(f.path + ": key '" + key + "' is not [width, height] in pixels");
      std::vector<double> v;
      if (node.IsSequence()) {
        Result<std::vector<double>> list = GetList(f.path, key, node, {2});
        if (!list.ok()) return bad;
        v = *list;
      } else {
        Result<cv::Mat> m = ParseFsMatrix(f.path, key, node);  // a 1x2 or 2x1 opencv-matrix
        if (!m.ok() || m->total() != 2) return bad;
        v = {m->at<double>(0), m->at<double>(1)};
      }
      if (!(v[0] >= 1) || !(v[1] >= 1) || !(v[0] <= 1e6) || !(v[1] <= 1e6) ||
          v[0] != std::floor(v[0]) || v[1] != std::floor(v[1])) {
        return bad;
      }
      return cv::Size(static_cast<int>(v[0]), static_cast<int>(v[1]));
    }
    const YAML::Node w = f.root["image_width"], h = f.root["image_height"];
    if (w.IsDefined() || h.IsDefined()) {
      Result<int> width = GetPositiveInt(f.path, "image_width", w);
      Result<int> height = GetPositiveInt(f.path, "image_height", h);
      if (!width.ok() || !height.ok()) {
        return Status::Error(f.path +
                             ": keys 'image_width' and 'image_height' must both be positive "
                             "integers");
      }
      return cv::Size(*width, *height);
    }
  }
  return cv::Size();
}

}  // namespace

Result<StereoCalibration> ReadRosCameraInfoPair(const std::string& left_yaml,
                                                const std::string& right_yaml) {
  Result<RosCamera> left = ReadRosCamera(left_yaml);
  if (!left.ok()) return left.status();
  Result<RosCamera> right = ReadRosCamera(right_yaml);
  if (!right.ok()) return right.status();
  if (left->size != right->size) {
    return Status::Error(right_yaml + ": keys 'image_width' x 'image_height' are " +
                         std::to_string(right->size.width) + "x" +
                         std::to_string(right->size.height) + " but " + left_yaml + " has " +
                         std::to_string(left->size.width) + "x" +
                         std::to_string(left->size.height));
  }
  if (left->P(0, 3) != 0) {
    return Status::Error(left_yaml +
                         ": key 'projection_matrix' has Tx = P[0][3] = " + Num(left->P(0, 3)) +
                         "; the left camera's must be 0 (are the files swapped?)");
  }
  if (right->P(0, 3) == 0) {
    return Status::Error(right_yaml +
                         ": key 'projection_matrix' has Tx = P[0][3] = 0, so it carries no "
                         "baseline (is this the right camera of a stereo calibration?)");
  }
  StereoCalibration c;
  c.image_size = left->size;
  c.K1 = left->K;
  c.D1 = left->D;
  c.K2 = right->K;
  c.D2 = right->D;
  const cv::Vec3d t_rect(right->P(0, 3) / right->P(0, 0), right->P(1, 3) / right->P(1, 1), 0.0);
  c.R = right->R.t() * left->R;
  c.T = right->R.t() * t_rect;
  c.source = left_yaml + " + " + right_yaml;
  return c;
}

Result<StereoCalibration> ReadKalibrCamchain(const std::string& path) {
  Result<YAML::Node> root = LoadYaml(path);
  if (!root.ok()) return root.status();
  StereoCalibration c;
  c.source = path;
  cv::Size sizes[2];
  for (int i = 0; i < 2; ++i) {
    const std::string cam = "cam" + std::to_string(i);
    const YAML::Node node = (*root)[cam];
    if (!node.IsDefined() || !node.IsMap()) {
      return Status::Error(path + ": missing key '" + cam + "' (a Kalibr camchain has cam0, cam1)");
    }
    const YAML::Node model_node = node["camera_model"];
    if (model_node.IsDefined()) {
      const std::string model = model_node.IsScalar() ? model_node.as<std::string>() : "";
      if (model != "pinhole") {
        return Status::Error(path + ": key '" + cam + ".camera_model' value " + Show(model_node) +
                             " is not supported (pinhole)");
      }
    }
    Result<std::vector<double>> in = GetList(path, cam + ".intrinsics", node["intrinsics"], {4});
    if (!in.ok()) return in.status();
    cv::Matx33d K((*in)[0], 0, (*in)[2], 0, (*in)[1], (*in)[3], 0, 0, 1);
    if (Status s = CheckIntrinsics(path, cam + ".intrinsics", K); !s.ok()) return s;
    cv::Mat D;
    const YAML::Node dm = node["distortion_model"];
    const std::string dist_model = dm.IsDefined() && dm.IsScalar() ? dm.as<std::string>() : "";
    if (dist_model == "radtan") {
      Result<std::vector<double>> d =
          GetList(path, cam + ".distortion_coeffs", node["distortion_coeffs"], {4});
      if (!d.ok()) return d.status();
      D = cv::Mat(1, 4, CV_64F, d->data()).clone();
    } else if (dm.IsDefined() && dist_model != "none") {
      return Status::Error(path + ": key '" + cam + ".distortion_model' value " + Show(dm) +
                           " is not supported (radtan, none)");
    }
    Result<std::vector<double>> res = GetList(path, cam + ".resolution", node["resolution"], {2});
    if (!res.ok()) return res.status();
    const auto pixels = [](double v) { return v >= 1 && v <= 1e6 && v == std::floor(v); };
    if (!pixels((*res)[0]) || !pixels((*res)[1])) {
      return Status::Error(path + ": key '" + cam + ".resolution' value " +
                           Show(node["resolution"]) +
                           " is not [width, height] in whole pixels (1 to 1000000)");
    }
    sizes[i] = cv::Size(static_cast<int>((*res)[0]), static_cast<int>((*res)[1]));
    if (i == 0) {
      c.K1 = K;
      c.D1 = D;
    } else {
      c.K2 = K;
      c.D2 = D;
      const YAML::Node t = node["T_cn_cnm1"];
      const std::string key = cam + ".T_cn_cnm1";
      if (!t.IsDefined()) return Status::Error(path + ": missing key '" + key + "'");
      if (!t.IsSequence() || t.size() != 4) {
        return Status::Error(path + ": key '" + key + "' value " + Show(t) +
                             " is not a 4x4 matrix (4 rows of 4)");
      }
      cv::Matx44d M;
      for (int r = 0; r < 4; ++r) {
        Result<std::vector<double>> row =
            GetList(path, key + "[" + std::to_string(r) + "]", t[r], {4});
        if (!row.ok()) return row.status();
        for (int col = 0; col < 4; ++col) M(r, col) = (*row)[col];
      }
      if (M(3, 0) != 0 || M(3, 1) != 0 || M(3, 2) != 0 || M(3, 3) != 1) {
        return Status::Error(path + ": key '" + key + "' last row is not [0, 0, 0, 1]");
      }
      c.R = M.get_minor<3, 3>(0, 0);
      c.T = cv::Vec3d(M(0, 3), M(1, 3), M(2, 3));
      if (Status s = CheckRotation(path, key, c.R); !s.ok()) return s;
    }
  }
  if (sizes[0] != sizes[1]) {
    return Status::Error(path +
                         ": key 'cam1.resolution' differs from 'cam0.resolution'; both "
                         "cameras must have the same image size");
  }
  c.image_size = sizes[0];
  return c;
}

Result<StereoCalibration> ReadOpenCvCalibration(const std::vector<std::string>& paths) {
  if (paths.empty() || paths.size() > 2) {
    return Status::Error("OpenCV calibration: give one or two FileStorage files, not " +
                         std::to_string(paths.size()));
  }
  std::vector<FsFile> files;
  for (const std::string& p : paths) {
    Result<FsFile> f = LoadOpenCvYaml(p);
    if (!f.ok()) return f.status();
    files.push_back(std::move(*f));
  }
  StereoCalibration c;
  for (const std::string& p : paths) c.source += (c.source.empty() ? "" : " + ") + p;
  Result<cv::Matx33d> k1 = FsIntrinsics(files, "K1", "M1");
  if (!k1.ok()) return k1.status();
  Result<cv::Matx33d> k2 = FsIntrinsics(files, "K2", "M2");
  if (!k2.ok()) return k2.status();
  Result<cv::Mat> d1 = FsDistortion(files, "D1");
  if (!d1.ok()) return d1.status();
  Result<cv::Mat> d2 = FsDistortion(files, "D2");
  if (!d2.ok()) return d2.status();
  std::string file, key;
  Result<cv::Mat> r = FsMatrix(files, {"R"}, true, &file, &key);
  if (!r.ok()) return r.status();
  if (r->rows == 3 && r->cols == 3) {
    for (int i = 0; i < 9; ++i) c.R.val[i] = r->at<double>(i);
  } else if (r->total() == 3 && (r->rows == 1 || r->cols == 1)) {
    cv::Mat rot;
    cv::Rodrigues(r->reshape(1, 3), rot);
    for (int i = 0; i < 9; ++i) c.R.val[i] = rot.at<double>(i);
  } else {
    return Status::Error(file + ": key 'R' is " + Shape(*r) +
                         ", expected 3x3 (matrix) or 3x1 (Rodrigues vector)");
  }
  if (Status s = CheckRotation(file, "R", c.R); !s.ok()) return s;
  Result<cv::Mat> t = FsMatrix(files, {"T"}, true, &file, &key);
  if (!t.ok()) return t.status();
  if (t->total() != 3 || (t->rows != 1 && t->cols != 1)) {
    return Status::Error(file + ": key 'T' is " + Shape(*t) + ", expected 3x1 or 1x3");
  }
  c.T = cv::Vec3d(t->at<double>(0), t->at<double>(1), t->at<double>(2));
  if (cv::norm(c.T) == 0) {
    return Status::Error(file + ": key 'T' is [0, 0, 0]; a stereo pair needs a baseline");
  }
  Result<cv::Size> size = FsImageSize(files);
  if (!size.ok()) return size.status();
  c.image_size = *size;
  c.K1 = *k1;
  c.K2 = *k2;
  c.D1 = *d1;
  c.D2 = *d2;
  return c;
}

Result<StereoCalibration> ReadStereoCalibration(const std::vector<std::string>& paths) {
  if (paths.empty()) return Status::Error("no calibration file given");
  auto top_level_has = [](const std::string& path, const char* key) {
    Result<std::string> text = ReadCalibrationText(path);
    if (!text.ok()) return false;  // the chosen reader reports it
    try {
      const YAML::Node root = YAML::Load(*text);
      return root.IsMap() && root[key].IsDefined();
    } catch (const YAML::Exception&) {
      return false;  // XML, or OpenCV's "%YAML:1.0" header that yaml-cpp rejects
    }
  };
  for (const std::string& p : paths) {
    if (Status s = CheckReadable(p); !s.ok()) return s;
  }
  if (paths.size() == 2 && top_level_has(paths[0], "camera_matrix") &&
      top_level_has(paths[1], "camera_matrix")) {
    return ReadRosCameraInfoPair(paths[0], paths[1]);
  }
  if (paths.size() == 1 && top_level_has(paths[0], "cam0")) return ReadKalibrCamchain(paths[0]);
  return ReadOpenCvCalibration(paths);
}

}  // namespace sfrt::camera
