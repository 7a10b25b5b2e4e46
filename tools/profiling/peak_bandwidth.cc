#include "profiling/peak_bandwidth.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <thread>
#include <vector>

namespace sfrt::profiling {
namespace {

using Clock = std::chrono::steady_clock;

// 64 bytes: one cache line per load, whatever vector width the compiler splits it into.
typedef uint64_t Line __attribute__((vector_size(64)));

// The sum of `lines` cache lines from `p`, four independent accumulators (the loads are not
// serialised behind one add chain).
uint64_t SumLines(const Line* p, size_t lines) {
  Line a = {}, b = {}, c = {}, d = {};
  size_t i = 0;
  for (; i + 4 <= lines; i += 4) {
    a += p[i];
    b += p[i + 1];
    c += p[i + 2];
    d += p[i + 3];
  }
  for (; i < lines; ++i) a += p[i];
  const Line s = a + b + c + d;
  uint64_t total = 0;
  for (int k = 0; k < 8; ++k) total += s[k];
  return total;
}

struct FreeDeleter {
  void operator()(void* p) const { std::free(p); }
};

// Each thread (the caller is thread 0) writes its slice once, waits for `go`, then sums it
// `passes` times. Returns the seconds from the common start to the last thread's end.
double TimePasses(const Line* base, size_t lines_per_thread, int threads, int passes,
                  std::atomic<uint64_t>* sink) {
  std::atomic<bool> go{false};
  std::atomic<int> ready{0};
  std::vector<std::thread> pool;
  const auto work = [&](int t) {
    const Line* slice = base + static_cast<size_t>(t) * lines_per_thread;
    uint64_t s = 0;
    for (int p = 0; p < passes; ++p) s += SumLines(slice, lines_per_thread);
    sink->fetch_add(s, std::memory_order_relaxed);
  };
  for (int t = 1; t < threads; ++t) {
    pool.emplace_back([&, t] {
      ready.fetch_add(1);
      while (!go.load(std::memory_order_acquire)) std::this_thread::yield();
      work(t);
    });
  }
  while (ready.load() < threads - 1) std::this_thread::yield();
  const auto start = Clock::now();
  go.store(true, std::memory_order_release);
  work(0);
  for (std::thread& th : pool) th.join();
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

Result<PeakBandwidth> MeasureReadBandwidth(int threads, double seconds, size_t buffer_bytes) {
  if (threads < 1) {
    return Status::Error("peak read bandwidth: threads must be >= 1, got " +
                         std::to_string(threads));
  }
  const size_t lines_per_thread =
      std::max<size_t>(1, buffer_bytes / sizeof(Line) / static_cast<size_t>(threads));
  const size_t bytes = lines_per_thread * static_cast<size_t>(threads) * sizeof(Line);
  std::unique_ptr<void, FreeDeleter> buffer(std::aligned_alloc(sizeof(Line), bytes));
  if (buffer == nullptr) {
    return Status::Error("peak read bandwidth: cannot allocate " + std::to_string(bytes >> 20) +
                         " MiB");
  }
  auto* lines = static_cast<Line*>(buffer.get());
  {  // first touch by the thread that reads the slice, so its pages are that thread's node's
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) {
      pool.emplace_back([&, t] {
        std::memset(lines + static_cast<size_t>(t) * lines_per_thread, t + 1,
                    lines_per_thread * sizeof(Line));
      });
    }
    for (std::thread& th : pool) th.join();
  }
  std::atomic<uint64_t> sink{0};
  const double one = TimePasses(lines, lines_per_thread, threads, 1, &sink);
  constexpr int kWindows = 20;
  const int passes = std::max(1, static_cast<int>(seconds / kWindows / std::max(one, 1e-9)));
  double best = 0;
  for (int window = 0; window < kWindows; ++window) {
    const double elapsed = TimePasses(lines, lines_per_thread, threads, passes, &sink);
    if (elapsed > 0) best = std::max(best, static_cast<double>(bytes) * passes / elapsed / 1e9);
  }
  PeakBandwidth result;
  result.threads = threads;
  result.gbytes_per_second = best;
  result.buffer_bytes = bytes;
  result.kernel = "4 x 64-byte sums over " + std::to_string(bytes >> 20) + " MiB, " +
                  std::to_string(passes) + " pass(es) a window";
  return result;
}

}  // namespace sfrt::profiling
