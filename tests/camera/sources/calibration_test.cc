// Calibration readers: each format written by the test, read back, compared with the known
// geometry; wrong keys and values give errors naming file, key and value.
#include "sfrt/camera/calibration.h"

#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/calib3d.hpp>
#include <sstream>
#include <string>

#include "camera/sources/test_util.h"

namespace sfrt::camera {
namespace {

using testing::TempDir;
using testing::WriteText;

// The known stereo rig every format encodes: 640x480, slightly different intrinsics, a small
// rotation and a 0.12 m baseline (right camera to the right of the left one).
struct Rig {
  cv::Size size{640, 480};
  cv::Matx33d K1{500, 0, 320.5, 0, 505, 240.25, 0, 0, 1};
  cv::Matx33d K2{510, 0, 318, 0, 512, 242, 0, 0, 1};
  cv::Mat D1 = (cv::Mat_<double>(1, 5) << -0.1, 0.02, 0.001, -0.002, 0.0);
  cv::Mat D2 = (cv::Mat_<double>(1, 5) << -0.12, 0.03, -0.001, 0.001, 0.0);
  cv::Matx33d R;
  cv::Vec3d T{-0.12, 0.002, 0.001};
  Rig() {
    cv::Mat rot;
    cv::Rodrigues(cv::Vec3d(0.01, -0.02, 0.005), rot);
    R = cv::Matx33d(reinterpret_cast<const double*>(rot.data));
  }
};

std::string List(const double* v, int n) {
  std::ostringstream s;
  s.precision(17);
  s << "[";
  for (int i = 0; i < n; ++i) s << (i ? ", " : "") << v[i];
  s << "]";
  return s.str();
}

std::string RosYaml(const Rig& rig, const cv::Matx33d& K, const cv::Mat& D, const cv::Mat& R,
                    const cv::Mat& P, const std::string& name) {
  std::ostringstream s;
  s << "image_width: " << rig.size.width << "\nimage_height: " << rig.size.height
    << "\ncamera_name: " << name
    << "\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: " << List(K.val, 9)
    << "\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n"
    << "  cols: 5\n  data: " << List(D.ptr<double>(), 5)
    << "\nrectification_matrix:\n  rows: 3\n  cols: 3\n  data: " << List(R.ptr<double>(), 9)
    << "\nprojection_matrix:\n  rows: 3\n  cols: 4\n  data: " << List(P.ptr<double>(), 12) << "\n";
  return s.str();
}

void ExpectRig(const StereoCalibration& c, const Rig& rig, double tol) {
  EXPECT_EQ(c.image_size, rig.size);
  EXPECT_LT(cv::norm(c.K1 - rig.K1, cv::NORM_INF), 1e-9);
  EXPECT_LT(cv::norm(c.K2 - rig.K2, cv::NORM_INF), 1e-9);
  EXPECT_LT(cv::norm(c.R - rig.R, cv::NORM_INF), tol) << cv::Mat(c.R);
  EXPECT_LT(cv::norm(c.T - rig.T, cv::NORM_INF), tol) << cv::Mat(c.T);
}

// ROS stores the rectification OpenCV computes; write it from stereoRectify and read R, T back.
TEST(RosCameraInfo, PairRecoversRotationAndTranslation) {
  TempDir tmp;
  Rig rig;
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(rig.K1, rig.D1, rig.K2, rig.D2, rig.size, rig.R, rig.T, R1, R2, P1, P2, Q,
                    cv::CALIB_ZERO_DISPARITY, 0);
  WriteText(tmp / "left.yaml", RosYaml(rig, rig.K1, rig.D1, R1, P1, "left"));
  WriteText(tmp / "right.yaml", RosYaml(rig, rig.K2, rig.D2, R2, P2, "right"));
  Result<StereoCalibration> c = ReadRosCameraInfoPair(tmp / "left.yaml", tmp / "right.yaml");
  ASSERT_TRUE(c.ok()) << c.message();
  ExpectRig(*c, rig, 1e-9);
  EXPECT_LT(cv::norm(c->D1 - rig.D1, cv::NORM_INF), 1e-12);
  Result<StereoCalibration> detected =
      ReadStereoCalibration({tmp / "left.yaml", tmp / "right.yaml"});
  ASSERT_TRUE(detected.ok()) << detected.message();
  ExpectRig(*detected, rig, 1e-9);
}

TEST(RosCameraInfo, ErrorsNameFileKeyAndValue) {
  TempDir tmp;
  Rig rig;
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(rig.K1, rig.D1, rig.K2, rig.D2, rig.size, rig.R, rig.T, R1, R2, P1, P2, Q,
                    cv::CALIB_ZERO_DISPARITY, 0);
  const std::string left = RosYaml(rig, rig.K1, rig.D1, R1, P1, "left");
  const std::string right = RosYaml(rig, rig.K2, rig.D2, R2, P2, "right");
  WriteText(tmp / "right.yaml", right);

  struct Case {
    std::string from, to;      // edit applied to the left file
    std::string must_contain;  // in the error
  };
  const Case cases[] = {
      {"camera_matrix:", "camera_matrx:", "key 'camera_matrix'"},
      {"plumb_bob", "equidistant", "'equidistant'"},
      {"image_width: 640", "image_width: wide", "'wide'"},
      {"  rows: 3\n  cols: 4", "  rows: 3\n  cols: 3", "key 'projection_matrix.cols' value 3"},
  };
  for (const Case& c : cases) {
    std::string text = left;
    const size_t at = text.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    text.replace(at, c.from.size(), c.to);
    WriteText(tmp / "left.yaml", text);
    Result<StereoCalibration> r = ReadRosCameraInfoPair(tmp / "left.yaml", tmp / "right.yaml");
    ASSERT_FALSE(r.ok()) << c.to;
    EXPECT_NE(r.message().find(tmp / "left.yaml"), std::string::npos) << r.message();
    EXPECT_NE(r.message().find(c.must_contain), std::string::npos) << r.message();
  }
  // Swapped files: the left one would carry the baseline.
  WriteText(tmp / "left.yaml", left);
  Result<StereoCalibration> swapped = ReadRosCameraInfoPair(tmp / "right.yaml", tmp / "left.yaml");
  ASSERT_FALSE(swapped.ok());
  EXPECT_NE(swapped.message().find("projection_matrix"), std::string::npos) << swapped.message();
}

std::string KalibrYaml(const Rig& rig, const std::string& cam1_dist_model = "radtan") {
  cv::Matx44d M = cv::Matx44d::eye();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) M(r, c) = rig.R(r, c);
    M(r, 3) = rig.T[r];
  }
  std::ostringstream s;
  s.precision(17);
  auto cam = [&](int i, const cv::Matx33d& K, const cv::Mat& D, const std::string& model) {
    s << "cam" << i << ":\n";
    if (i == 1) {
      s << "  T_cn_cnm1:\n";
      for (int r = 0; r < 4; ++r) s << "  - " << List(&M.val[4 * r], 4) << "\n";
    }
    s << "  camera_model: pinhole\n  distortion_coeffs: " << List(D.ptr<double>(), 4)
      << "\n  distortion_model: " << model << "\n  intrinsics: [" << K(0, 0) << ", " << K(1, 1)
      << ", " << K(0, 2) << ", " << K(1, 2) << "]\n  resolution: [" << rig.size.width << ", "
      << rig.size.height << "]\n  rostopic: /cam" << i << "/image_raw\n";
  };
  cam(0, rig.K1, rig.D1, "radtan");
  cam(1, rig.K2, rig.D2, cam1_dist_model);
  return s.str();
}

