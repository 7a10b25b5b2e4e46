// Preprocessor::Run, Preprocessor::RunQuantized and RgbdPreprocessor::Run allocate nothing (their
// headers promise it): the program links the counting allocator
// (tests/common/counting_allocator.h).
#include <gtest/gtest.h>

#include <vector>

#include "common/counting_allocator.h"
#include "sfrt/camera/preprocess.h"

namespace sfrt::camera {
namespace {

TEST(PreprocessAllocation, CountingHooksSeeAnAllocation) {
  EXPECT_TRUE(sfrt::testing::CountingHooksAreLive());
}

TEST(PreprocessAllocation, StereoAndRgbdRunsAllocateNothing) {
  constexpr int kH = 24;
  constexpr int kW = 40;
  const cv::Mat colour(kH, kW, CV_8UC3, cv::Scalar(10, 20, 30));
  const cv::Mat depth16(kH, kW, CV_16UC1, cv::Scalar::all(1500));
  const cv::Mat depth32(kH, kW, CV_32FC1, cv::Scalar::all(2.5));
  Result<Preprocessor> stereo = Preprocessor::Create(PreprocessParams(), kH, kW);
  ASSERT_TRUE(stereo.ok()) << stereo.message();
  Result<RgbdPreprocessor> rgbd = RgbdPreprocessor::Create(RgbdPreprocessParams(), kH, kW);
  ASSERT_TRUE(rgbd.ok()) << rgbd.message();
  std::vector<float> out12(stereo->output_floats());
  std::vector<float> out8(rgbd->output_floats());
  std::vector<uint8_t> bytes12(stereo->output_floats());
  const Preprocessor::QuantizedTable table =
      stereo->Tabulate([](float v) { return static_cast<uint8_t>(v > 0 ? 200 : 10); });
  for (int round = 0; round < 3; ++round) {
    const long before = sfrt::testing::AllocationCount();
    const bool ok_stereo =
        stereo->Run(colour, colour, colour, colour, out12.data(), out12.size()).ok() &&
        stereo->RunQuantized(colour, colour, colour, colour, table, bytes12.data(), bytes12.size())
            .ok();
    const bool ok_rgbd = rgbd->Run(colour, depth16, colour, depth32, out8.data(), out8.size()).ok();
    const long allocated = sfrt::testing::AllocationCount() - before;
    ASSERT_TRUE(ok_stereo && ok_rgbd);
    EXPECT_EQ(allocated, 0) << "round " << round;
  }
}

}  // namespace
}  // namespace sfrt::camera
