// Side-by-side stereo video: written with cv::VideoWriter (MJPG in AVI, which OpenCV encodes and
// decodes with its built-in codec, whatever backends Debian's build has), read back and split.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <opencv2/videoio.hpp>
#include <string>

#include "camera/sources/test_util.h"
#include "sfrt/camera/stereo_source.h"

namespace sfrt::camera {
namespace {

using testing::TempDir;

constexpr int kEyeWidth = 32;
constexpr int kHeight = 24;
constexpr int kFrames = 5;

// Frame f: left half grey-blue with G = 40 f, right half red with G = 40 f (flat colours survive
// MJPEG within a few levels).
void WriteSbsVideo(const std::string& path) {
  cv::VideoWriter writer(path, cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'),
                         10.0, cv::Size(2 * kEyeWidth, kHeight));
  ASSERT_TRUE(writer.isOpened()) << path;
  for (int f = 0; f < kFrames; ++f) {
    cv::Mat frame(kHeight, 2 * kEyeWidth, CV_8UC3);
    frame(cv::Rect(0, 0, kEyeWidth, kHeight)).setTo(cv::Scalar(200, 40 * f, 30));
    frame(cv::Rect(kEyeWidth, 0, kEyeWidth, kHeight)).setTo(cv::Scalar(30, 40 * f, 200));
    writer.write(frame);
  }
}

bool Near(const cv::Mat& image, cv::Scalar bgr, double tolerance) {
  const cv::Scalar m = cv::mean(image);
  for (int c = 0; c < 3; ++c) {
    if (std::abs(m[c] - bgr[c]) > tolerance) return false;
  }
  return true;
}

TEST(SbsVideoSource, SplitsHalvesInOrderWithTimestamps) {
  TempDir tmp;
  const std::string path = tmp / "sbs.avi";
  WriteSbsVideo(path);
  Result<std::unique_ptr<StereoSource>> source = OpenSbsVideoSource(path);
  ASSERT_TRUE(source.ok()) << source.message();
  EXPECT_EQ((*source)->size(), kFrames);
  FramePair pair;
  double last_time = -1;
  for (int f = 0; f < kFrames; ++f) {
    Result<Fetched> got = (*source)->Next(&pair);
    ASSERT_TRUE(got.ok()) << got.message();
    ASSERT_EQ(*got, Fetched::kPair) << "frame " << f;
    EXPECT_EQ(pair.left.size(), cv::Size(kEyeWidth, kHeight));
    EXPECT_EQ(pair.right.size(), cv::Size(kEyeWidth, kHeight));
    EXPECT_EQ(pair.left.type(), CV_8UC3);
    EXPECT_TRUE(Near(pair.left, cv::Scalar(200, 40 * f, 30), 6)) << cv::mean(pair.left);
    EXPECT_TRUE(Near(pair.right, cv::Scalar(30, 40 * f, 200), 6)) << cv::mean(pair.right);
    EXPECT_EQ(pair.index, f);
    EXPECT_EQ(pair.frame_number, f);
    ASSERT_TRUE(pair.timestamp_s.has_value());
    EXPECT_NEAR(*pair.timestamp_s, f * 0.1, 1e-6);
    EXPECT_GT(*pair.timestamp_s, last_time);
    last_time = *pair.timestamp_s;
    EXPECT_EQ(pair.left_path, path + "#" + std::to_string(f) + " (left half)");
  }
  Result<Fetched> end = (*source)->Next(&pair);
  ASSERT_TRUE(end.ok()) << end.message();
  EXPECT_EQ(*end, Fetched::kEnd);
  EXPECT_TRUE((*source)->skipped().empty());
}

TEST(SbsVideoSource, RightFirstSwapsHalves) {
  TempDir tmp;
  const std::string path = tmp / "sbs.avi";
  WriteSbsVideo(path);
  VideoOptions options;
  options.left_first = false;
  Result<std::unique_ptr<StereoSource>> source = OpenSbsVideoSource(path, options);
  ASSERT_TRUE(source.ok()) << source.message();
  FramePair pair;
  Result<Fetched> got = (*source)->Next(&pair);
  ASSERT_TRUE(got.ok() && *got == Fetched::kPair) << got.message();
  EXPECT_TRUE(Near(pair.left, cv::Scalar(30, 0, 200), 6)) << cv::mean(pair.left);
  EXPECT_TRUE(Near(pair.right, cv::Scalar(200, 0, 30), 6)) << cv::mean(pair.right);
}

TEST(SbsVideoSource, WindowsOverVideoAreConsecutiveFrames) {
  TempDir tmp;
  const std::string path = tmp / "sbs.avi";
  WriteSbsVideo(path);
  Result<std::unique_ptr<StereoSource>> source = OpenSbsVideoSource(path);
  ASSERT_TRUE(source.ok()) << source.message();
  PairWindow window(source->get());
  int windows = 0;
  while (true) {
    Result<Fetched> got = window.Next();
    ASSERT_TRUE(got.ok()) << got.message();
    if (*got == Fetched::kEnd) break;
    EXPECT_EQ(window.previous().frame_number, windows);
    EXPECT_EQ(window.current().frame_number, windows + 1);
    // Each slot owns its images: the previous frame still shows its own content.
    EXPECT_TRUE(Near(window.previous().left, cv::Scalar(200, 40 * windows, 30), 6));
    ++windows;
  }
  EXPECT_EQ(windows, kFrames - 1);
  // The window rule (window_chain.h) on the video's frame numbers: one chain, no break.
  EXPECT_EQ(window.counts().windows, kFrames - 1);
  EXPECT_EQ(window.counts().breaks(), 0);
}

TEST(SbsVideoSource, MissingOrUndecodableFileIsAnError) {
  TempDir tmp;
  Result<std::unique_ptr<StereoSource>> missing = OpenSbsVideoSource(tmp / "none.avi");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find(tmp / "none.avi"), std::string::npos) << missing.message();

