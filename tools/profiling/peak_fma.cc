#include "profiling/peak_fma.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling {
namespace {

using Clock = std::chrono::steady_clock;

const internal::PeakKernel* KernelFor(Isa isa) {
  // avx512amx's float32 kernels are avx512's.
  switch (isa == Isa::kAvx512Amx ? Isa::kAvx512 : isa) {
    case Isa::kRef:
      return internal::PeakKernelRef();
#if SFRT_PEAK_AVX2
    case Isa::kAvx2:
      return internal::PeakKernelAvx2();
#endif
#if SFRT_PEAK_AVX512
    case Isa::kAvx512:
      return internal::PeakKernelAvx512();
#endif
#if SFRT_PEAK_NEON
    case Isa::kNeon:
      return internal::PeakKernelNeon();
#endif
    default:
      return nullptr;
  }
}

// Seconds for `threads` threads (the caller's included) each running `iterations` rounds at
// once, from the common start to the last one finishing.
double TimeThreads(const internal::PeakKernel& kernel, int threads, int64_t iterations,
                   std::atomic<float>* sink) {
  std::atomic<bool> go{false};
  std::atomic<int> ready{0};
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) {
    pool.emplace_back([&] {
      ready.fetch_add(1);
      while (!go.load(std::memory_order_acquire)) std::this_thread::yield();
      sink->store(kernel.run(iterations), std::memory_order_relaxed);
    });
  }
  while (ready.load() < threads - 1) std::this_thread::yield();
  const auto start = Clock::now();
  go.store(true, std::memory_order_release);
  sink->store(kernel.run(iterations), std::memory_order_relaxed);
  for (std::thread& t : pool) t.join();
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

namespace internal {

double MeasureGopsPerSecond(const PeakKernel& kernel, int threads, double seconds) {
  std::atomic<float> sink{0};
  // Calibrate on one thread: grow the iteration count until a run takes >= 2 ms.
  int64_t iterations = 256;
  double t = 0;
  for (;;) {
    const auto start = Clock::now();
    sink.store(kernel.run(iterations), std::memory_order_relaxed);
    t = std::chrono::duration<double>(Clock::now() - start).count();
    if (t >= 2e-3 || iterations >= (int64_t{1} << 40)) break;
    iterations *= 4;
  }
  // Many short windows, keeping the fastest: on a machine shared with other work, some windows
  // run undisturbed, and the best of them is the hardware's rate.
  constexpr int kWindows = 20;
  const double per_window = std::max(seconds / kWindows, 1e-3);
  iterations = std::max<int64_t>(
      1, static_cast<int64_t>(static_cast<double>(iterations) * per_window / std::max(t, 1e-9)));
  double best = 0;
  for (int window = 0; window < kWindows; ++window) {
    const double elapsed = TimeThreads(kernel, threads, iterations, &sink);
    if (elapsed > 0) {
      best = std::max(best, static_cast<double>(threads) * static_cast<double>(iterations) *
                                static_cast<double>(kernel.ops_per_iteration) / elapsed / 1e9);
    }
  }
  return best;
}

}  // namespace internal

Result<PeakFma> MeasurePeakFma(Isa isa, int threads, double seconds) {
  if (isa == Isa::kAuto) isa = BestIsa();
  if (threads < 1) {
    return Status::Error("peak FMA: threads must be >= 1, got " + std::to_string(threads));
  }
  const internal::PeakKernel* kernel = KernelFor(isa);
  if (kernel == nullptr || !IsaSupported(isa)) {
    return Status::Error(
        std::string("peak FMA: ISA '") + IsaName(isa) +
        "' is not available in this build on this CPU (available: " + SupportedIsaList() + ")");
  }
  PeakFma result;
  result.isa = isa;
  result.threads = threads;
  result.gflops = internal::MeasureGopsPerSecond(*kernel, threads, seconds);
  result.kernel = kernel->description;
  return result;
}

}  // namespace sfrt::profiling
