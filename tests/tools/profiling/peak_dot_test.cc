// tools/profiling/peak_dot.h: the int8 (vpdpbusd, tdpbusd), int16 (vpdpwssd) and bf16 (vdpbf16ps,
// tdpbf16ps) peak loops give a positive, finite throughput on 1 and 2 threads where this CPU has
// them (skipped, saying why, where not); elsewhere they fail with the reason. AMX detection
// answers with a reason or "".
#include "profiling/peak_dot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "profiling/cpu_extensions.h"

namespace sfrt::profiling {
namespace {

class PeakDotTest : public ::testing::TestWithParam<DotType> {};

TEST_P(PeakDotTest, GivesAPositiveFiniteThroughputNamingTheInstruction) {
  const DotType type = GetParam();
  if (std::string why = PeakDotUnavailable(type); !why.empty()) {
    GTEST_SKIP() << DotTypeName(type) << " peak not available here: " << why;
  }
  struct Names {
    const char* loop;
    const char* instruction;
  };
  const Names names = type == DotType::kInt8      ? Names{"avx512_vnni", "vpdpbusd"}
                      : type == DotType::kInt16   ? Names{"avx512_vnni", "vpdpwssd"}
                      : type == DotType::kBf16    ? Names{"avx512_bf16", "vdpbf16ps"}
                      : type == DotType::kAmxInt8 ? Names{"amx_int8", "tdpbusd"}
                                                  : Names{"amx_bf16", "tdpbf16ps"};
  for (int threads : {1, 2}) {
    SCOPED_TRACE(threads);
    Result<PeakDot> peak = MeasurePeakDot(type, threads, 0.01);
    ASSERT_TRUE(peak.ok()) << peak.message();
    EXPECT_EQ(peak->type, type);
    EXPECT_EQ(peak->threads, threads);
    EXPECT_TRUE(std::isfinite(peak->gops));
    EXPECT_GT(peak->gops, 0.0);
    EXPECT_DOUBLE_EQ(peak->gmacs, peak->gops / 2);
    EXPECT_NE(peak->kernel.find(names.loop), std::string::npos) << peak->kernel;
    EXPECT_NE(peak->kernel.find(names.instruction), std::string::npos) << peak->kernel;
  }
}

TEST_P(PeakDotTest, FailsWithTheReasonWhereUnavailableAndOnZeroThreads) {
  const DotType type = GetParam();
  Result<PeakDot> none = MeasurePeakDot(type, 0, 0.01);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.message().find("threads"), std::string::npos) << none.message();
  const std::string why = PeakDotUnavailable(type);
  if (why.empty()) return;  // runs here: the test above measures it
  Result<PeakDot> missing = MeasurePeakDot(type, 1, 0.01);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find("not available (" + why + ")"), std::string::npos)
      << missing.message();
}

INSTANTIATE_TEST_SUITE_P(Types, PeakDotTest,
                         ::testing::Values(DotType::kInt8, DotType::kInt16, DotType::kBf16,
                                           DotType::kAmxInt8, DotType::kAmxBf16),
                         [](const ::testing::TestParamInfo<DotType>& param) {
                           return std::string(DotTypeName(param.param));
                         });

TEST(CpuExtensions, AnswersAreStableAndNameTheFailedCheck) {
  // Cached: the same answer twice (AMX's permission request is made at most once).
  EXPECT_EQ(internal::Avx512VnniMissing(), internal::Avx512VnniMissing());
  EXPECT_EQ(internal::Avx512Bf16Missing(), internal::Avx512Bf16Missing());
  EXPECT_EQ(AmxUnavailable(), AmxUnavailable());
#if defined(__x86_64__)
  for (const std::string& why :
       {internal::Avx512VnniMissing(), internal::Avx512Bf16Missing(), internal::AmxMissing()}) {
    if (why.empty()) continue;
    EXPECT_TRUE(why.find("CPUID") != std::string::npos || why.find("XCR0") != std::string::npos ||
                why.find("arch_prctl") != std::string::npos)
        << why;
  }
#else
  EXPECT_EQ(AmxUnavailable(), "not an x86-64 CPU");
#endif
}

}  // namespace
}  // namespace sfrt::profiling
