// Rectification against analytic cases: an ideal rig (identity rotation, known baseline) must map
// to itself, and for a rotated, distorted rig a 3-D point's images must land on the same row
// after rectification, where the rectified projection says (at the output size).
#include "sfrt/camera/rectifier.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace sfrt::camera {
namespace {

const cv::Size kRaw(640, 480);

StereoCalibration IdealRig(double baseline) {
  StereoCalibration c;
  c.image_size = kRaw;
  c.K1 = cv::Matx33d(500, 0, 319.5, 0, 500, 239.5, 0, 0, 1);
  c.K2 = c.K1;
  c.T = cv::Vec3d(-baseline, 0, 0);
  c.source = "ideal rig";
  return c;
}

StereoCalibration RealisticRig() {
  StereoCalibration c;
  c.image_size = kRaw;
  c.K1 = cv::Matx33d(500, 0, 322, 0, 503, 236, 0, 0, 1);
  c.K2 = cv::Matx33d(508, 0, 315, 0, 506, 244, 0, 0, 1);
  c.D1 = (cv::Mat_<double>(1, 5) << -0.08, 0.015, 0.0005, -0.0007, 0.0);
  c.D2 = (cv::Mat_<double>(1, 5) << -0.06, 0.01, -0.0004, 0.0003, 0.0);
  cv::Mat rot;
  cv::Rodrigues(cv::Vec3d(0.012, -0.018, 0.006), rot);
  c.R = cv::Matx33d(reinterpret_cast<const double*>(rot.data));
  c.T = cv::Vec3d(-0.12, 0.003, -0.002);
  c.source = "realistic rig";
  return c;
}

// A smooth random-ish texture so identity remaps can be compared pixel by pixel.
cv::Mat Texture() {
  cv::Mat image(kRaw, CV_8UC3);
  for (int y = 0; y < kRaw.height; ++y) {
    for (int x = 0; x < kRaw.width; ++x) {
      image.at<cv::Vec3b>(y, x) =
          cv::Vec3b(static_cast<uint8_t>((x * 7 + y * 3) & 255),
                    static_cast<uint8_t>((x * y) & 255), static_cast<uint8_t>((x ^ y) & 255));
    }
  }
  return image;
}

TEST(StereoRectifier, IdealRigKeepsFocalBaselineAndPixels) {
  Result<StereoRectifier> r = StereoRectifier::Create(IdealRig(0.1), kRaw, {});
  ASSERT_TRUE(r.ok()) << r.message();
  const RectifiedCamera& cam = r->camera();
  EXPECT_EQ(cam.size, kRaw);
  EXPECT_NEAR(cam.fx, 500, 1e-6);
  EXPECT_NEAR(cam.fy, 500, 1e-6);
  EXPECT_NEAR(cam.cx, 319.5, 1e-6);
  EXPECT_NEAR(cam.cy, 239.5, 1e-6);
  EXPECT_NEAR(cam.baseline, 0.1, 1e-12);

  const cv::Mat texture = Texture();
  cv::Mat left, right;
  ASSERT_TRUE(r->Apply(texture, texture, &left, &right).ok());
  // The maps are the identity, so remapping reproduces every pixel (fixed-point maps: +-1).
  EXPECT_LE(cv::norm(left, texture, cv::NORM_INF), 1);
  EXPECT_LE(cv::norm(right, texture, cv::NORM_INF), 1);

  // Apply() reuses the caller's buffers once they have the output size.
  const uint8_t* before = left.data;
  ASSERT_TRUE(r->Apply(texture, texture, &left, &right).ok());
  EXPECT_EQ(left.data, before);
}

TEST(StereoRectifier, IdealRigScaledToModelSizeReportsScaledCamera) {
  RectifyOptions options;
  options.output_size = cv::Size(480, 360);  // 0.75
  Result<StereoRectifier> r = StereoRectifier::Create(IdealRig(0.25), kRaw, options);
  ASSERT_TRUE(r.ok()) << r.message();
  const RectifiedCamera& cam = r->camera();
  EXPECT_NEAR(cam.fx, 375, 1e-6);
  EXPECT_NEAR(cam.fy, 375, 1e-6);
  // Pixel centres: (319.5 + 0.5) * 0.75 - 0.5.
  EXPECT_NEAR(cam.cx, 239.5, 1e-6);
  EXPECT_NEAR(cam.cy, 179.5, 1e-6);
  EXPECT_NEAR(cam.baseline, 0.25, 1e-12);
}

// Renders a Gaussian blob (sigma in raw pixels) centred at pixel `at` into a black image.
cv::Mat Blob(cv::Point2d at, double sigma) {
  cv::Mat image(kRaw, CV_8UC3, cv::Scalar::all(0));
  for (int y = 0; y < kRaw.height; ++y) {
    for (int x = 0; x < kRaw.width; ++x) {
      const double d2 = (x - at.x) * (x - at.x) + (y - at.y) * (y - at.y);
      const double v = 255.0 * std::exp(-d2 / (2 * sigma * sigma));
      image.at<cv::Vec3b>(y, x) = cv::Vec3b::all(static_cast<uint8_t>(std::lround(v)));
    }
  }
  return image;
}

cv::Point2d Centroid(const cv::Mat& image) {
  double sum = 0, sx = 0, sy = 0;
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) {
      const double v = image.at<cv::Vec3b>(y, x)[1];
      if (v < 8) continue;  // ignore the faint tail the 8-bit rounding distorts
      sum += v;
      sx += v * x;
      sy += v * y;
    }
  }
  return sum > 0 ? cv::Point2d(sx / sum, sy / sum) : cv::Point2d(-1, -1);
}

