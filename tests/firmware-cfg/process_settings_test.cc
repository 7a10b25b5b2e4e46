// Applying a profile's process settings (sfrt/config/process_settings.h) through the seams:
// hand-made ProcessCapabilities and ThreadOps that record calls instead of making them, so the
// outcome does not depend on who runs the test (root or not, container or not).
#include "sfrt/config/process_settings.h"

#include <gtest/gtest.h>

#include <cerrno>
#include <string>
#include <vector>

namespace sfrt::config {
namespace {

struct Calls {
  std::vector<std::vector<int>> affinity;
  std::vector<int> fifo;
  int other = 0;
  int lock_all = 0;
  std::vector<unsigned long long> cap;
  int fifo_result = 0;
  int lock_result = 0;
};

ThreadOps Recording(Calls* calls) {
  ThreadOps ops;
  ops.set_affinity = [calls](const std::vector<int>& cpus) {
    calls->affinity.push_back(cpus);
    return 0;
  };
  ops.set_fifo = [calls](int priority) {
    calls->fifo.push_back(priority);
    return calls->fifo_result;
  };
  ops.set_other = [calls] {
    ++calls->other;
    return 0;
  };
  ops.lock_all = [calls] {
    ++calls->lock_all;
    return calls->lock_result;
  };
  ops.cap_memory = [calls](unsigned long long bytes) {
    calls->cap.push_back(bytes);
    return 0;
  };
  return ops;
}

DeploymentProfile FifoProfile() {
  DeploymentProfile p;
  p.stages[static_cast<int>(Stage::kSource)].rt_priority = 50;
  p.stages[static_cast<int>(Stage::kInfer)].rt_priority = 40;
  p.stages[static_cast<int>(Stage::kInfer)].cpus = {1, 7};
  return p;
}

ProcessCapabilities Caps(bool sys_nice, bool ipc_lock) {
  ProcessCapabilities caps;
  caps.cap_sys_nice = sys_nice;
  caps.cap_ipc_lock = ipc_lock;
  caps.rlimit_rtprio = 0;
  caps.rlimit_memlock = 64 * 1024;
  caps.available_cpus = {0, 1};
  return caps;
}

const SettingOutcome* Find(const std::vector<SettingOutcome>& outcomes, const std::string& key) {
  for (const SettingOutcome& o : outcomes) {
    if (o.setting == key) return &o;
  }
  return nullptr;
}

TEST(ProcessSettings, FifoWithoutCapSysNiceIsNotAttemptedAndNamesTheFix) {
  Calls calls;
  ProcessSettings ps(FifoProfile(), Caps(/*sys_nice=*/false, false), Recording(&calls));
  ASSERT_TRUE(ps.has_thread_settings());
  ps.ApplyToCurrentThread(0);  // capture
  ps.ApplyToCurrentThread(2);  // infer
  EXPECT_TRUE(calls.fifo.empty()) << "SCHED_FIFO must not be attempted without permission";
  EXPECT_EQ(calls.other, 2);  // both threads explicitly back to SCHED_OTHER
  const std::vector<SettingOutcome> out = ps.Outcomes();
  for (const char* key : {"stages.source.priority", "stages.infer.priority"}) {
    const SettingOutcome* o = Find(out, key);
    ASSERT_NE(o, nullptr) << key;
    EXPECT_FALSE(o->applied) << key;
    EXPECT_NE(o->note.find("CAP_SYS_NICE"), std::string::npos) << o->note;
    EXPECT_NE(o->note.find("LimitRTPRIO"), std::string::npos) << o->note;
  }
  const std::vector<std::string> warnings = ps.Warnings();
  ASSERT_FALSE(warnings.empty());
  EXPECT_EQ(warnings[0].rfind("stages.source.priority: ", 0), 0u) << warnings[0];
}

TEST(ProcessSettings, FifoWithCapSysNiceIsAppliedAtTheProfilesPriority) {
  Calls calls;
  ProcessSettings ps(FifoProfile(), Caps(/*sys_nice=*/true, false), Recording(&calls));
  ps.ApplyToCurrentThread(2);
  ASSERT_EQ(calls.fifo, std::vector<int>({40}));
  const std::vector<SettingOutcome> outcomes = ps.Outcomes();
  const SettingOutcome* o = Find(outcomes, "stages.infer.priority");
  ASSERT_NE(o, nullptr);
  EXPECT_TRUE(o->applied);
  EXPECT_EQ(o->value, "SCHED_FIFO 40");
  // The capture stage has not started: its outcome says so.
  const SettingOutcome* c = Find(outcomes, "stages.source.priority");
  ASSERT_NE(c, nullptr);
  EXPECT_FALSE(c->applied);
  EXPECT_EQ(c->note, "the stage did not start");
}

TEST(ProcessSettings, FailedSchedCallIsReportedWithTheSystemsReasonAndFallsBack) {
  Calls calls;
  calls.fifo_result = EPERM;  // e.g. a container that drops CAP_SYS_NICE despite the snapshot
  ProcessSettings ps(FifoProfile(), Caps(true, false), Recording(&calls));
  ps.ApplyToCurrentThread(2);
  EXPECT_EQ(calls.other, 1);
  const std::vector<SettingOutcome> outcomes = ps.Outcomes();
  const SettingOutcome* o = Find(outcomes, "stages.infer.priority");
  ASSERT_NE(o, nullptr);
  EXPECT_FALSE(o->applied);
  EXPECT_NE(o->note.find("Operation not permitted"), std::string::npos) << o->note;
}

TEST(ProcessSettings, AffinityKeepsTheCpusThatExistAndReportsTheMissingOne) {
  Calls calls;
  ProcessSettings ps(FifoProfile(), Caps(true, false), Recording(&calls));
  ps.ApplyToCurrentThread(2);  // infer: cpus 1, 7; only 0 and 1 exist
  ps.ApplyToCurrentThread(3);  // output: no cpus -> the whole process set
  ASSERT_EQ(calls.affinity.size(), 2u);
  EXPECT_EQ(calls.affinity[0], std::vector<int>({1}));
  EXPECT_EQ(calls.affinity[1], std::vector<int>({0, 1}));
  const std::vector<SettingOutcome> outcomes = ps.Outcomes();
  const SettingOutcome* o = Find(outcomes, "stages.infer.cpus");
  ASSERT_NE(o, nullptr);
  EXPECT_FALSE(o->applied);
  EXPECT_EQ(o->value, "1,7");
  EXPECT_NE(o->note.find("CPU 7"), std::string::npos) << o->note;
}

TEST(ProcessSettings, MlockallNeedsCapIpcLockOrLimitAndTheCapIsSet) {
  DeploymentProfile p;
  p.mlockall = true;
  p.memory_cap_mib = 512;
  {
    Calls calls;
    ProcessSettings ps(p, Caps(false, /*ipc_lock=*/false), Recording(&calls));
    EXPECT_FALSE(ps.has_thread_settings());
    ps.ApplyProcessWide();
    EXPECT_EQ(calls.lock_all, 0);
    ASSERT_EQ(calls.cap, std::vector<unsigned long long>({512ull << 20}));
    const std::vector<SettingOutcome> outcomes = ps.Outcomes();
    const SettingOutcome* o = Find(outcomes, "memory.mlockall");
    ASSERT_NE(o, nullptr);
    EXPECT_FALSE(o->applied);
    EXPECT_NE(o->note.find("CAP_IPC_LOCK"), std::string::npos) << o->note;
    const SettingOutcome* cap = Find(outcomes, "memory.cap_mib");
    ASSERT_NE(cap, nullptr);
    EXPECT_TRUE(cap->applied);
  }
  {
    Calls calls;
    ProcessSettings ps(p, Caps(false, /*ipc_lock=*/true), Recording(&calls));
    ps.ApplyProcessWide();
    EXPECT_EQ(calls.lock_all, 1);
    const std::vector<SettingOutcome> outcomes = ps.Outcomes();
    ASSERT_NE(Find(outcomes, "memory.mlockall"), nullptr);
    EXPECT_TRUE(Find(outcomes, "memory.mlockall")->applied);
  }
}

TEST(ProcessSettings, NoThreadSettingsMeansNoSystemCalls) {
  Calls calls;
  ProcessSettings ps(DeploymentProfile{}, Caps(false, false), Recording(&calls));
  for (int s = 0; s < kStageCount; ++s) ps.ApplyToCurrentThread(s);
  ps.ApplyProcessWide();
  EXPECT_TRUE(calls.affinity.empty());
  EXPECT_TRUE(calls.fifo.empty());
  EXPECT_EQ(calls.other, 0);
  EXPECT_TRUE(ps.Outcomes().empty());
}

}  // namespace
}  // namespace sfrt::config
