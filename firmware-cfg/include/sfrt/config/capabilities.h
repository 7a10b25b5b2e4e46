// Which of a profile's process settings this process may apply: SCHED_FIFO priorities, mlockall
// and CPU affinity. A setting the process may not apply is not an error: the pipeline runs
// without it and reports a warning that names the setting and the fix.
//
// The seam: QueryProcessCapabilities() reads the system (effective capabilities from
// /proc/self/status, getrlimit, sched_getaffinity); CheckCapabilities() is a pure function of
// that snapshot, so tests pass a hand-made ProcessCapabilities.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "sfrt/config/profile.h"

namespace sfrt::config {

// RLIM_INFINITY as an unsigned 64-bit value: "unlimited".
inline constexpr uint64_t kUnlimited = ~uint64_t{0};

struct ProcessCapabilities {
  bool cap_sys_nice = false;        // CAP_SYS_NICE in the effective set
  bool cap_ipc_lock = false;        // CAP_IPC_LOCK in the effective set
  uint64_t rlimit_rtprio = 0;       // soft RLIMIT_RTPRIO (highest SCHED_FIFO priority allowed)
  uint64_t rlimit_memlock = 0;      // soft RLIMIT_MEMLOCK in bytes, kUnlimited when unlimited
  std::vector<int> available_cpus;  // sched_getaffinity of the process, ascending
};

// Reads the calling process's capabilities, limits and CPU set.
ProcessCapabilities QueryProcessCapabilities();

// Parses the "CapEff:" line of /proc/<pid>/status text into the capability mask; nullopt when
// the line is absent or malformed.
std::optional<uint64_t> ParseEffectiveCapabilities(const std::string& proc_status_text);

struct CapabilityWarning {
  std::string setting;           // key path: "stages.infer.priority", "memory.mlockall", ...
  std::string message;           // what cannot be applied, why, what happens instead, and the fix
  std::string ToString() const;  // "<setting>: <message>"
};

// Every process-level setting of `profile` that `caps` does not permit, in profile order.
std::vector<CapabilityWarning> CheckCapabilities(const DeploymentProfile& profile,
                                                 const ProcessCapabilities& caps);

// "0-3,6" style list of CPU numbers.
std::string FormatCpuList(const std::vector<int>& cpus);

}  // namespace sfrt::config
