#include "sfrt/config/capabilities.h"

#include <sched.h>
#include <sys/resource.h>

#include <algorithm>
#include <fstream>
#include <sstream>

namespace sfrt::config {
namespace {

constexpr int kCapIpcLock = 14;  // linux/capability.h
constexpr int kCapSysNice = 23;

uint64_t SoftLimit(int resource) {
  struct rlimit limit {};
  if (getrlimit(resource, &limit) != 0) return 0;
  return limit.rlim_cur == RLIM_INFINITY ? kUnlimited : static_cast<uint64_t>(limit.rlim_cur);
}

std::string Bytes(uint64_t bytes) {
  if (bytes == kUnlimited) return "unlimited";
  if (bytes >= (1ull << 20) && bytes % (1ull << 20) == 0) {
    return std::to_string(bytes >> 20) + " MiB";
  }
  if (bytes >= 1024 && bytes % 1024 == 0) return std::to_string(bytes >> 10) + " KiB";
  return std::to_string(bytes) + " bytes";
}

}  // namespace

std::string CapabilityWarning::ToString() const { return setting + ": " + message; }

std::optional<uint64_t> ParseEffectiveCapabilities(const std::string& proc_status_text) {
  std::istringstream in(proc_status_text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("CapEff:", 0) != 0) continue;
    std::string hex = line.substr(7);
    hex.erase(0, hex.find_first_not_of(" \t"));
    while (!hex.empty() && (hex.back() == ' ' || hex.back() == '\t' || hex.back() == '\r')) {
      hex.pop_back();
    }
    if (hex.empty() || hex.size() > 16) return std::nullopt;
    uint64_t mask = 0;
    for (char ch : hex) {
      int digit;
      if (ch >= '0' && ch <= '9') {
        digit = ch - '0';
      } else if (ch >= 'a' && ch <= 'f') {
        digit = ch - 'a' + 10;
      } else if (ch >= 'A' && ch <= 'F') {
        digit = ch - 'A' + 10;
      } else {
        return std::nullopt;
      }
      mask = (mask << 4) | static_cast<uint64_t>(digit);
    }
    return mask;
  }
  return std::nullopt;
}

ProcessCapabilities QueryProcessCapabilities() {
  ProcessCapabilities caps;
  std::ifstream status("/proc/self/status");
  std::stringstream text;
  text << status.rdbuf();
  if (auto mask = ParseEffectiveCapabilities(text.str())) {
    caps.cap_sys_nice = (*mask >> kCapSysNice) & 1;
    caps.cap_ipc_lock = (*mask >> kCapIpcLock) & 1;
  }
  caps.rlimit_rtprio = SoftLimit(RLIMIT_RTPRIO);
  caps.rlimit_memlock = SoftLimit(RLIMIT_MEMLOCK);
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) {
    for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
      if (CPU_ISSET(cpu, &set)) caps.available_cpus.push_back(cpu);
    }
  }
  return caps;
}

std::string FormatCpuList(const std::vector<int>& cpus) {
  std::vector<int> sorted = cpus;
  std::sort(sorted.begin(), sorted.end());
  std::string out;
  for (size_t i = 0; i < sorted.size();) {
    size_t j = i;
    while (j + 1 < sorted.size() && sorted[j + 1] == sorted[j] + 1) ++j;
    if (!out.empty()) out += ",";
    out += std::to_string(sorted[i]);
    if (j > i) out += "-" + std::to_string(sorted[j]);
    i = j + 1;
  }
  return out.empty() ? "none" : out;
}

std::vector<CapabilityWarning> CheckCapabilities(const DeploymentProfile& profile,
                                                 const ProcessCapabilities& caps) {
  std::vector<CapabilityWarning> warnings;
  for (int i = 0; i < kStageCount; ++i) {
    const StageSettings& st = profile.stages[i];
    const std::string stage = std::string("stages.") + StageName(static_cast<Stage>(i));
    if (st.rt_priority && !caps.cap_sys_nice &&
        caps.rlimit_rtprio < static_cast<uint64_t>(*st.rt_priority)) {
      const std::string prio = std::to_string(*st.rt_priority);
      warnings.push_back(
          {stage + ".priority",
           "SCHED_FIFO priority " + prio +
               " cannot be applied: the process lacks CAP_SYS_NICE and RLIMIT_RTPRIO is " +
               std::to_string(caps.rlimit_rtprio) +
               "; the stage runs under SCHED_OTHER. Fix: grant CAP_SYS_NICE (setcap "
               "cap_sys_nice+ep on the binary, or AmbientCapabilities=CAP_SYS_NICE in the systemd "
               "unit) or raise the limit to at least " +
               prio + " (LimitRTPRIO=" + prio + " in the unit, or '<user> - rtprio " + prio +
               "' in /etc/security/limits.conf)"});
    }
    std::vector<int> missing;
    for (int cpu : st.cpus) {
      if (!std::binary_search(caps.available_cpus.begin(), caps.available_cpus.end(), cpu)) {
        missing.push_back(cpu);
      }
    }
    if (!missing.empty()) {
      warnings.push_back(
          {stage + ".cpus",
           "CPU " + FormatCpuList(missing) +
               " does not exist or is not available to this process (available: " +
               FormatCpuList(caps.available_cpus) +
               "); the stage runs without that CPU in its affinity. Fix: list only CPUs in " +
               FormatCpuList(caps.available_cpus) +
               ", or widen the process's CPU set (taskset, cpuset cgroup, CPUAffinity= in the "
               "unit)"});
    }
  }
  if (profile.mlockall && !caps.cap_ipc_lock) {
    const uint64_t need =
        profile.memory_cap_mib ? static_cast<uint64_t>(*profile.memory_cap_mib) << 20 : kUnlimited;
    if (caps.rlimit_memlock < need) {
      const std::string need_text = profile.memory_cap_mib ? "memory.cap_mib (" + Bytes(need) + ")"
                                                           : "unlimited (no cap_mib)";
      const std::string limit_value =
          profile.memory_cap_mib ? std::to_string(need) : std::string("infinity");
      warnings.push_back(
          {"memory.mlockall",
           "mlockall cannot lock the process's memory: the process lacks CAP_IPC_LOCK and "
           "RLIMIT_MEMLOCK is " +
               Bytes(caps.rlimit_memlock) + ", below " + need_text +
               "; pages stay swappable and page faults may add latency. Fix: grant "
               "CAP_IPC_LOCK (setcap cap_ipc_lock+ep, or AmbientCapabilities=CAP_IPC_LOCK) or "
               "raise the limit (LimitMEMLOCK=" +
               limit_value + " in the systemd unit, or '<user> - memlock " +
               (profile.memory_cap_mib ? std::to_string(need >> 10) : std::string("unlimited")) +
               "' in /etc/security/limits.conf, which counts KiB)"});
    }
  }
  return warnings;
}

}  // namespace sfrt::config
