// A fixed pool of worker threads, created once (at Session::Create) and reused by every Run().
//
// ParallelFor(n, fn, ctx) calls fn(ctx, begin, end) over disjoint ranges covering [0, n); the
// calling thread works too, so a pool of T threads has T - 1 workers. Ranges are handed out in
// small chunks from an atomic counter, so a core slowed by other load takes fewer of them.
//
// No lock, no allocation, no thread creation per call. The hand-off is two atomic words:
// - the caller publishes a job by bumping `generation_`; workers wait for it to change;
// - each worker decrements `pending_` when it has finished; the caller waits for zero.
// Whoever waits first spins (a pause instruction per try) for up to `spin_us` microseconds and
// only then sleeps in the kernel on that word (Linux futex, FUTEX_PRIVATE). The side that
// changes a word wakes it only when someone sleeps on it, so while both sides keep within the
// spin window a ParallelFor makes no system call at all. A job's end is not a barrier for the
// workers: they spin for the next job from the moment they finish this one.
//
// Choosing spin_us (SessionOptions::spin_us): spinning burns a core that could do other work and
// sleeping adds a wake-up (tens of microseconds, more on a loaded machine) to the next job.
// - spin_us < 0: never sleep. Lowest latency; for cores reserved for inference.
// - spin_us = 0: sleep at once. Least CPU; every job then pays a wake-up per worker.
// - default (1000): long enough to bridge the gaps between the steps of one Run() and a slow
//   chunk; short enough that an idle pool sleeps within a millisecond of the last Run().
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
  void Work();
  // Waits until `word` differs from `value`: spins, then sleeps on it, counting itself in
  // `sleepers` while it may be asleep.
  void WaitWhileEqual(std::atomic<uint32_t>& word, uint32_t value,
                      std::atomic<int>& sleepers) const;

  std::vector<std::thread> workers_;
  const int64_t spin_ns_;  // < 0: spin forever
  // Each word on its own cache line: the caller writes one, the workers the other.
  alignas(64) std::atomic<uint32_t> generation_{0};  // bumped once per job, and at shutdown
  alignas(64) std::atomic<int> generation_sleepers_{0};
  alignas(64) std::atomic<uint32_t> pending_{0};  // workers still in the current job
  alignas(64) std::atomic<int> pending_sleepers_{0};
  alignas(64) std::atomic<int> next_{0};  // the next index to hand out
  // The current job: written before generation_ is bumped (release), read after (acquire).
  Fn fn_ = nullptr;
  void* ctx_ = nullptr;
  int n_ = 0;
  int grain_ = 1;
  bool stop_ = false;
};

}  // namespace sfrt
