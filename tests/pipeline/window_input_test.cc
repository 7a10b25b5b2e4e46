// pipeline::WindowInput: one window's network input from images in memory, as `sfrt infer` and
// the Python package build it (the resize and preprocessing of the pipeline's preprocess stage).
#include "sfrt/pipeline/window_input.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace sfrt::pipeline {
namespace {

ModelMetadata StereoMeta(const char* color_order) {
  ModelMetadata meta;
  meta.input.channels = 12;
  meta.input.image_order = {"left1", "right1", "left0", "right0"};
  meta.input.color_order = color_order;
  meta.input.scale = 1.0f / 255;
  meta.input.mean[0] = 0.2f;
  meta.input.mean[1] = 0.5f;
  meta.input.mean[2] = 0.7f;
  meta.input.std[0] = 0.3f;
  return meta;
}

ModelMetadata RgbdMeta() {
  ModelMetadata meta = StereoMeta("RGB");
  meta.input.channels = 8;
  meta.input.image_order = {"color0", "depth0", "color1", "depth1"};
  meta.input.depth_mean = 2.0f;
  meta.input.depth_std = 1.5f;
  meta.input.depth_invalid = -1.0f;
  return meta;
}

std::array<cv::Mat, 4> RandomImages(int rows, int cols, int seed) {
  cv::RNG rng(static_cast<uint64_t>(seed));
  std::array<cv::Mat, 4> images;
  for (cv::Mat& m : images) {
    m.create(rows, cols, CV_8UC3);
    rng.fill(m, cv::RNG::UNIFORM, 0, 256);
  }
  return images;
}

std::vector<float> BuildAt(WindowInput& input, const std::array<cv::Mat, 4>& images, int h, int w) {
  std::vector<float> x(input.Floats(h, w));
  Status built = input.Build(images, h, w, x);
  EXPECT_TRUE(built.ok()) << built.message();
  return x;
}

TEST(WindowInput, ImagesGivenAsRgbGiveWhatTheirBgrCopiesGive) {
  for (const char* model_order : {"BGR", "RGB"}) {
    const std::array<cv::Mat, 4> bgr = RandomImages(24, 40, 1);
    std::array<cv::Mat, 4> rgb;
    for (size_t i = 0; i < 4; ++i) cv::cvtColor(bgr[i], rgb[i], cv::COLOR_BGR2RGB);
    auto from_bgr = WindowInput::Create(StereoMeta(model_order), {});
    WindowInputOptions as_rgb;
    as_rgb.given = camera::ColorOrder::kRGB;
    auto from_rgb = WindowInput::Create(StereoMeta(model_order), as_rgb);
    ASSERT_TRUE(from_bgr.ok() && from_rgb.ok());
    for (auto [h, w] : {std::pair{24, 40}, std::pair{16, 24}}) {  // in place, then resized
      EXPECT_EQ(BuildAt(*from_bgr, bgr, h, w), BuildAt(*from_rgb, rgb, h, w)) << model_order;
    }
  }
}

TEST(WindowInput, ResizesAsThePipelineDoesAndFeedsTheModelsSlotOrder) {
  const std::array<cv::Mat, 4> images = RandomImages(48, 64, 2);
  auto input = WindowInput::Create(StereoMeta("BGR"), {});
  ASSERT_TRUE(input.ok());
  const std::vector<float> x = BuildAt(*input, images, 24, 32);
  // The pipeline's resize (INTER_AREA when shrinking), then the first slot is left1.
  cv::Mat left1;
  cv::resize(images[2], left1, cv::Size(32, 24), 0, 0, cv::INTER_AREA);
  const cv::Vec3b p = left1.at<cv::Vec3b>(5, 7);
  const float* got = &x[(5 * 32 + 7) * 12];
  EXPECT_FLOAT_EQ(got[0], (p[0] / 255.0f - 0.2f) / 0.3f);
  EXPECT_FLOAT_EQ(got[1], (p[1] / 255.0f - 0.5f) / 1.0f);
  EXPECT_FLOAT_EQ(got[2], (p[2] / 255.0f - 0.7f) / 1.0f);
}

TEST(WindowInput, ImagesWithARowStrideAreReadAsTheirPackedCopies) {
  const std::array<cv::Mat, 4> big = RandomImages(40, 60, 3);
  std::array<cv::Mat, 4> crops, packed;
  for (size_t i = 0; i < 4; ++i) {
    crops[i] = big[i](cv::Rect(5, 3, 32, 24));
    packed[i] = crops[i].clone();
  }
  auto input = WindowInput::Create(StereoMeta("RGB"), {});
  ASSERT_TRUE(input.ok());
  EXPECT_EQ(BuildAt(*input, crops, 24, 32), BuildAt(*input, packed, 24, 32));
  EXPECT_EQ(BuildAt(*input, crops, 16, 20), BuildAt(*input, packed, 16, 20));
}

TEST(WindowInput, SizeIsChosenAsSfrtRunChoosesIt) {
  ModelMetadata meta = StereoMeta("BGR");
  meta.training = TrainingState::kTrained;
  meta.input.traced_height = 96;
  meta.input.traced_width = 128;
  auto recorded = WindowInput::Create(meta, {});
  ASSERT_TRUE(recorded.ok());
  auto size = recorded->ChooseSize(480, 640);
  ASSERT_TRUE(size.ok());
  EXPECT_EQ(size->height, 96);
  EXPECT_EQ(size->width, 128);
  WindowInputOptions asked;
  asked.height = 128;
  asked.width = 96;
  auto inverse = WindowInput::Create(meta, asked);
  ASSERT_TRUE(inverse.ok());
  auto refused = inverse->ChooseSize(480, 640);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.message().find("inverse aspect"), std::string::npos) << refused.message();
}

