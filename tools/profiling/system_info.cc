#include "profiling/system_info.h"

#include <linux/perf_event.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "profiling/build_info.h"

namespace sfrt::profiling {

ResourceUsage ReadResourceUsage() {
  struct rusage u {};
  getrusage(RUSAGE_SELF, &u);
  ResourceUsage r;
  r.minor_faults = u.ru_minflt;
  r.major_faults = u.ru_majflt;
  r.voluntary_switches = u.ru_nvcsw;
  r.involuntary_switches = u.ru_nivcsw;
  r.max_rss_kib = u.ru_maxrss;
  return r;
}

ResourceUsage operator-(const ResourceUsage& a, const ResourceUsage& b) {
  ResourceUsage d;
  d.minor_faults = a.minor_faults - b.minor_faults;
  d.major_faults = a.major_faults - b.major_faults;
  d.voluntary_switches = a.voluntary_switches - b.voluntary_switches;
  d.involuntary_switches = a.involuntary_switches - b.involuntary_switches;
  d.max_rss_kib = a.max_rss_kib;
  return d;
}

namespace {

std::string ReadFirstLine(const char* path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

}  // namespace

MigrationCounter::MigrationCounter() {
  struct perf_event_attr attr;
  std::memset(&attr, 0, sizeof(attr));
  attr.size = sizeof(attr);
  attr.type = PERF_TYPE_SOFTWARE;
  attr.config = PERF_COUNT_SW_CPU_MIGRATIONS;
  attr.inherit = 1;
  long fd = syscall(SYS_perf_event_open, &attr, 0, -1, -1, 0);
  if (fd < 0 && (errno == EACCES || errno == EPERM)) {
    attr.exclude_kernel = 1;  // what perf_event_paranoid 2 still allows
    attr.exclude_hv = 1;
    fd = syscall(SYS_perf_event_open, &attr, 0, -1, -1, 0);
  }
  if (fd < 0) {
    const int err = errno;
    reason_ =
        std::string("perf_event_open(PERF_COUNT_SW_CPU_MIGRATIONS) failed: ") + std::strerror(err);
    const std::string paranoid = ReadFirstLine("/proc/sys/kernel/perf_event_paranoid");
    if (!paranoid.empty()) reason_ += " (kernel.perf_event_paranoid = " + paranoid + ")";
    if (err == ENOSYS) reason_ += " (no perf events in this kernel or blocked by seccomp)";
    return;
  }
  fd_ = static_cast<int>(fd);
}

MigrationCounter::~MigrationCounter() {
  if (fd_ >= 0) close(fd_);
}

int64_t MigrationCounter::Read() const {
  if (fd_ < 0) return -1;
  uint64_t value = 0;
  if (read(fd_, &value, sizeof(value)) != static_cast<ssize_t>(sizeof(value))) return -1;
  return static_cast<int64_t>(value);
}

const BuildInfo& GetBuildInfo() {
  static const BuildInfo info = [] {
    BuildInfo b;
    b.compiler = SFRT_BUILD_COMPILER;
#if defined(__clang__)
    b.compiler += " (clang " __clang_version__ ")";
#elif defined(__GNUC__)
    b.compiler += " (g++ " __VERSION__ ")";
#endif
    b.build_type = SFRT_BUILD_TYPE;
    b.cxx_flags = SFRT_BUILD_CXX_FLAGS;
    b.version = SFRT_BUILD_VERSION;
    b.git_describe = SFRT_BUILD_GIT_DESCRIBE;
    b.system = SFRT_BUILD_SYSTEM;
    return b;
  }();
  return info;
}

std::string IsaFlags(const std::string& isa_name) {
  if (isa_name == "avx2") return SFRT_BUILD_FLAGS_AVX2;
  if (isa_name == "avx512") return SFRT_BUILD_FLAGS_AVX512;
  if (isa_name == "avx512amx") return SFRT_BUILD_FLAGS_AVX512AMX;
  if (isa_name == "neon") return SFRT_BUILD_FLAGS_NEON;
  return "";
}

std::string CpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line, hardware, implementer, part;
  while (std::getline(in, line)) {
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string key = line.substr(0, colon);
    while (!key.empty() && (key.back() == ' ' || key.back() == '\t')) key.pop_back();
    std::string value = line.substr(colon + 1);
    while (!value.empty() && value.front() == ' ') value.erase(value.begin());
    if (key == "model name" && !value.empty()) return value;
    if (key == "Hardware" && hardware.empty()) hardware = value;
    if (key == "CPU implementer" && implementer.empty()) implementer = value;
    if (key == "CPU part" && part.empty()) part = value;
  }
  if (!hardware.empty()) return hardware;
  if (!implementer.empty()) return "CPU implementer " + implementer + ", part " + part;
  return "unknown";
}

int AvailableCpus() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) != 0) return 0;
  return CPU_COUNT(&set);
}

}  // namespace sfrt::profiling
