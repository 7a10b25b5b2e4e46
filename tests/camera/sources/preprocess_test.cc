// Preprocessing into the H x W x 12 network input (two stereo pairs) and the H x W x 8 one (two
// RGB-D frames): image order, colour order, scale, mean and std, and depth in 16-bit units or
// float metres with its missing values, checked value by value against the model file's formula
// evaluated directly.
#include "sfrt/camera/preprocess.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace sfrt::camera {
namespace {

constexpr int kH = 5;
constexpr int kW = 7;

cv::Mat RandomImage(std::mt19937* rng) {
  cv::Mat image(kH, kW, CV_8UC3);
  std::uniform_int_distribution<int> dist(0, 255);
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      for (int c = 0; c < 3; ++c) image.at<cv::Vec3b>(y, x)[c] = static_cast<uint8_t>(dist(*rng));
    }
  }
  return image;
}

TEST(Preprocessor, OrderColourScaleMeanStdExactly) {
  std::mt19937 rng(1234);
  const cv::Mat images[4] = {RandomImage(&rng), RandomImage(&rng), RandomImage(&rng),
                             RandomImage(&rng)};  // left0, right0, left1, right1
  Result<std::array<ImageSlot, 4>> order = ParseImageOrder({"right1", "left0", "right0", "left1"});
  ASSERT_TRUE(order.ok()) << order.message();
  for (const char* colour : {"BGR", "RGB"}) {
    PreprocessParams params;
    params.image_order = *order;
    params.color_order = *ParseColorOrder(colour);
    params.scale = 1.0f / 255.0f;
    const float mean[3] = {0.485f, 0.456f, 0.406f};
    const float std[3] = {0.229f, 0.224f, 0.225f};
    std::memcpy(params.mean, mean, sizeof(mean));
    std::memcpy(params.std, std, sizeof(std));
    Result<Preprocessor> p = Preprocessor::Create(params, kH, kW);
    ASSERT_TRUE(p.ok()) << p.message();
    std::vector<float> out(p->output_floats(), -999.0f);
    ASSERT_EQ(out.size(), static_cast<size_t>(kH * kW * 12));
    Status s = p->Run(images[0], images[1], images[2], images[3], out.data(), out.size());
    ASSERT_TRUE(s.ok()) << s.message();

    const int source_of_group[4] = {3, 0, 1, 2};  // right1, left0, right0, left1
    const bool rgb = std::string(colour) == "RGB";
    for (int y = 0; y < kH; ++y) {
      for (int x = 0; x < kW; ++x) {
        for (int g = 0; g < 4; ++g) {
          const cv::Vec3b bgr = images[source_of_group[g]].at<cv::Vec3b>(y, x);
          for (int c = 0; c < 3; ++c) {
            const float pixel = static_cast<float>(rgb ? bgr[2 - c] : bgr[c]);
            const float want = (pixel * params.scale - mean[c]) / std[c];
            const float got = out[(static_cast<size_t>(y) * kW + x) * 12 + 3 * g + c];
            ASSERT_EQ(got, want) << colour << " y=" << y << " x=" << x << " g=" << g << " c=" << c;
          }
        }
      }
    }
  }
}