TEST(KalibrCamchain, ReadsBothCamerasAndExtrinsics) {
  TempDir tmp;
  Rig rig;
  WriteText(tmp / "camchain.yaml", KalibrYaml(rig));
  Result<StereoCalibration> c = ReadKalibrCamchain(tmp / "camchain.yaml");
  ASSERT_TRUE(c.ok()) << c.message();
  ExpectRig(*c, rig, 1e-12);
  ASSERT_EQ(c->D2.cols, 4);
  EXPECT_DOUBLE_EQ(c->D2.at<double>(0, 0), -0.12);
  Result<StereoCalibration> detected = ReadStereoCalibration({tmp / "camchain.yaml"});
  ASSERT_TRUE(detected.ok()) << detected.message();
  ExpectRig(*detected, rig, 1e-12);
}

TEST(KalibrCamchain, ErrorsNameFileKeyAndValue) {
  TempDir tmp;
  Rig rig;
  WriteText(tmp / "fisheye.yaml", KalibrYaml(rig, "equidistant"));
  Result<StereoCalibration> fisheye = ReadKalibrCamchain(tmp / "fisheye.yaml");
  ASSERT_FALSE(fisheye.ok());
  EXPECT_NE(fisheye.message().find(tmp / "fisheye.yaml"), std::string::npos);
  EXPECT_NE(fisheye.message().find("cam1.distortion_model"), std::string::npos)
      << fisheye.message();
  EXPECT_NE(fisheye.message().find("equidistant"), std::string::npos) << fisheye.message();

  std::string text = KalibrYaml(rig);
  text.replace(text.find("T_cn_cnm1"), 9, "T_cam_imu");
  WriteText(tmp / "noext.yaml", text);
  Result<StereoCalibration> noext = ReadKalibrCamchain(tmp / "noext.yaml");
  ASSERT_FALSE(noext.ok());
  EXPECT_NE(noext.message().find("missing key 'cam1.T_cn_cnm1'"), std::string::npos)
      << noext.message();

  text = KalibrYaml(rig);
  text.replace(text.find("intrinsics: [500"), 16, "intrinsics: [abc");
  WriteText(tmp / "nan.yaml", text);
  Result<StereoCalibration> nan = ReadKalibrCamchain(tmp / "nan.yaml");
  ASSERT_FALSE(nan.ok());
  EXPECT_NE(nan.message().find("cam0.intrinsics[0]"), std::string::npos) << nan.message();
  EXPECT_NE(nan.message().find("'abc'"), std::string::npos) << nan.message();

  // fuzz_calibration (UBSan: 4.4e89 converted to int): a resolution past any camera's, or not a
  // whole number, is refused naming the key.
  for (const char* bad : {"[640, 4444444444444444444444448]", "[640.5, 480]"}) {
    text = KalibrYaml(rig);
    const size_t at = text.rfind("resolution: [");
    text.replace(at, text.find('\n', at) - at, std::string("resolution: ") + bad);
    WriteText(tmp / "res.yaml", text);
    Result<StereoCalibration> res = ReadKalibrCamchain(tmp / "res.yaml");
    ASSERT_FALSE(res.ok()) << bad;
    EXPECT_NE(res.message().find("key 'cam1.resolution' value"), std::string::npos)
        << res.message();
    EXPECT_NE(res.message().find("is not [width, height] in whole pixels (1 to 1000000)"),
              std::string::npos)
        << res.message();
  }
}