  testing::WriteText(tmp / "junk.avi", "this is not a video container at all");
  Result<std::unique_ptr<StereoSource>> junk = OpenSbsVideoSource(tmp / "junk.avi");
  ASSERT_FALSE(junk.ok());
  EXPECT_NE(junk.message().find(tmp / "junk.avi"), std::string::npos) << junk.message();
}

// Cutting the file leaves the container's frame count (5) above what decodes: the early end is a
// bad frame named by file and frame number.
TEST(SbsVideoSource, TruncatedFileReportsTheEarlyEnd) {
  TempDir tmp;
  const std::string path = tmp / "cut.avi";
  WriteSbsVideo(path);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) * 6 / 10);
  for (BadFramePolicy policy : {BadFramePolicy::kStop, BadFramePolicy::kSkip}) {
    VideoOptions options;
    options.on_bad_frame = policy;
    Result<std::unique_ptr<StereoSource>> source = OpenSbsVideoSource(path, options);
    ASSERT_TRUE(source.ok()) << source.message();
    EXPECT_EQ((*source)->size(), kFrames);
    FramePair pair;
    int frames = 0;
    Status error;
    while (true) {
      Result<Fetched> got = (*source)->Next(&pair);
      if (!got.ok()) {
        error = got.status();
        break;
      }
      if (*got == Fetched::kEnd) break;
      ++frames;
    }
    ASSERT_LT(frames, kFrames);
    const std::string where = path + "#" + std::to_string(frames);
    if (policy == BadFramePolicy::kStop) {
      ASSERT_FALSE(error.ok());
      EXPECT_NE(error.message().find(where), std::string::npos) << error.message();
      EXPECT_NE(error.message().find("ended early"), std::string::npos) << error.message();
    } else {
      EXPECT_TRUE(error.ok()) << error.message();
      ASSERT_EQ((*source)->skipped().size(), 1u);
      EXPECT_EQ((*source)->skipped()[0].path, where);
    }
  }
}

}  // namespace
}  // namespace sfrt::camera