TEST(WindowInput, RgbdDepthIsResizedByTheNearestSample) {
  auto input = WindowInput::Create(RgbdMeta(), {});
  ASSERT_TRUE(input.ok());
  ASSERT_TRUE(input->rgbd());
  std::array<cv::Mat, 4> frames = RandomImages(20, 20, 4);
  frames[1] = cv::Mat(20, 20, CV_16UC1, cv::Scalar(2000));
  frames[1].colRange(0, 10).setTo(0);  // no depth on the left half
  frames[3] = cv::Mat(20, 20, CV_32FC1, cv::Scalar(3.5f));
  const std::vector<float> x = BuildAt(*input, frames, 10, 10);
  for (int c = 0; c < 10; ++c) {
    const float* px = &x[(4 * 10 + c) * 8];
    EXPECT_FLOAT_EQ(px[3], c < 5 ? -1.0f : 0.0f) << c;  // (2 m - 2) / 1.5, or missing
    EXPECT_FLOAT_EQ(px[7], 1.0f) << c;                  // (3.5 m - 2) / 1.5
  }
}

TEST(WindowInput, CheckNamesTheImageAndWhatWasExpected) {
  auto input = WindowInput::Create(StereoMeta("BGR"), {});
  ASSERT_TRUE(input.ok());
  std::array<cv::Mat, 4> images = RandomImages(20, 30, 5);
  const std::array<std::string, 4> names = {"left0", "right0", "left1", "right1"};
  images[2] = images[2](cv::Rect(0, 0, 30, 10)).clone();
  Status size = input->Check(images, names, "one size");
  EXPECT_EQ(size.message(), "left1 is 10x30 but left0 is 20x30 (one size)");
  images[2] = cv::Mat(20, 30, CV_32FC3);
  Status type = input->Check(images, names, "one size");
  EXPECT_EQ(type.message(),
            "left1 has 3 channel(s) of 32-bit floats; an image is 3 channels of 8 bits");
}

TEST(WindowInput, APlainTensorModelTakesNoImages) {
  ModelMetadata meta;
  meta.input.channels = 12;
  auto input = WindowInput::Create(meta, {});
  ASSERT_FALSE(input.ok());
  EXPECT_NE(input.message().find("plain tensor"), std::string::npos);
}

TEST(CheckFiniteTensor, NamesTheFirstElementThatIsNotFinite) {
  std::vector<float> x(4 * 5 * 3, 0.0f);
  EXPECT_TRUE(CheckFiniteTensor(x, 5, 3, "x").ok());
  x[(2 * 5 + 3) * 3 + 1] = INFINITY;
  x[(3 * 5 + 0) * 3 + 0] = NAN;
  EXPECT_EQ(CheckFiniteTensor(x, 5, 3, "a.npy").message(),
            "a.npy: element [2, 3, 1] (flat index 40) is infinite; the input must be finite");
}

}  // namespace
}  // namespace sfrt::pipeline