void WriteOpenCv(const std::string& path, const Rig& rig, bool m_names, bool with_size) {
  cv::FileStorage fs(path, cv::FileStorage::WRITE);
  ASSERT_TRUE(fs.isOpened()) << path;
  fs << (m_names ? "M1" : "K1") << cv::Mat(rig.K1) << "D1" << rig.D1;
  fs << (m_names ? "M2" : "K2") << cv::Mat(rig.K2) << "D2" << rig.D2;
  fs << "R" << cv::Mat(rig.R) << "T" << cv::Mat(rig.T);
  if (with_size) fs << "image_size" << std::vector<int>{rig.size.width, rig.size.height};
}

TEST(OpenCvCalibration, YamlWithKNamesOrMNames) {
  TempDir tmp;
  Rig rig;
  WriteOpenCv(tmp / "stereo.yml", rig, /*m_names=*/false, /*with_size=*/true);
  WriteOpenCv(tmp / "stereo_m.yaml", rig, /*m_names=*/true, /*with_size=*/true);
  for (const std::string& path : {tmp / "stereo.yml", tmp / "stereo_m.yaml"}) {
    Result<StereoCalibration> c = ReadOpenCvCalibration({path});
    ASSERT_TRUE(c.ok()) << c.message();
    ExpectRig(*c, rig, 1e-12);
    Result<StereoCalibration> detected = ReadStereoCalibration({path});
    ASSERT_TRUE(detected.ok()) << detected.message();
    ExpectRig(*detected, rig, 1e-12);
  }
}

