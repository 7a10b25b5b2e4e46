// tools/profiling/peak_bandwidth.h: the read-bandwidth loop gives a positive, finite rate on one
// and two threads over the whole buffer (split between them), and refuses zero threads. (Rates
// are the benchmark's business: nothing here checks a speed.)
#include "profiling/peak_bandwidth.h"

#include <gtest/gtest.h>

#include <cmath>

namespace sfrt::profiling {
namespace {

constexpr size_t kSmallBuffer = size_t{16} << 20;  // enough to run the loop, quick under ASan

TEST(PeakBandwidth, OneAndTwoThreadsGiveAPositiveFiniteRateOverTheWholeBuffer) {
  for (int threads : {1, 2}) {
    SCOPED_TRACE(threads);
    Result<PeakBandwidth> peak = MeasureReadBandwidth(threads, 0.01, kSmallBuffer);
    ASSERT_TRUE(peak.ok()) << peak.message();
    EXPECT_EQ(peak->threads, threads);
    EXPECT_TRUE(std::isfinite(peak->gbytes_per_second));
    EXPECT_GT(peak->gbytes_per_second, 0.0);
    EXPECT_EQ(peak->buffer_bytes, kSmallBuffer);  // 16 MiB splits evenly into 64-byte lines
    EXPECT_NE(peak->kernel.find("16 MiB"), std::string::npos) << peak->kernel;
  }
}

TEST(PeakBandwidth, RefusesZeroThreads) {
  Result<PeakBandwidth> peak = MeasureReadBandwidth(0, 0.01, kSmallBuffer);
  ASSERT_FALSE(peak.ok());
  EXPECT_NE(peak.message().find("threads must be >= 1"), std::string::npos) << peak.message();
}

}  // namespace
}  // namespace sfrt::profiling
