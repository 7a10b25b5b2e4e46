// The capability check (sfrt/config/capabilities.h), driven through hand-made
// ProcessCapabilities snapshots, and the /proc parsing and system query behind it.
#include "sfrt/config/capabilities.h"

#include <gtest/gtest.h>
#include <sched.h>

#include <algorithm>
#include <string>
#include <vector>

namespace sfrt::config {
namespace {

DeploymentProfile ProfileWith(std::optional<int> capture_priority,
                              std::optional<int> infer_priority, std::vector<int> infer_cpus,
                              bool mlockall, std::optional<long long> cap_mib) {
  DeploymentProfile p;
  p.stages[static_cast<int>(Stage::kSource)].rt_priority = capture_priority;
  p.stages[static_cast<int>(Stage::kInfer)].rt_priority = infer_priority;
  p.stages[static_cast<int>(Stage::kInfer)].cpus = std::move(infer_cpus);
  p.mlockall = mlockall;
  p.memory_cap_mib = cap_mib;
  return p;
}

ProcessCapabilities Unprivileged() {
  ProcessCapabilities caps;
  caps.rlimit_rtprio = 0;
  caps.rlimit_memlock = 64 * 1024;  // the common default: 64 KiB
  caps.available_cpus = {0, 1};
  return caps;
}

std::vector<std::string> Settings(const std::vector<CapabilityWarning>& warnings) {
  std::vector<std::string> out;
  for (const CapabilityWarning& w : warnings) out.push_back(w.setting);
  return out;
}

TEST(ParseEffectiveCapabilities, ReadsTheCapEffHexMask) {
  const std::string status =
      "Name:\tsfrt\nCapInh:\t0000000000000000\nCapPrm:\t000001ffffffffff\n"
      "CapEff:\t0000000000804000\nCapBnd:\t000001ffffffffff\n";
  auto mask = ParseEffectiveCapabilities(status);
  ASSERT_TRUE(mask.has_value());
  EXPECT_EQ(*mask, (uint64_t{1} << 23) | (uint64_t{1} << 14));  // CAP_SYS_NICE | CAP_IPC_LOCK
}

TEST(ParseEffectiveCapabilities, RejectsAbsentOrMalformedLines) {
  EXPECT_FALSE(ParseEffectiveCapabilities("Name:\tsfrt\n").has_value());
  EXPECT_FALSE(ParseEffectiveCapabilities("CapEff:\t00zz\n").has_value());
  EXPECT_FALSE(ParseEffectiveCapabilities("CapEff:\t\n").has_value());
  EXPECT_FALSE(ParseEffectiveCapabilities("CapEff:\t00000000000000000\n").has_value());
}

TEST(CheckCapabilities, PrivilegedProcessGetsNoWarnings) {
  ProcessCapabilities caps;
  caps.cap_sys_nice = true;
  caps.cap_ipc_lock = true;
  caps.available_cpus = {0, 1, 2, 3};
  EXPECT_TRUE(CheckCapabilities(ProfileWith(80, 40, {2, 3}, true, std::nullopt), caps).empty());
}

TEST(CheckCapabilities, FifoPriorityNeedsCapSysNiceOrAHighEnoughRtprioLimit) {
  const DeploymentProfile p = ProfileWith(50, 40, {}, false, std::nullopt);
  ProcessCapabilities caps = Unprivileged();
  std::vector<CapabilityWarning> w = CheckCapabilities(p, caps);
  EXPECT_EQ(Settings(w),
            (std::vector<std::string>{"stages.source.priority", "stages.infer.priority"}));
  ASSERT_FALSE(w.empty());
  const std::string text = w[0].ToString();
  EXPECT_EQ(text.rfind("stages.source.priority: SCHED_FIFO priority 50 cannot be applied: the "
                       "process lacks CAP_SYS_NICE and RLIMIT_RTPRIO is 0; the stage runs under "
                       "SCHED_OTHER. Fix: grant CAP_SYS_NICE",
                       0),
            0u)
      << text;
  EXPECT_NE(text.find("LimitRTPRIO=50"), std::string::npos) << text;

  caps.rlimit_rtprio = 45;  // enough for infer (40), not for capture (50)
  EXPECT_EQ(Settings(CheckCapabilities(p, caps)),
            (std::vector<std::string>{"stages.source.priority"}));
  caps.rlimit_rtprio = 50;
  EXPECT_TRUE(CheckCapabilities(p, caps).empty());
  caps.rlimit_rtprio = 0;
  caps.cap_sys_nice = true;
  EXPECT_TRUE(CheckCapabilities(p, caps).empty());
}

TEST(CheckCapabilities, MlockallNeedsCapIpcLockOrAMemlockLimitAtLeastTheCap) {
  const DeploymentProfile capped = ProfileWith(std::nullopt, std::nullopt, {}, true, 512);
  ProcessCapabilities caps = Unprivileged();
  std::vector<CapabilityWarning> w = CheckCapabilities(capped, caps);
  ASSERT_EQ(Settings(w), (std::vector<std::string>{"memory.mlockall"}));
  const std::string text = w[0].ToString();
  EXPECT_NE(text.find("RLIMIT_MEMLOCK is 64 KiB, below memory.cap_mib (512 MiB)"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("LimitMEMLOCK=536870912"), std::string::npos) << text;
  EXPECT_NE(text.find("memlock 524288"), std::string::npos) << text;  // limits.conf counts KiB

  caps.rlimit_memlock = uint64_t{512} << 20;
  EXPECT_TRUE(CheckCapabilities(capped, caps).empty());
  caps.rlimit_memlock = (uint64_t{512} << 20) - 1;
  EXPECT_EQ(CheckCapabilities(capped, caps).size(), 1u);
  caps.cap_ipc_lock = true;
  EXPECT_TRUE(CheckCapabilities(capped, caps).empty());

  // No cap: only an unlimited limit (or CAP_IPC_LOCK) will do.
  const DeploymentProfile uncapped =
      ProfileWith(std::nullopt, std::nullopt, {}, true, std::nullopt);
  caps = Unprivileged();
  caps.rlimit_memlock = uint64_t{64} << 30;
  w = CheckCapabilities(uncapped, caps);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].message.find("below unlimited (no cap_mib)"), std::string::npos) << w[0].message;
  EXPECT_NE(w[0].message.find("LimitMEMLOCK=infinity"), std::string::npos) << w[0].message;
  caps.rlimit_memlock = kUnlimited;
  EXPECT_TRUE(CheckCapabilities(uncapped, caps).empty());