// OpenCV's XML parser crashes on damaged files (fuzz_calibration), so XML is refused by name,
// valid or not, before any parser sees it.
TEST(OpenCvCalibration, XmlIsRefusedWithAConversionHint) {
  TempDir tmp;
  Rig rig;
  WriteOpenCv(tmp / "stereo.xml", rig, /*m_names=*/true, /*with_size=*/true);
  {
    std::ofstream damaged(tmp / "damaged.xml", std::ios::binary);
    damaged << "<?xml ion=";  // crashed cv::FileStorage::open in OpenCV 4.6
  }
  for (const std::string& path : {tmp / "stereo.xml", tmp / "damaged.xml"}) {
    for (bool detect : {false, true}) {
      Result<StereoCalibration> r =
          detect ? ReadStereoCalibration({path}) : ReadOpenCvCalibration({path});
      ASSERT_FALSE(r.ok()) << path;
      EXPECT_NE(r.message().find(path + ": OpenCV XML calibration files are not read"),
                std::string::npos)
          << r.message();
      EXPECT_NE(r.message().find("save it as OpenCV YAML"), std::string::npos) << r.message();
    }
  }
}

TEST(OpenCvCalibration, IntrinsicsAndExtrinsicsInTwoFilesWithRodrigues) {
  TempDir tmp;
  Rig rig;
  {
    cv::FileStorage fs(tmp / "intrinsics.yml", cv::FileStorage::WRITE);
    fs << "M1" << cv::Mat(rig.K1) << "D1" << rig.D1 << "M2" << cv::Mat(rig.K2) << "D2" << rig.D2;
  }
  {
    cv::Mat rvec;
    cv::Rodrigues(cv::Mat(rig.R), rvec);
    cv::FileStorage fs(tmp / "extrinsics.yml", cv::FileStorage::WRITE);
    fs << "R" << rvec << "T" << cv::Mat(rig.T);
  }
  Result<StereoCalibration> c =
      ReadOpenCvCalibration({tmp / "intrinsics.yml", tmp / "extrinsics.yml"});
  ASSERT_TRUE(c.ok()) << c.message();
  EXPECT_EQ(c->image_size, cv::Size());  // not in these files
  EXPECT_LT(cv::norm(c->R - rig.R, cv::NORM_INF), 1e-12);
  EXPECT_LT(cv::norm(c->T - rig.T, cv::NORM_INF), 1e-15);
}

