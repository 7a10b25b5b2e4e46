// The visualisation's PNG encoder (pipeline/src/png_encoder.h) against an independent decoder
// (OpenCV's imdecode): lossless on a real flow picture and on noise, padded rows included.
#include "png_encoder.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <vector>

#include "sfrt/pipeline/visualize.h"

namespace sfrt::pipeline {
namespace {

void ExpectDecodesToTheSamePixels(const cv::Mat& image) {
  std::vector<uint8_t> png;
  PngEncoder encoder;
  Status s = encoder.Encode(image, &png);
  ASSERT_TRUE(s.ok()) << s.message();
  ASSERT_GT(png.size(), 8u);
  const cv::Mat back = cv::imdecode(png, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(back.type(), CV_8UC3);
  ASSERT_EQ(back.size(), image.size());
  EXPECT_EQ(cv::norm(back, image, cv::NORM_INF), 0.0);
}

TEST(PngEncoder, AFlowPictureDecodesToTheSamePixels) {
  cv::Mat left(96, 128, CV_8UC3);
  cv::randu(left, 0, 255);
  std::vector<float> flow(96 * 128 * 3);
  std::mt19937 rng(7);
  std::normal_distribution<float> motion(0.0f, 0.02f);
  for (float& v : flow) v = motion(rng);
  Visualizer vis(VisualizerOptions{VisScale{}, "m"});
  cv::Mat canvas;
  vis.Render(left, flow.data(), 3, "frame_000000", &canvas);
  ExpectDecodesToTheSamePixels(canvas);
}

TEST(PngEncoder, NoiseAndPaddedRowsDecodeToTheSamePixels) {
  cv::Mat big(57, 301, CV_8UC3);
  cv::randu(big, 0, 255);
  ExpectDecodesToTheSamePixels(big);
  ExpectDecodesToTheSamePixels(big(cv::Rect(3, 5, 101, 40)));  // a view: rows with a stride
}

TEST(PngEncoder, RefusesWhatIsNotEightBitColour) {
  std::vector<uint8_t> png;
  PngEncoder encoder;
  EXPECT_FALSE(encoder.Encode(cv::Mat(4, 4, CV_8UC1), &png).ok());
  EXPECT_FALSE(encoder.Encode(cv::Mat(), &png).ok());
}

}  // namespace
}  // namespace sfrt::pipeline