  // mlockall off: nothing to check.
  caps = Unprivileged();
  EXPECT_TRUE(
      CheckCapabilities(ProfileWith(std::nullopt, std::nullopt, {}, false, 512), caps).empty());
}

TEST(CheckCapabilities, AffinityCpusMustBeInTheProcessCpuSet) {
  const DeploymentProfile p = ProfileWith(std::nullopt, std::nullopt, {1, 2, 3, 7}, false, {});
  std::vector<CapabilityWarning> w = CheckCapabilities(p, Unprivileged());
  ASSERT_EQ(Settings(w), (std::vector<std::string>{"stages.infer.cpus"}));
  EXPECT_EQ(w[0].message.rfind("CPU 2-3,7 does not exist or is not available to this process "
                               "(available: 0-1); the stage runs without that CPU",
                               0),
            0u)
      << w[0].message;
}

TEST(FormatCpuList, CollapsesRuns) {
  EXPECT_EQ(FormatCpuList({0, 1, 2, 3}), "0-3");
  EXPECT_EQ(FormatCpuList({5, 0, 2, 3}), "0,2-3,5");
  EXPECT_EQ(FormatCpuList({}), "none");
}

TEST(QueryProcessCapabilities, ListsTheCpuThisThreadRunsOn) {
  const ProcessCapabilities caps = QueryProcessCapabilities();
  const int cpu = sched_getcpu();
  ASSERT_GE(cpu, 0);
  EXPECT_TRUE(std::binary_search(caps.available_cpus.begin(), caps.available_cpus.end(), cpu));
}

}  // namespace
}  // namespace sfrt::config
