// A fixed pool of worker threads, created once (at Session::Create) and reused by every Run().
//
// ParallelFor(n, fn, ctx) calls fn(ctx, begin, end) over disjoint ranges covering [0, n); the
// calling thread works too, so a pool of T threads has T - 1 workers. Ranges are handed out in
// small chunks from an atomic counter, so a core slowed by other load takes fewer of them.
// No allocation, no thread creation per call: one mutex and two condition variables.
//
// Thread-safety: one ParallelFor at a time (the owning Session is not thread-safe either).
#pragma once

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

namespace sfrt {

class ThreadPool {
 public:
  using Fn = void (*)(void* ctx, int begin, int end);

  // threads >= 1. pin: bind thread i (the caller is 0) to CPU i modulo the CPUs available.
  ThreadPool(int threads, bool pin);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }
  void ParallelFor(int n, Fn fn, void* ctx);

 private:
  void WorkerLoop();
  void Work();

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_;
  std::condition_variable done_;
  unsigned long generation_ = 0;  // guarded by mutex_
  int busy_ = 0;                  // workers still in the current job; guarded by mutex_
  bool stop_ = false;             // guarded by mutex_
  // The current job (written before generation_ changes, under mutex_).
  Fn fn_ = nullptr;
  void* ctx_ = nullptr;
  int n_ = 0;
  int grain_ = 1;
  std::atomic<int> next_{0};
};

}  // namespace sfrt
