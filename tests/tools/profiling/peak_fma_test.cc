// tools/profiling/peak_fma.h and system_info.h: the peak loop runs on every ISA this CPU has and
// gives a positive, finite throughput; counters and build metadata are filled.
#include "profiling/peak_fma.h"

#include <gtest/gtest.h>
#include <sys/mman.h>

#include <cmath>
#include <cstring>

#include "profiling/system_info.h"

namespace sfrt::profiling {
namespace {

TEST(PeakFma, EverySupportedIsaGivesAPositiveFiniteThroughput) {
  for (Isa isa : SupportedIsas()) {
    SCOPED_TRACE(IsaName(isa));
    Result<PeakFma> peak = MeasurePeakFma(isa, 1, 0.01);
    ASSERT_TRUE(peak.ok()) << peak.message();
    EXPECT_EQ(peak->isa, isa);
    EXPECT_TRUE(std::isfinite(peak->gflops));
    EXPECT_GT(peak->gflops, 0.0);
    // avx512amx's float32 loop is avx512's.
    const std::string vector_isa = isa == Isa::kAvx512Amx ? "avx512" : IsaName(isa);
    EXPECT_NE(peak->kernel.find(vector_isa), std::string::npos) << peak->kernel;
  }
}

TEST(PeakFma, TwoThreadsGiveAPositiveFiniteThroughput) {
  Result<PeakFma> peak = MeasurePeakFma(Isa::kAuto, 2, 0.01);
  ASSERT_TRUE(peak.ok()) << peak.message();
  EXPECT_EQ(peak->isa, BestIsa());
  EXPECT_EQ(peak->threads, 2);
  EXPECT_TRUE(std::isfinite(peak->gflops));
  EXPECT_GT(peak->gflops, 0.0);
}

TEST(PeakFma, RejectsZeroThreadsAndIsasTheCpuLacks) {
  Result<PeakFma> none = MeasurePeakFma(Isa::kRef, 0, 0.01);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.message().find("threads"), std::string::npos) << none.message();
  // x86-64 lacks NEON, aarch64 lacks AVX2: at least one is missing.
  for (Isa isa : {Isa::kAvx2, Isa::kAvx512, Isa::kNeon, Isa::kAvx512Amx}) {
    if (IsaSupported(isa)) continue;
    Result<PeakFma> missing = MeasurePeakFma(isa, 1, 0.01);
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.message().find(IsaName(isa)), std::string::npos) << missing.message();
  }
}

TEST(ResourceUsage, TouchingFreshPagesCountsMinorFaults) {
  constexpr size_t kBytes = 16 << 20;
  void* p = mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(p, MAP_FAILED);
  const ResourceUsage before = ReadResourceUsage();
  std::memset(p, 1, kBytes);
  const ResourceUsage delta = ReadResourceUsage() - before;
  munmap(p, kBytes);
  // 4096 pages of 4 KiB (fewer with transparent huge pages, at least one fault either way).
  EXPECT_GE(delta.minor_faults, 1);
  EXPECT_GE(delta.major_faults, 0);
  EXPECT_GT(delta.max_rss_kib, 0);
}

TEST(MigrationCounter, CountsOrSaysWhyNot) {
  MigrationCounter counter;
  if (counter.available()) {
    EXPECT_GE(counter.Read(), 0);
    EXPECT_TRUE(counter.unavailable_reason().empty());
  } else {
    EXPECT_EQ(counter.Read(), -1);
    EXPECT_NE(counter.unavailable_reason().find("perf_event_open"), std::string::npos);
  }
}

TEST(BuildInfo, NamesCompilerVersionAndCpu) {
  const BuildInfo& b = GetBuildInfo();
  EXPECT_FALSE(b.compiler.empty());
  EXPECT_EQ(b.version, SFRT_TEST_PROJECT_VERSION);
  EXPECT_FALSE(b.git_describe.empty());
  EXPECT_FALSE(CpuModel().empty());
  EXPECT_GE(AvailableCpus(), 1);
  EXPECT_EQ(IsaFlags("ref"), "");
  if (IsaSupported(Isa::kAvx512)) {
    EXPECT_NE(IsaFlags("avx512").find("-mavx512f"), std::string::npos);
  }
}

}  // namespace
}  // namespace sfrt::profiling