// The uint8 path: each byte is the caller's quantiser applied to the float Run() writes there
// (here a plain rounding of the normalised value to 1/64 steps around 128), and a destination
// of the wrong size is refused in bytes.
TEST(Preprocessor, RunQuantizedWritesTheQuantisedValueOfEveryFloatRunWrites) {
  std::mt19937 rng(99);
  const cv::Mat images[4] = {RandomImage(&rng), RandomImage(&rng), RandomImage(&rng),
                             RandomImage(&rng)};
  PreprocessParams params;
  params.color_order = ColorOrder::kRGB;
  params.scale = 1.0f / 255.0f;
  const float mean[3] = {0.485f, 0.456f, 0.406f};
  const float std[3] = {0.229f, 0.224f, 0.225f};
  std::memcpy(params.mean, mean, sizeof(mean));
  std::memcpy(params.std, std, sizeof(std));
  Result<Preprocessor> p = Preprocessor::Create(params, kH, kW);
  ASSERT_TRUE(p.ok()) << p.message();
  auto quantize = [](float v) {
    const float q = std::nearbyint(v * 64.0f) + 128.0f;
    return static_cast<uint8_t>(q < 0 ? 0 : q > 255 ? 255 : q);
  };
  const Preprocessor::QuantizedTable table = p->Tabulate(quantize);
  std::vector<float> floats(p->output_floats());
  ASSERT_TRUE(
      p->Run(images[0], images[1], images[2], images[3], floats.data(), floats.size()).ok());
  std::vector<uint8_t> bytes(p->output_floats(), 7);
  Status s = p->RunQuantized(images[0], images[1], images[2], images[3], table, bytes.data(),
                             bytes.size());
  ASSERT_TRUE(s.ok()) << s.message();
  int clamped = 0;
  for (size_t i = 0; i < floats.size(); ++i) {
    ASSERT_EQ(bytes[i], quantize(floats[i])) << "element " << i;
    clamped += bytes[i] == 0 || bytes[i] == 255;
  }
  EXPECT_LT(clamped, static_cast<int>(floats.size()) / 2);  // the values spread over the range
  s = p->RunQuantized(images[0], images[1], images[2], images[3], table, bytes.data(),
                      bytes.size() - 1);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("destination holds 419 bytes, expected 420"), std::string::npos)
      << s.message();
}

TEST(Preprocessor, HandComputedValuesAndStridedImages) {
  // A 1x1 ROI inside a larger image (non-contiguous rows are fine; here 2x2 for a real stride).
  cv::Mat big(4, 4, CV_8UC3, cv::Scalar(0, 0, 0));
  big.at<cv::Vec3b>(1, 1) = cv::Vec3b(10, 20, 30);  // B G R
  big.at<cv::Vec3b>(1, 2) = cv::Vec3b(40, 50, 60);
  big.at<cv::Vec3b>(2, 1) = cv::Vec3b(70, 80, 90);
  big.at<cv::Vec3b>(2, 2) = cv::Vec3b(100, 110, 120);
  const cv::Mat roi = big(cv::Rect(1, 1, 2, 2));
  const cv::Mat zero(2, 2, CV_8UC3, cv::Scalar::all(0));
  PreprocessParams params;  // L0 R0 L1 R1
  params.color_order = ColorOrder::kRGB;
  params.scale = 2.0f;
  params.mean[0] = 10;  // R
  params.mean[1] = 0;
  params.mean[2] = 20;  // B
  params.std[0] = 2;
  params.std[1] = 4;
  params.std[2] = 0.5f;
  Result<Preprocessor> p = Preprocessor::Create(params, 2, 2);
  ASSERT_TRUE(p.ok()) << p.message();
  std::vector<float> out(p->output_floats());
  ASSERT_TRUE(p->Run(zero, zero, zero, roi, out.data(), out.size()).ok());
  // Pixel (1, 0) of right1 is B=70 G=80 R=90: R -> (180-10)/2, G -> 160/4, B -> (140-20)/0.5.
  const float* px = &out[(1 * 2 + 0) * 12 + 9];
  EXPECT_EQ(px[0], 85.0f);
  EXPECT_EQ(px[1], 40.0f);
  EXPECT_EQ(px[2], 240.0f);
  // left0 is black: R -> -5, G -> 0, B -> -40.
  EXPECT_EQ(out[0], -5.0f);
  EXPECT_EQ(out[1], 0.0f);
  EXPECT_EQ(out[2], -40.0f);
}