TEST(OpenCvCalibration, ErrorsNameFileKeyAndValue) {
  TempDir tmp;
  Rig rig;
  {
    cv::FileStorage fs(tmp / "nok.yml", cv::FileStorage::WRITE);
    fs << "Kleft" << cv::Mat(rig.K1) << "D1" << rig.D1 << "K2" << cv::Mat(rig.K2) << "D2" << rig.D2
       << "R" << cv::Mat(rig.R) << "T" << cv::Mat(rig.T);
  }
  Result<StereoCalibration> nok = ReadOpenCvCalibration({tmp / "nok.yml"});
  ASSERT_FALSE(nok.ok());
  EXPECT_NE(nok.message().find(tmp / "nok.yml"), std::string::npos) << nok.message();
  EXPECT_NE(nok.message().find("missing key 'K1' or 'M1'"), std::string::npos) << nok.message();

  {
    cv::FileStorage fs(tmp / "badt.yml", cv::FileStorage::WRITE);
    fs << "K1" << cv::Mat(rig.K1) << "D1" << rig.D1 << "K2" << cv::Mat(rig.K2) << "D2" << rig.D2
       << "R" << cv::Mat(rig.R) << "T" << (cv::Mat_<double>(2, 1) << 0.1, 0.2);
  }
  Result<StereoCalibration> badt = ReadOpenCvCalibration({tmp / "badt.yml"});
  ASSERT_FALSE(badt.ok());
  EXPECT_NE(badt.message().find("key 'T' is 2x1"), std::string::npos) << badt.message();

  {
    cv::FileStorage fs(tmp / "badr.yml", cv::FileStorage::WRITE);
    fs << "K1" << cv::Mat(rig.K1) << "D1" << rig.D1 << "K2" << cv::Mat(rig.K2) << "D2" << rig.D2
       << "R" << cv::Mat(2 * rig.R) << "T" << cv::Mat(rig.T);
  }
  Result<StereoCalibration> badr = ReadOpenCvCalibration({tmp / "badr.yml"});
  ASSERT_FALSE(badr.ok());
  EXPECT_NE(badr.message().find("key 'R' is not a rotation"), std::string::npos) << badr.message();

  WriteOpenCv(tmp / "a.yml", rig, false, false);
  WriteOpenCv(tmp / "b.yml", rig, true, false);
  Result<StereoCalibration> twice = ReadOpenCvCalibration({tmp / "a.yml", tmp / "b.yml"});
  ASSERT_FALSE(twice.ok());
  EXPECT_NE(twice.message().find("give it once"), std::string::npos) << twice.message();

  // Damage OpenCV's own reader would have allocated or decoded first: a huge matrix, channels,
  // a data count that does not match rows x cols, a file far larger than any calibration.
  const std::string header = "%YAML:1.0\n---\n";
  const std::string k1 = "K1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n";
  const struct {
    const char* name;
    std::string text;
    const char* must_contain;
  } damaged[] = {
      {"huge.yml",
       header + "K1: !!opencv-matrix\n   rows: 3\n   cols: 100000\n   dt: d\n"
                "   data: [ 1. ]\n",
       "key 'K1' is 3x100000; a calibration matrix is at most 64x64"},
      {"channels.yml",
       header + "K1: !!opencv-matrix\n   rows: 1\n   cols: 3\n   dt: 3d\n"
                "   data: [ 1., 2., 3., 4., 5., 6., 7., 8., 9. ]\n",
       "key 'K1' has 3 channels, expected 1"},
      {"count.yml", header + k1 + "   data: [ 1., 0., 2. ]\n",
       "key 'K1.data' has 3 values, expected 9"},
      {"big.yml", header + "# " + std::string(1 << 20, 'x') + "\n", "bytes; the limit is 1048576"},
  };
  for (const auto& d : damaged) {
    {
      std::ofstream f(tmp / d.name, std::ios::binary);
      f << d.text;
    }
    Result<StereoCalibration> r = ReadOpenCvCalibration({tmp / d.name});
    ASSERT_FALSE(r.ok()) << d.name;
    EXPECT_NE(r.message().find(tmp / d.name), std::string::npos) << r.message();
    EXPECT_NE(r.message().find(d.must_contain), std::string::npos) << r.message();
  }

  Result<StereoCalibration> missing = ReadStereoCalibration({tmp / "none.yml"});
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find(tmp / "none.yml"), std::string::npos) << missing.message();
}

}  // namespace
}  // namespace sfrt::camera
