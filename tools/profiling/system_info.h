// What the process and the machine did around a measurement: page faults, context switches and
// CPU migrations (to explain latency spikes), and how this binary was built and where it runs.
#pragma once

#include <cstdint>
#include <string>

namespace sfrt::profiling {

// getrusage(RUSAGE_SELF): the whole process, every thread. Counters only grow; subtract two
// snapshots for what happened in between.
struct ResourceUsage {
  int64_t minor_faults = 0;          // page faults served without I/O
  int64_t major_faults = 0;          // page faults that read from disk
  int64_t voluntary_switches = 0;    // a thread blocked (waited for work, I/O, a lock)
  int64_t involuntary_switches = 0;  // the scheduler preempted a thread
  int64_t max_rss_kib = 0;           // peak resident set so far (not a counter)
};
ResourceUsage ReadResourceUsage();
// Counter differences a - b (max_rss_kib: a's).
ResourceUsage operator-(const ResourceUsage& a, const ResourceUsage& b);

// CPU migrations of this process's threads: perf_event_open(PERF_COUNT_SW_CPU_MIGRATIONS) on
// the calling thread with inherit, so threads created after Open() count too (open it before
// creating thread pools). Needs no privilege at perf_event_paranoid <= 2; where the kernel or a
// container refuses it, available() is false and unavailable_reason() says why.
class MigrationCounter {
 public:
  MigrationCounter();  // opens the counter
  ~MigrationCounter();
  MigrationCounter(const MigrationCounter&) = delete;
  MigrationCounter& operator=(const MigrationCounter&) = delete;

  bool available() const { return fd_ >= 0; }
  const std::string& unavailable_reason() const { return reason_; }
  // Migrations so far (this thread and its descendants since Open()); -1 when unavailable.
  int64_t Read() const;

 private:
  int fd_ = -1;
  std::string reason_;
};

// Fixed at configure/compile time (tools/profiling/build_info.h.in).
struct BuildInfo {
  std::string compiler;      // "GNU 12.2.0 (g++ 12.2.0)"
  std::string build_type;    // CMAKE_BUILD_TYPE, e.g. "Release"
  std::string cxx_flags;     // CMAKE_CXX_FLAGS + CMAKE_CXX_FLAGS_<BUILD_TYPE>
  std::string version;       // project version, "0.1.0"
  std::string git_describe;  // `git describe --always --dirty` at configure time, or "unknown"
  std::string system;        // CMAKE_SYSTEM_PROCESSOR, "x86_64"
};
const BuildInfo& GetBuildInfo();
// The extra compiler flags the runtime's kernels for `isa_name` ("avx2", "avx512", "avx512amx":
// its AMX kernels, the rest being avx512's, "neon") were built with; "" for "ref" (the build's own
// flags) or an ISA not in this build.
std::string IsaFlags(const std::string& isa_name);

// The CPU's model name from /proc/cpuinfo ("model name" on x86, else "Hardware"/"CPU part"
// lines on ARM), or "unknown".
std::string CpuModel();
// CPUs this process may run on (sched_getaffinity), or 0 if unknown.
int AvailableCpus();

}  // namespace sfrt::profiling