TEST(Preprocessor, RejectsBadParametersAndBuffers) {
  Result<std::array<ImageSlot, 4>> dup = ParseImageOrder({"left0", "left0", "left1", "right1"});
  ASSERT_FALSE(dup.ok());
  EXPECT_NE(dup.message().find("'left0' twice"), std::string::npos) << dup.message();
  Result<std::array<ImageSlot, 4>> three = ParseImageOrder({"left0", "right0", "left1"});
  ASSERT_FALSE(three.ok());
  Result<ImageSlot> typo = ParseImageSlot("left2");
  ASSERT_FALSE(typo.ok());
  EXPECT_NE(typo.message().find("'left2'"), std::string::npos);
  Result<ColorOrder> colour = ParseColorOrder("YUV");
  ASSERT_FALSE(colour.ok());
  EXPECT_NE(colour.message().find("'YUV'"), std::string::npos);

  PreprocessParams params;
  params.std[1] = 0;
  Result<Preprocessor> zero_std = Preprocessor::Create(params, 2, 2);
  ASSERT_FALSE(zero_std.ok());
  EXPECT_NE(zero_std.message().find("std[1] is 0"), std::string::npos) << zero_std.message();

  params = PreprocessParams();
  params.image_order[3] = ImageSlot::kLeft0;
  ASSERT_FALSE(Preprocessor::Create(params, 2, 2).ok());

  Result<Preprocessor> p = Preprocessor::Create(PreprocessParams(), 2, 3);
  ASSERT_TRUE(p.ok()) << p.message();
  const cv::Mat ok(2, 3, CV_8UC3, cv::Scalar::all(1));
  const cv::Mat wrong(3, 2, CV_8UC3, cv::Scalar::all(1));
  std::vector<float> out(p->output_floats());
  Status size = p->Run(ok, ok, wrong, ok, out.data(), out.size());
  ASSERT_FALSE(size.ok());
  EXPECT_NE(size.message().find("left1 image is 3x2"), std::string::npos) << size.message();
  Status short_dst = p->Run(ok, ok, ok, ok, out.data(), out.size() - 1);
  ASSERT_FALSE(short_dst.ok());
  EXPECT_NE(short_dst.message().find("71 floats, expected 72"), std::string::npos)
      << short_dst.message();
}

// The RGB-D form: colour as above, depth d metres fed as (d - depth_mean) / depth_std and a
// missing depth (0, negative, NaN or infinite) as depth_invalid; 16-bit maps hold d * units.
TEST(RgbdPreprocessor, OrderColourAndDepthInUnitsOrMetresExactly) {
  std::mt19937 rng(99);
  const cv::Mat color0 = RandomImage(&rng);
  const cv::Mat color1 = RandomImage(&rng);
  cv::Mat depth16(kH, kW, CV_16UC1);
  cv::Mat depth32(kH, kW, CV_32FC1);
  std::uniform_int_distribution<int> mm(0, 65535);
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      depth16.at<uint16_t>(y, x) = static_cast<uint16_t>((x + y) % 5 == 0 ? 0 : mm(rng));
      depth32.at<float>(y, x) = static_cast<float>(mm(rng)) / 700.0f;
    }
  }
  depth32.at<float>(0, 1) = 0.0f;
  depth32.at<float>(1, 2) = -1.0f;
  depth32.at<float>(2, 3) = std::numeric_limits<float>::quiet_NaN();
  depth32.at<float>(3, 4) = std::numeric_limits<float>::infinity();

  Result<std::array<ImageSlot, 4>> order =
      ParseImageOrder({"depth1", "color0", "depth0", "color1"});
  ASSERT_TRUE(order.ok()) << order.message();
  RgbdPreprocessParams params;
  params.order = *order;
  params.color_order = ColorOrder::kRGB;
  params.scale = 1.0f / 255.0f;
  params.mean[0] = 0.5f;
  params.std[2] = 0.25f;
  params.depth_mean = 3.0f;
  params.depth_std = 2.0f;
  params.depth_invalid = -7.5f;
  params.depth_units_per_metre = 5000.0f;
  Result<RgbdPreprocessor> p = RgbdPreprocessor::Create(params, kH, kW);
  ASSERT_TRUE(p.ok()) << p.message();
  std::vector<float> out(p->output_floats(), -999.0f);
  ASSERT_EQ(out.size(), static_cast<size_t>(kH * kW * 8));
  // depth0 as 16-bit units, depth1 as float metres.
  Status s = p->Run(color0, depth16, color1, depth32, out.data(), out.size());
  ASSERT_TRUE(s.ok()) << s.message();

  auto depth_value = [&](float metres, bool missing) {
    return missing ? params.depth_invalid : (metres - params.depth_mean) / params.depth_std;
  };
  int missing_seen = 0;
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      const float* px = out.data() + (static_cast<size_t>(y) * kW + x) * 8;
      // Channel 0: depth1 (float metres).
      const float d1 = depth32.at<float>(y, x);
      const bool d1_missing = !(std::isfinite(d1) && d1 > 0);
      missing_seen += d1_missing;
      ASSERT_EQ(px[0], depth_value(d1, d1_missing)) << y << "," << x;
      // Channels 1-3: color0 (RGB order); 4: depth0 (16-bit); 5-7: color1.
      for (int c = 0; c < 3; ++c) {
        const float want0 = (static_cast<float>(color0.at<cv::Vec3b>(y, x)[2 - c]) * params.scale -
                             params.mean[c]) /
                            params.std[c];
        const float want1 = (static_cast<float>(color1.at<cv::Vec3b>(y, x)[2 - c]) * params.scale -
                             params.mean[c]) /
                            params.std[c];
        ASSERT_EQ(px[1 + c], want0) << y << "," << x << " c " << c;
        ASSERT_EQ(px[5 + c], want1) << y << "," << x << " c " << c;
      }
      const uint16_t d0 = depth16.at<uint16_t>(y, x);
      missing_seen += d0 == 0;
      ASSERT_EQ(px[4], depth_value(static_cast<float>(d0) / 5000.0f, d0 == 0)) << y << "," << x;
    }
  }
  EXPECT_GE(missing_seen, 4 + 5);  // every kind of missing depth was exercised
}

