// A fixed pool of worker threads, created once (at Session::Create) and reused by every Run().
//
// ParallelFor(n, fn, ctx) calls fn(ctx, begin, end) over disjoint ranges covering [0, n); the
// calling thread works too, so a pool of T threads has T - 1 workers. Ranges are handed out in
// small chunks from an atomic counter, so a core slowed by other load takes fewer of them.
//
// No lock, no allocation, no thread creation per call. The hand-off is lock-free:
// - the caller publishes a job (function, context, item count) and then opens it by storing
//   (generation, next item = 0) in one 64-bit word; workers wait for the generation to change;
// - every thread claims chunks of items by compare-and-swap on that word, which fails once the
//   job is closed, so a worker that wakes late claims nothing and never reads the next job's
//   fields as this one's;
// - each finished chunk adds its size to a done counter; ParallelFor returns when it reaches the
//   item count. The caller never waits for a worker that has not started: it does the unclaimed
//   work itself, which is what keeps a loaded or oversubscribed machine from stalling Run().
// Whoever waits spins (a pause instruction per try) for up to `spin_us` microseconds and only
// then sleeps in the kernel on a 32-bit word (Linux futex, FUTEX_PRIVATE). The side that changes a
// word wakes it only when someone sleeps on it, so while the waits stay within the spin window a
// ParallelFor makes no system call at all.
//
// Choosing spin_us (SessionOptions::spin_us): spinning burns a core that could do other work and
// sleeping adds a wake-up (tens of microseconds, more on a loaded machine) to the next job.
// - spin_us < 0: never sleep. Lowest latency; for cores reserved for inference.
// - spin_us = 0: sleep at once. Least CPU; every job then pays a wake-up per worker.
// - default (200): bridges the gaps between the steps of one Run() (microseconds) and most
//   chunks of small layers; a pool left idle sleeps within 0.2 ms, and a core shared with other
//   work loses at most that much per wait.
//
// Thread-safety: one ParallelFor at a time (the owning Session is not thread-safe either).
#pragma once

#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace sfrt {

class ThreadPool {
 public:
  using Fn = void (*)(void* ctx, int begin, int end);

  // threads >= 1. pin: bind thread i (the caller is 0) to CPU i modulo the CPUs available.
  // spin_us: how long a waiting thread spins before it sleeps (see above; < 0: never sleeps).
  ThreadPool(int threads, bool pin, int spin_us);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }
  void ParallelFor(int n, Fn fn, void* ctx);

 private:
  void WorkerLoop();
  // Claims and runs chunks of job `generation` until none is left or the job is closed.
  void Work(uint32_t generation);
  // Waits until `word` differs from `value`: spins, then sleeps on it, counting itself in
  // `sleepers` while it may be asleep.
  void WaitWhileEqual(std::atomic<uint32_t>& word, uint32_t value,
                      std::atomic<int>& sleepers) const;

  std::vector<std::thread> workers_;
  const int64_t spin_ns_;  // < 0: spin forever
  uint32_t jobs_ = 0;      // the caller's count of published jobs
  // Each word on its own cache line.
  alignas(64) std::atomic<uint64_t> claim_{0};  // (generation << 32) | next item; kClosed: none
  alignas(64) std::atomic<uint32_t> generation_{0};  // futex word: the newest job, or shutdown
  alignas(64) std::atomic<int> generation_sleepers_{0};
  alignas(64) std::atomic<uint32_t> done_{0};  // futex word: items finished in the current job
  alignas(64) std::atomic<int> done_sleepers_{0};
  // The current job, written while it is closed (all seq_cst: see Work()).
  alignas(64) std::atomic<Fn> fn_{nullptr};
  std::atomic<void*> ctx_{nullptr};
  std::atomic<int> n_{0};
  std::atomic<int> grain_{1};
  std::atomic<bool> stop_{false};
};

}  // namespace sfrt
