#include "sfrt/config/process_settings.h"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace sfrt::config {
namespace {

std::string StageKey(int stage, const char* what) {
  return std::string("stages.") + StageName(static_cast<Stage>(stage)) + "." + what;
}

std::string Errno(int err) { return std::strerror(err); }

}  // namespace

ThreadOps ThreadOps::System() {
  ThreadOps ops;
  ops.set_affinity = [](const std::vector<int>& cpus) {
    cpu_set_t set;
    CPU_ZERO(&set);
    for (int cpu : cpus) {
      if (cpu >= 0 && cpu < CPU_SETSIZE) CPU_SET(cpu, &set);
    }
    return pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
  };
  ops.set_fifo = [](int priority) {
    sched_param param{};
    param.sched_priority = priority;
    return pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  };
  ops.set_other = [] {
    sched_param param{};
    param.sched_priority = 0;
    return pthread_setschedparam(pthread_self(), SCHED_OTHER, &param);
  };
  ops.lock_all = [] { return mlockall(MCL_CURRENT | MCL_FUTURE) == 0 ? 0 : errno; };
  ops.cap_memory = [](unsigned long long bytes) {
    struct rlimit limit {};
    if (getrlimit(RLIMIT_DATA, &limit) != 0) return errno;
    limit.rlim_cur = static_cast<rlim_t>(bytes);
    if (limit.rlim_max != RLIM_INFINITY && limit.rlim_max < limit.rlim_cur) return EPERM;
    return setrlimit(RLIMIT_DATA, &limit) == 0 ? 0 : errno;
  };
  return ops;
}

ProcessSettings::ProcessSettings(const DeploymentProfile& profile, const ProcessCapabilities& caps,
                                 ThreadOps ops)
    : profile_(profile), caps_(caps), ops_(std::move(ops)) {
  std::sort(caps_.available_cpus.begin(), caps_.available_cpus.end());
  refused_ = CheckCapabilities(profile_, caps_);
  for (int i = 0; i < kStageCount; ++i) {
    const StageSettings& st = profile_.stages[i];
    if (!st.cpus.empty()) {
      outcomes_.push_back(
          {StageKey(i, "cpus"), FormatCpuList(st.cpus), false, "the stage did not start"});
      has_thread_settings_ = true;
    }
    if (st.rt_priority) {
      outcomes_.push_back({StageKey(i, "priority"), "SCHED_FIFO " + std::to_string(*st.rt_priority),
                           false, "the stage did not start"});
      has_thread_settings_ = true;
    }
  }
  if (profile_.mlockall) {
    outcomes_.push_back({"memory.mlockall", "true", false, "not attempted"});
  }
  if (profile_.memory_cap_mib) {
    outcomes_.push_back({"memory.cap_mib", std::to_string(*profile_.memory_cap_mib) + " MiB", false,
                         "not attempted"});
  }
  decided_.assign(outcomes_.size(), false);
}

void ProcessSettings::Set(const std::string& setting, bool applied, const std::string& note) {
  std::lock_guard<std::mutex> lock(mu_);
  for (size_t i = 0; i < outcomes_.size(); ++i) {
    if (outcomes_[i].setting != setting || decided_[i]) continue;
    outcomes_[i].applied = applied;
    outcomes_[i].note = note;
    decided_[i] = true;
  }
}

void ProcessSettings::ApplyProcessWide() {
  auto refused = [&](const std::string& key) -> const CapabilityWarning* {
    for (const CapabilityWarning& w : refused_) {
      if (w.setting == key) return &w;
    }
    return nullptr;
  };
  if (profile_.mlockall) {
    if (const CapabilityWarning* w = refused("memory.mlockall")) {
      Set("memory.mlockall", false, w->message);
    } else if (int rc = ops_.lock_all(); rc != 0) {
      Set("memory.mlockall", false,
          "mlockall failed: " + Errno(rc) +
              "; pages stay swappable. Fix: grant CAP_IPC_LOCK (setcap cap_ipc_lock+ep) or raise "
              "RLIMIT_MEMLOCK (LimitMEMLOCK=infinity in the systemd unit)");
    } else {
      Set("memory.mlockall", true, "");
    }
  }
  if (profile_.memory_cap_mib) {
    const unsigned long long bytes = static_cast<unsigned long long>(*profile_.memory_cap_mib)
                                     << 20;
    if (int rc = ops_.cap_memory(bytes); rc != 0) {
      Set("memory.cap_mib", false,
          "setrlimit(RLIMIT_DATA) failed: " + Errno(rc) +
              "; the process runs without the cap. Fix: raise the hard limit (LimitDATA= in the "
              "systemd unit, or 'ulimit -H -d') to at least the cap");
    } else {
      Set("memory.cap_mib", true, "");
    }
  }
}

void ProcessSettings::ApplyToCurrentThread(int stage) {
  if (!has_thread_settings_ || stage < 0 || stage >= kStageCount) return;
  const StageSettings& st = profile_.stages[stage];
  auto refused = [&](const std::string& key) -> const CapabilityWarning* {
    for (const CapabilityWarning& w : refused_) {
      if (w.setting == key) return &w;
    }
    return nullptr;
  };

  // Affinity: the stage's CPUs that exist, else the process's whole set.
  std::vector<int> cpus;
  for (int cpu : st.cpus) {
    if (std::binary_search(caps_.available_cpus.begin(), caps_.available_cpus.end(), cpu)) {
      cpus.push_back(cpu);
    }
  }
  if (cpus.empty()) cpus = caps_.available_cpus;
  const int affinity_rc = cpus.empty() ? 0 : ops_.set_affinity(cpus);
  if (!st.cpus.empty()) {
    const std::string key = StageKey(stage, "cpus");
    if (affinity_rc != 0) {
      Set(key, false,
          "sched_setaffinity failed: " + Errno(affinity_rc) +
              "; the stage runs on any CPU. Fix: list only CPUs in " +
              FormatCpuList(caps_.available_cpus) + " or widen the process's CPU set");
    } else if (const CapabilityWarning* w = refused(key)) {
      Set(key, false, w->message);
    } else {
      Set(key, true, "");
    }
  }

  // Scheduling: SCHED_FIFO when asked and permitted, else SCHED_OTHER (not what was inherited).
  if (st.rt_priority) {
    const std::string key = StageKey(stage, "priority");
    if (const CapabilityWarning* w = refused(key)) {
      (void)ops_.set_other();
      Set(key, false, w->message);
    } else if (int rc = ops_.set_fifo(*st.rt_priority); rc != 0) {
      (void)ops_.set_other();
      Set(key, false,
          "pthread_setschedparam(SCHED_FIFO, " + std::to_string(*st.rt_priority) +
              ") failed: " + Errno(rc) +
              "; the stage runs under SCHED_OTHER. Fix: grant CAP_SYS_NICE (setcap "
              "cap_sys_nice+ep, or AmbientCapabilities=CAP_SYS_NICE) or raise RLIMIT_RTPRIO "
              "(LimitRTPRIO=" +
              std::to_string(*st.rt_priority) + ")");
    } else {
      Set(key, true, "");
    }
  } else {
    (void)ops_.set_other();
  }
}

std::vector<SettingOutcome> ProcessSettings::Outcomes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return outcomes_;
}

std::vector<std::string> ProcessSettings::Warnings() const {
  std::vector<std::string> out;
  for (const SettingOutcome& o : Outcomes()) {
    if (!o.applied) out.push_back(o.setting + ": " + o.note);
  }
  return out;
}

}  // namespace sfrt::config
