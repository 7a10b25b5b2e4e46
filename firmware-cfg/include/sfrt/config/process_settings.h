// Applying a profile's process settings at `sfrt run --config` (issue #6): CPU affinity and
// SCHED_FIFO priority per pipeline stage, mlockall, and the memory cap.
//
// A setting the process may not apply is never an error: CheckCapabilities() (capabilities.h)
// decides up front from a ProcessCapabilities snapshot which settings are not permitted; those
// are not attempted and are reported with the warning that names the fix. The others are
// attempted through ThreadOps; a call that still fails (e.g. a container without the capability
// the snapshot claims) is reported as not applied with the system's reason. Either way the run
// continues without the setting. Outcomes() lists every setting the profile asks for, applied or
// not, for the start banner and the final summary.
//
// The seams: tests pass a hand-made ProcessCapabilities (e.g. no CAP_SYS_NICE) and ThreadOps
// that record calls instead of making them, so the outcome does not depend on who runs the test.
//
// Stage threads: ApplyToCurrentThread(stage) is called first on each stage's thread. Threads a
// thread creates inherit its affinity and policy (Linux, PTHREAD_INHERIT_SCHED), so applying the
// infer stage's settings on the thread that creates the runtime's Session also places its thread
// pool. Every call sets both affinity and policy explicitly (a stage without settings gets the
// process's whole CPU set and SCHED_OTHER), so no stage keeps what it inherited.
//
// Thread-safety: ApplyToCurrentThread() may be called concurrently; the rest from one thread.
#pragma once

#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "sfrt/config/capabilities.h"
#include "sfrt/config/profile.h"

namespace sfrt::config {

// The system calls, replaceable in tests. Each returns 0 or an errno value.
struct ThreadOps {
  std::function<int(const std::vector<int>& cpus)> set_affinity;  // calling thread
  std::function<int(int priority)> set_fifo;                      // SCHED_FIFO, calling thread
  std::function<int()> set_other;                                 // SCHED_OTHER, calling thread
  std::function<int()> lock_all;                                  // mlockall(CURRENT | FUTURE)
  std::function<int(unsigned long long bytes)> cap_memory;        // setrlimit(RLIMIT_DATA)
  static ThreadOps System();
};

struct SettingOutcome {
  std::string setting;  // key path: "stages.infer.cpus", "memory.mlockall", ...
  std::string value;    // as asked: "0-1", "SCHED_FIFO 40", "true", "512 MiB"
  bool applied = false;
  std::string note;  // why not, and the fix (empty when applied)
};

class ProcessSettings {
 public:
  ProcessSettings(const DeploymentProfile& profile, const ProcessCapabilities& caps,
                  ThreadOps ops = ThreadOps::System());

  // mlockall and the memory cap. Call once, before the pipeline starts.
  void ApplyProcessWide();
  // Affinity and scheduling of the calling thread for `stage` (0 capture .. 3 output).
  void ApplyToCurrentThread(int stage);
  // Whether any stage asks for CPUs or a priority (otherwise ApplyToCurrentThread does nothing).
  bool has_thread_settings() const { return has_thread_settings_; }

  // One entry per setting the profile asks for, in profile order; a stage's entry is filled
  // the first time that stage's settings are applied.
  std::vector<SettingOutcome> Outcomes() const;
  // The warnings for settings not applied, "setting: note".
  std::vector<std::string> Warnings() const;

 private:
  void Set(const std::string& setting, bool applied, const std::string& note);

  DeploymentProfile profile_;
  ProcessCapabilities caps_;
  ThreadOps ops_;
  bool has_thread_settings_ = false;
  std::vector<CapabilityWarning> refused_;  // CheckCapabilities: not attempted
  mutable std::mutex mu_;
  std::vector<SettingOutcome> outcomes_;
  std::vector<bool> decided_;
};

}  // namespace sfrt::config