TEST(RgbdPreprocessor, RejectsStereoSlotsBadDepthParametersAndMapsOfTheWrongType) {
  Result<std::array<ImageSlot, 4>> mixed = ParseImageOrder({"color0", "depth0", "left1", "depth1"});
  ASSERT_FALSE(mixed.ok());
  EXPECT_NE(mixed.message().find("mixes stereo images and RGB-D frames"), std::string::npos)
      << mixed.message();

  RgbdPreprocessParams params;
  params.order = vocabulary::kDefaultImageOrder;
  Result<RgbdPreprocessor> stereo = RgbdPreprocessor::Create(params, 2, 2);
  ASSERT_FALSE(stereo.ok());
  EXPECT_NE(stereo.message().find("not color0, depth0, color1 or depth1"), std::string::npos)
      << stereo.message();
  PreprocessParams stereo_params;
  stereo_params.image_order = vocabulary::kDefaultRgbdOrder;
  Result<Preprocessor> rgbd_as_stereo = Preprocessor::Create(stereo_params, 2, 2);
  ASSERT_FALSE(rgbd_as_stereo.ok());
  EXPECT_NE(rgbd_as_stereo.message().find("RGB-D frames go through RgbdPreprocessor"),
            std::string::npos)
      << rgbd_as_stereo.message();

  params = RgbdPreprocessParams();
  params.depth_std = 0;
  ASSERT_FALSE(RgbdPreprocessor::Create(params, 2, 2).ok());
  params = RgbdPreprocessParams();
  params.depth_units_per_metre = 0;
  ASSERT_FALSE(RgbdPreprocessor::Create(params, 2, 2).ok());

  Result<RgbdPreprocessor> p = RgbdPreprocessor::Create(RgbdPreprocessParams(), 2, 3);
  ASSERT_TRUE(p.ok()) << p.message();
  const cv::Mat colour(2, 3, CV_8UC3, cv::Scalar::all(1));
  const cv::Mat depth(2, 3, CV_16UC1, cv::Scalar::all(1000));
  const cv::Mat depth8(2, 3, CV_8UC1, cv::Scalar::all(1));
  std::vector<float> out(p->output_floats());
  Status eight_bit = p->Run(colour, depth, colour, depth8, out.data(), out.size());
  ASSERT_FALSE(eight_bit.ok());
  EXPECT_NE(eight_bit.message().find("depth1 is 2x3 with 1 channels of depth 0; expected 16-bit "
                                     "or float32 single-channel"),
            std::string::npos)
      << eight_bit.message();
  Status short_dst = p->Run(colour, depth, colour, depth, out.data(), out.size() - 1);
  ASSERT_FALSE(short_dst.ok());
  EXPECT_NE(short_dst.message().find("47 floats, expected 48"), std::string::npos)
      << short_dst.message();
  ASSERT_TRUE(p->Run(colour, depth, colour, depth, out.data(), out.size()).ok());
  EXPECT_EQ(out[3], 1.0f);  // 1000 mm at the default 1000 units per metre, mean 0, std 1
}

}  // namespace
}  // namespace sfrt::camera