cv::Point2d Project(const cv::Matx34d& P, const cv::Vec3d& X) {
  const cv::Vec3d p = P * cv::Vec4d(X[0], X[1], X[2], 1);
  return {p[0] / p[2], p[1] / p[2]};
}

struct ScaleCase {
  cv::Size output;
  double tolerance_px;  // in output pixels
};

TEST(StereoRectifier, PointLandsOnTheSameRowInBothViews) {
  const StereoCalibration calib = RealisticRig();
  // Identity at full size, one-pass scaled remap, and the two-stage (remap + INTER_AREA) path.
  // Measured worst errors: 0.014, 0.014 and 0.022 output px (blob centroids through 8-bit
  // rounding and 1/32 px fixed-point maps); a half-pixel-centre mistake in the scaling would be
  // 0.125 px or more.
  const ScaleCase cases[] = {{kRaw, 0.05}, {cv::Size(480, 360), 0.05}, {cv::Size(192, 144), 0.05}};
  const cv::Vec3d points[] = {{0.3, -0.2, 2.0}, {-0.5, 0.4, 3.0}, {0.05, 0.02, 1.5}};
  for (const ScaleCase& sc : cases) {
    RectifyOptions options;
    options.output_size = sc.output;
    Result<StereoRectifier> r = StereoRectifier::Create(calib, kRaw, options);
    ASSERT_TRUE(r.ok()) << r.message();
    EXPECT_NEAR(r->camera().baseline, cv::norm(calib.T), 1e-9);
    for (const cv::Vec3d& X : points) {
      // Raw images of the point through each camera's lens model.
      std::vector<cv::Point2d> left_raw, right_raw;
      cv::projectPoints(std::vector<cv::Point3d>{cv::Point3d(X)}, cv::Vec3d(0, 0, 0),
                        cv::Vec3d(0, 0, 0), cv::Mat(calib.K1), calib.D1, left_raw);
      cv::Mat rvec;
      cv::Rodrigues(cv::Mat(calib.R), rvec);
      cv::projectPoints(std::vector<cv::Point3d>{cv::Point3d(X)}, rvec, cv::Mat(calib.T),
                        cv::Mat(calib.K2), calib.D2, right_raw);
      cv::Mat left, right;
      ASSERT_TRUE(r->Apply(Blob(left_raw[0], 4.0), Blob(right_raw[0], 4.0), &left, &right).ok());
      const cv::Point2d got_left = Centroid(left);
      const cv::Point2d got_right = Centroid(right);
      // Where the rectified cameras see it: X in the rectified left frame, through P1 and P2.
      const cv::Vec3d X_rect = r->R1() * X;
      const cv::Point2d want_left = Project(r->P1(), X_rect);
      const cv::Point2d want_right = Project(r->P2(), X_rect);
      ASSERT_NEAR(want_left.y, want_right.y, 1e-9);  // rectification's own promise
      SCOPED_TRACE(testing::Message() << "output " << sc.output << " point " << X);
      EXPECT_NEAR(got_left.y, got_right.y, sc.tolerance_px);
      EXPECT_NEAR(got_left.y, want_left.y, sc.tolerance_px);
      EXPECT_NEAR(got_left.x, want_left.x, sc.tolerance_px);
      EXPECT_NEAR(got_right.x, want_right.x, sc.tolerance_px);
      // Disparity = f * B / Z.
      EXPECT_NEAR(got_left.x - got_right.x, r->camera().fx * r->camera().baseline / X_rect[2],
                  2 * sc.tolerance_px);
    }
  }
}

TEST(StereoRectifier, RejectsMismatchedSizesNamingThem) {
  Result<StereoRectifier> wrong = StereoRectifier::Create(IdealRig(0.1), cv::Size(1280, 720), {});
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.message().find("480x640"), std::string::npos) << wrong.message();
  EXPECT_NE(wrong.message().find("720x1280 (HxW)"), std::string::npos) << wrong.message();

  Result<StereoRectifier> r = StereoRectifier::Create(IdealRig(0.1), kRaw, {});
  ASSERT_TRUE(r.ok()) << r.message();
  cv::Mat small(100, 100, CV_8UC3, cv::Scalar::all(0)), left, right;
  Status s = r->Apply(small, Texture(), &left, &right);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("left image is 100x100"), std::string::npos) << s.message();
}

TEST(StereoRectifier, ResizeOnlyMatchesOpenCvResize) {
  Result<StereoRectifier> r = StereoRectifier::CreateResizeOnly(kRaw, cv::Size(320, 240));
  ASSERT_TRUE(r.ok()) << r.message();
  EXPECT_EQ(r->camera().fx, 0);
  const cv::Mat texture = Texture();
  cv::Mat left, right, expected;
  ASSERT_TRUE(r->Apply(texture, texture, &left, &right).ok());
  cv::resize(texture, expected, cv::Size(320, 240), 0, 0, cv::INTER_AREA);
  EXPECT_EQ(cv::norm(left, expected, cv::NORM_INF), 0);
}

}  // namespace
}  // namespace sfrt::camera
