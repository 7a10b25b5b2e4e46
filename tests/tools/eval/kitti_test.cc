// eval/kitti.h: the KITTI Scene Flow 2015 files (encode, decode, round trip within the
// encodings' quantisation), the devkit's filling of missing estimates, the projection of a 3D
// flow, and the outlier counts on hand-worked cases.
#include "eval/kitti.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <vector>

namespace sfrt::eval {
namespace {

std::string TempPath(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "sfrt_kitti_test";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

TEST(KittiFiles, DisparityRoundTripsWithin1Over256AndKeepsMissingValues) {
  cv::Mat d(5, 7, CV_32F);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0.1f, 250.0f);
  for (int y = 0; y < d.rows; ++y) {
    for (int x = 0; x < d.cols; ++x) d.at<float>(y, x) = u(rng);
  }
  d.at<float>(2, 3) = kNoDisparity;
  d.at<float>(0, 0) = 0.001f;  // below 1/256: written as 1 (still a value), as the devkit does
  const std::string path = TempPath("disp.png");
  ASSERT_TRUE(WriteKittiDisparity(path, d).ok());
  Result<cv::Mat> back = ReadKittiDisparity(path);
  ASSERT_TRUE(back.ok()) << back.message();
  for (int y = 0; y < d.rows; ++y) {
    for (int x = 0; x < d.cols; ++x) {
      const float want = d.at<float>(y, x);
      const float got = back->at<float>(y, x);
      if (want == kNoDisparity) {
        EXPECT_EQ(got, kNoDisparity);
      } else if (want < 1.0f / 256) {
        EXPECT_EQ(got, 1.0f / 256);
      } else {
        EXPECT_LE(want - got, 1.0f / 256) << y << "," << x;
        EXPECT_GE(want - got, 0.0f);  // truncated
      }
    }
  }
}

TEST(KittiFiles, FlowRoundTripsWithin1Over64AndReadsBlueAsValid) {
  cv::Mat f(4, 6, CV_32FC3);
  for (int y = 0; y < f.rows; ++y) {
    for (int x = 0; x < f.cols; ++x) f.at<cv::Vec3f>(y, x) = {x * 13.37f - 40, y * -7.1f, 1};
  }
  f.at<cv::Vec3f>(1, 1)[2] = 0;
  const std::string path = TempPath("flow.png");
  ASSERT_TRUE(WriteKittiFlow(path, f).ok());
  Result<cv::Mat> back = ReadKittiFlow(path);
  ASSERT_TRUE(back.ok()) << back.message();
  for (int y = 0; y < f.rows; ++y) {
    for (int x = 0; x < f.cols; ++x) {
      const cv::Vec3f want = f.at<cv::Vec3f>(y, x);
      const cv::Vec3f got = back->at<cv::Vec3f>(y, x);
      EXPECT_EQ(got[2], want[2]);
      if (want[2] == 0) continue;
      EXPECT_NEAR(got[0], want[0], 1.0 / 64);
      EXPECT_NEAR(got[1], want[1], 1.0 / 64);
    }
  }
  // The raw PNG: R holds u, G holds v (OpenCV's BGR order: index 2 and 1), B the flag.
  cv::Mat raw(1, 1, CV_16UC3, cv::Scalar(1, 32768 + 64 * 2, 32768 - 64 * 3));
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(cv::imencode(".png", raw, bytes));
  cv::Mat decoded = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
  ASSERT_TRUE(cv::imwrite(path, decoded));
  Result<cv::Mat> one = ReadKittiFlow(path);
  ASSERT_TRUE(one.ok());
  EXPECT_EQ(one->at<cv::Vec3f>(0, 0), cv::Vec3f(-3, 2, 1));
}

// What sfrt eval scores is what the devkit reads from the written submission, value for value.
TEST(KittiFiles, AsSubmittedIsExactlyWhatTheWrittenSubmissionReadsBackAs) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> disparity(-2.0f, 300.0f);
  std::uniform_real_distribution<float> motion(-600.0f, 600.0f);
  KittiEstimate e{cv::Mat(9, 11, CV_32F), cv::Mat(9, 11, CV_32F), cv::Mat(9, 11, CV_32FC3)};
  for (int y = 0; y < 9; ++y) {
    for (int x = 0; x < 11; ++x) {
      e.disparity0.at<float>(y, x) = disparity(rng);
      e.disparity1.at<float>(y, x) = disparity(rng);
      e.flow.at<cv::Vec3f>(y, x) = {motion(rng), motion(rng), (x + y) % 5 == 0 ? 0.0f : 1.0f};
    }
  }
  e.disparity0.at<float>(0, 0) = kNoDisparity;
  e.disparity0.at<float>(0, 1) = 0.001f;                     // below 1/256: kept as 1/256
  e.disparity1.at<float>(0, 0) = 1000.0f;                    // beyond the 16-bit range: clamped
  e.flow.at<cv::Vec3f>(0, 0) = {std::nanf(""), 1.0f, 1.0f};  // not finite: no value
  const KittiEstimate scored = AsSubmitted(e);
  const std::string d0 = TempPath("as_submitted_d0.png");
  const std::string d1 = TempPath("as_submitted_d1.png");
  const std::string flow = TempPath("as_submitted_flow.png");
  ASSERT_TRUE(WriteKittiDisparity(d0, e.disparity0).ok());
  ASSERT_TRUE(WriteKittiDisparity(d1, e.disparity1).ok());
  ASSERT_TRUE(WriteKittiFlow(flow, e.flow).ok());
  Result<cv::Mat> back_d0 = ReadKittiDisparity(d0);
  Result<cv::Mat> back_d1 = ReadKittiDisparity(d1);
  Result<cv::Mat> back_flow = ReadKittiFlow(flow);
  ASSERT_TRUE(back_d0.ok() && back_d1.ok() && back_flow.ok());
  EXPECT_EQ(cv::norm(scored.disparity0, *back_d0, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(scored.disparity1, *back_d1, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(scored.flow, *back_flow, cv::NORM_INF), 0.0);
  EXPECT_EQ(scored.disparity0.at<float>(0, 1), 1.0f / 256);
  EXPECT_EQ(scored.disparity1.at<float>(0, 0), 65535.0f / 256);
  EXPECT_EQ(scored.flow.at<cv::Vec3f>(0, 0)[2], 0.0f);
  EXPECT_EQ(e.disparity0.at<float>(0, 1), 0.001f);  // the estimate itself is left as it was
}

TEST(KittiFiles, CalibrationGivesFocalCentreAndBaselineAndNamesMissingKeys) {
  const std::string path = TempPath("calib.txt");
  {
    std::ofstream o(path);
    o << "calib_time: 09-Jan-2012 13:57:47\n"
      << "P_rect_02: 7.215377e+02 0.000000e+00 6.095593e+02 4.485728e+01 0.000000e+00 "
         "7.215377e+02 1.728540e+02 2.163791e-01 0.000000e+00 0.000000e+00 1.000000e+00 "
         "2.745884e-03\n"
      << "P_rect_03: 7.215377e+02 0.000000e+00 6.095593e+02 -3.395242e+02 0.000000e+00 "
         "7.215377e+02 1.728540e+02 2.199936e+00 0.000000e+00 0.000000e+00 1.000000e+00 "
         "2.729905e-03\n";
  }
  Result<PinholeStereo> c = ReadKittiCalibration(path);
  ASSERT_TRUE(c.ok()) << c.message();
  EXPECT_DOUBLE_EQ(c->focal, 721.5377);
  EXPECT_DOUBLE_EQ(c->cx, 609.5593);
  EXPECT_DOUBLE_EQ(c->cy, 172.854);
  EXPECT_NEAR(c->baseline, 0.5327, 1e-4);
  const std::string round = TempPath("calib2.txt");
  ASSERT_TRUE(WriteKittiCalibration(round, *c).ok());
  Result<PinholeStereo> again = ReadKittiCalibration(round);
  ASSERT_TRUE(again.ok());
  EXPECT_NEAR(again->baseline, c->baseline, 1e-9);
  {
    std::ofstream o(path);
    o << "P_rect_02: 1 0 0 0 0 1 0 0 0 0 1 0\n";
  }
  Result<PinholeStereo> missing = ReadKittiCalibration(path);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find("no P_rect_03 line"), std::string::npos) << missing.message();
}

TEST(KittiFill, GapsTakeTheSmallerNeighbourAndEndsTheNearestValue) {
  const float n = kNoDisparity;
  cv::Mat d = (cv::Mat_<float>(3, 7) << n, 5, n, n, 9, n, n,  //
               n, n, n, n, n, n, n,                           //
               2, n, 4, n, n, 1, n);
  InterpolateDisparity(&d);
  const cv::Mat want = (cv::Mat_<float>(3, 7) << 5, 5, 5, 5, 9, 9, 9,  //
                        n, n, n, n, n, n, n,  // an empty row between two: the devkit leaves it
                        2, 2, 4, 1, 1, 1, 1);
  EXPECT_EQ(cv::countNonZero(d != want), 0) << d;
  // Columns: the ends take the nearest value; flow u and v each.
  cv::Mat top = (cv::Mat_<float>(3, 2) << n, n, 3, n, n, n);
  InterpolateDisparity(&top);
  EXPECT_EQ(cv::countNonZero(top != 3), 0) << top;
  cv::Mat f(1, 4, CV_32FC3, cv::Scalar(0, 0, 0));
  f.at<cv::Vec3f>(0, 0) = {4, -1, 1};
  f.at<cv::Vec3f>(0, 3) = {2, 5, 1};
  InterpolateFlow(&f);
  EXPECT_EQ(f.at<cv::Vec3f>(0, 1), cv::Vec3f(2, -1, 1));
  EXPECT_EQ(f.at<cv::Vec3f>(0, 2), cv::Vec3f(2, -1, 1));
}

TEST(KittiProjection, TheGroundTruthsOwnSceneFlowProjectsBackOntoIt) {
  PinholeStereo c{721.5, 0.54, 30.5, 10.2};
  cv::Mat d0(20, 60, CV_32F), d1(20, 60, CV_32F), flow(20, 60, CV_32FC3);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> disp(5, 80), move(-20, 20), change(-3, 3);
  for (int y = 0; y < 20; ++y) {
    for (int x = 0; x < 60; ++x) {
      d0.at<float>(y, x) = disp(rng);
      d1.at<float>(y, x) = d0.at<float>(y, x) + change(rng);
      flow.at<cv::Vec3f>(y, x) = {move(rng), move(rng), 1};
    }
  }
  const std::vector<float> sf = KittiGroundTruthSceneFlow(d0, d1, flow, c);
  const KittiEstimate e = ProjectSceneFlow(d0, sf.data(), c);
  for (int y = 0; y < 20; ++y) {
    for (int x = 0; x < 60; ++x) {
      EXPECT_NEAR(e.disparity1.at<float>(y, x), d1.at<float>(y, x), 1e-3);
      EXPECT_NEAR(e.flow.at<cv::Vec3f>(y, x)[0], flow.at<cv::Vec3f>(y, x)[0], 1e-3);
      EXPECT_NEAR(e.flow.at<cv::Vec3f>(y, x)[1], flow.at<cv::Vec3f>(y, x)[1], 1e-3);
    }
  }
}

TEST(KittiCounts, GroundTruthAsEstimateHasNoOutliersAndAKnownPerturbationItsKnownCount) {
  // 4 x 5 scene; the right two columns are an object (foreground); (3, 0) has no disparity at
  // t+1 (so no SF there either).
  cv::Mat d0(4, 5, CV_32F, cv::Scalar(40)), d1(4, 5, CV_32F, cv::Scalar(38));
  cv::Mat flow(4, 5, CV_32FC3, cv::Scalar(10, -2, 1)), obj(4, 5, CV_8U, cv::Scalar(0));
  obj.colRange(3, 5).setTo(1);
  d1.at<float>(3, 0) = kNoDisparity;
  KittiEstimate truth{d0.clone(), d1.clone(), flow.clone()};
  KittiCounts exact;
  exact.Add(d0, d1, flow, obj, truth);
  for (KittiMap m : {KittiMap::kD1, KittiMap::kD2, KittiMap::kFl, KittiMap::kSf}) {
    EXPECT_EQ(exact.PercentAll(m), 0.0);
  }
  EXPECT_EQ(exact.pixels(KittiMap::kD1, KittiRegion::kBackground), 12u);
  EXPECT_EQ(exact.pixels(KittiMap::kD2, KittiRegion::kBackground), 11u);
  EXPECT_EQ(exact.pixels(KittiMap::kSf, KittiRegion::kForeground), 8u);
  // Perturb: disparity at t off by 2.5 px (not an outlier: under 3 px) at (0,0); by 4 px (10%:
  // an outlier) at (1,1) and (2,4); the flow off by 3.5 px at (0,4) (3.5 / |(10,-2)| = 34%: an
  // outlier) and by 3.5 px at (3,0), where the SF has no pixel.
  KittiEstimate e{d0.clone(), d1.clone(), flow.clone()};
  e.disparity0.at<float>(0, 0) += 2.5f;
  e.disparity0.at<float>(1, 1) += 4.0f;
  e.disparity0.at<float>(2, 4) -= 4.0f;
  e.flow.at<cv::Vec3f>(0, 4)[0] += 3.5f;
  e.flow.at<cv::Vec3f>(3, 0)[1] += 3.5f;
  KittiCounts c;
  c.Add(d0, d1, flow, obj, e);
  EXPECT_EQ(c.outliers(KittiMap::kD1, KittiRegion::kBackground), 1u);
  EXPECT_EQ(c.outliers(KittiMap::kD1, KittiRegion::kForeground), 1u);
  EXPECT_DOUBLE_EQ(c.PercentAll(KittiMap::kD1), 100.0 * 2 / 20);
  EXPECT_EQ(c.outliers(KittiMap::kFl, KittiRegion::kForeground), 1u);
  EXPECT_EQ(c.outliers(KittiMap::kFl, KittiRegion::kBackground), 1u);
  EXPECT_EQ(c.outliers(KittiMap::kSf, KittiRegion::kBackground), 1u);  // (1,1); not (3,0)
  EXPECT_EQ(c.outliers(KittiMap::kSf, KittiRegion::kForeground), 2u);  // (2,4) and (0,4)
  EXPECT_DOUBLE_EQ(c.Percent(KittiMap::kSf, KittiRegion::kForeground), 100.0 * 2 / 8);
  EXPECT_DOUBLE_EQ(c.PercentAll(KittiMap::kSf), 100.0 * 3 / 19);
  KittiCounts merged = exact;
  merged.Merge(c);
  EXPECT_EQ(merged.pixels(KittiMap::kSf, KittiRegion::kBackground), 22u);
  EXPECT_EQ(merged.outliers(KittiMap::kSf, KittiRegion::kBackground), 1u);
}

}  // namespace
}  // namespace sfrt::eval
