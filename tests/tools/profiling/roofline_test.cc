// profiling/roofline.h: the unit each of the runtime's kernel names runs on, and a step's place
// against hand-computed roofs.
#include "profiling/roofline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace sfrt::profiling {
namespace {

TEST(Roofline, EveryKernelNameOfTheRuntimeMapsToTheUnitItRunsOn) {
  struct Case {
    const char* kernel;
    ComputeUnit unit;
  };
  const Case cases[] = {
      {"conv2d_u8s8__avx512amx_16x64", ComputeUnit::kAmxInt8},
      {"upconv2d_u8s8__avx512amx_16x64", ComputeUnit::kAmxInt8},
      {"conv2d_bf16__avx512amx_16x64", ComputeUnit::kAmxBf16},
      {"upconv2d_bf16__avx512amx_16x64", ComputeUnit::kAmxBf16},
      {"conv2d_u8s8__amx_emulated_16x64", ComputeUnit::kUnmeasured},
      {"upconv2d_bf16__amx_emulated_16x64", ComputeUnit::kUnmeasured},
      {"conv2d_u8s8__avx512vnni_6x64", ComputeUnit::kInt8Dot},
      {"upconv2d_u8s8__avx512vnni_6x64", ComputeUnit::kInt8Dot},
      {"conv2d_fewout_u8s8__avx512vnni_8x3", ComputeUnit::kInt8Dot},
      {"conv2d_narrow_u8s8__avx512vnni_16x4", ComputeUnit::kInt8Dot},
      {"conv2d_bf16__avx512bf16_6x64", ComputeUnit::kBf16Dot},
      {"conv2d_fewout_bf16__avx512bf16_8x3", ComputeUnit::kBf16Dot},
      {"upconv2d_bf16__avx512bf16_6x64", ComputeUnit::kBf16Dot},
      {"conv2d_f32__avx512_12x32", ComputeUnit::kFma},
      {"conv2d_fewout_f32__avx2_4xc", ComputeUnit::kFma},
      {"upconv2x_conv3x3_f32__neon_8x8", ComputeUnit::kFma},
      {"conv2d_winograd_f4x4_3x3__avx512_6x64", ComputeUnit::kFma},
      {"upconv2x_conv3x3_winograd_f2x2_2x2__avx2_6x16", ComputeUnit::kFma},
      {"conv2d_u8s8__neon_sdot_5x16", ComputeUnit::kUnmeasured},
      {"upconv2d_u8s8__neon_usdot_5x16", ComputeUnit::kUnmeasured},
      {"conv2d_bf16__neon_bfdot_5x16", ComputeUnit::kUnmeasured},
      {"ref::Conv2dInt8", ComputeUnit::kUnmeasured},
      {"ref::UpConv2dBf16", ComputeUnit::kUnmeasured},
      {"ref::Conv2d", ComputeUnit::kFma},
      {"something_new", ComputeUnit::kUnmeasured},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(KernelUnit(c.kernel, 1000), c.unit) << c.kernel;
    EXPECT_EQ(KernelUnit(c.kernel, 0), ComputeUnit::kMemory) << c.kernel << " doing no MACs";
  }
}

TEST(Roofline, AComputeBoundStepIsMeasuredAgainstItsUnitsPeak) {
  // 1e9 MACs over 10 MB: 100 MACs a byte; at 20 GB/s the memory roof is 2,000 GMAC/s, above the
  // 500 GMAC/s peak. 4 ms: 250 GMAC/s, half the roof.
  StepWork w;
  w.macs = 1000000000;
  w.bytes_read = 6000000;
  w.bytes_written = 3000000;
  w.weight_bytes = 1000000;
  Peaks peaks;
  peaks.int8_gmacs = 500;
  peaks.read_gbytes = 20;
  const RooflinePoint p = PlaceStep(w, ComputeUnit::kInt8Dot, 4.0, peaks);
  EXPECT_DOUBLE_EQ(p.intensity, 100.0);
  EXPECT_DOUBLE_EQ(p.roof_gmacs, 500.0);
  EXPECT_DOUBLE_EQ(p.achieved_gmacs, 250.0);
  EXPECT_DOUBLE_EQ(p.achieved_gbytes, 2.5);
  EXPECT_DOUBLE_EQ(p.share, 0.5);
  EXPECT_FALSE(p.memory_bound);
}

TEST(Roofline, ALowIntensityStepIsMeasuredAgainstTheBandwidthRoof) {
  // The 64->3 output layer's shape: 3 MACs a byte at 20 GB/s is a 60 GMAC/s roof, far below
  // the peak.
  StepWork w;
  w.macs = 300000000;
  w.bytes_read = 100000000;
  Peaks peaks;
  peaks.fma_gmacs = 1000;
  peaks.read_gbytes = 20;
  const RooflinePoint p = PlaceStep(w, ComputeUnit::kFma, 10.0, peaks);
  EXPECT_DOUBLE_EQ(p.roof_gmacs, 60.0);
  EXPECT_TRUE(p.memory_bound);
  EXPECT_DOUBLE_EQ(p.achieved_gmacs, 30.0);
  EXPECT_DOUBLE_EQ(p.share, 0.5);
}

TEST(Roofline, AMemoryStepIsItsBandwidthOverTheReadBandwidth) {
  StepWork w;
  w.bytes_read = 40000000;
  w.bytes_written = 10000000;
  Peaks peaks;
  peaks.read_gbytes = 25;
  const RooflinePoint p = PlaceStep(w, KernelUnit("quantize_u8__avx512", 0), 5.0, peaks);
  EXPECT_EQ(p.unit, ComputeUnit::kMemory);
  EXPECT_DOUBLE_EQ(p.achieved_gbytes, 10.0);
  EXPECT_DOUBLE_EQ(p.share, 0.4);
  EXPECT_TRUE(std::isnan(p.roof_gmacs));
}

TEST(Roofline, AnUnmeasuredUnitHasNoRoofAndNoShare) {
  StepWork w;
  w.macs = 1000;
  w.bytes_read = 10;
  Peaks peaks;
  peaks.read_gbytes = 25;
  const RooflinePoint p = PlaceStep(w, ComputeUnit::kUnmeasured, 1.0, peaks);
  EXPECT_TRUE(std::isnan(p.roof_gmacs));
  EXPECT_TRUE(std::isnan(p.share));
}

TEST(Roofline, FloorsSumEachStepAtItsRoofAndAllMacsAtTheMainUnitsPeak) {
  StepWork quantize;  // 50 MB at 25 GB/s: 2 ms
  quantize.bytes_read = 40000000;
  quantize.bytes_written = 10000000;
  StepWork conv;  // 1e9 MACs at 500 GMAC/s: 2 ms
  conv.macs = 1000000000;
  conv.bytes_read = 1000000;
  StepWork out;  // 3e8 MACs over 1e8 bytes: 75 GMAC/s roof, 4 ms
  out.macs = 300000000;
  out.bytes_read = 100000000;
  Peaks peaks;
  peaks.int8_gmacs = 500;
  peaks.read_gbytes = 25;
  const std::vector<std::string> kernels = {"quantize_u8__avx512", "conv2d_u8s8__avx512vnni_6x64",
                                            "conv2d_fewout_u8s8__avx512vnni_8x3"};
  const std::vector<double> ms = {4, 4, 8};
  const Roofline r = PlaceSteps({quantize, conv, out}, kernels, ms, peaks);
  ASSERT_EQ(r.points.size(), 3u);
  EXPECT_EQ(r.macs, 1300000000u);
  EXPECT_EQ(r.main_unit, ComputeUnit::kInt8Dot);
  EXPECT_NEAR(r.floor_ms, 2.0 + 2.0 + 4.0, 1e-9);
  EXPECT_NEAR(r.main_floor_ms, 1.3e9 / 500e6, 1e-9);
  for (const RooflinePoint& p : r.points) EXPECT_NEAR(p.share, 0.5, 1e-12);
}

}  // namespace
}  // namespace sfrt::profiling
