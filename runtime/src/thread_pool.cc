#include "thread_pool.h"

#include <pthread.h>
#include <sched.h>

#include <chrono>
#include <climits>

#if defined(__linux__)
#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace sfrt {
namespace {

static_assert(sizeof(std::atomic<uint32_t>) == sizeof(uint32_t) &&
                  std::atomic<uint32_t>::is_always_lock_free,
              "the futex word must be a plain 32-bit integer");

void CpuRelax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#elif defined(__aarch64__)
  asm volatile("yield" ::: "memory");
#endif
}

// Sleeps while *word == value (returns at once if it differs, or spuriously).
void SleepWhileEqual(std::atomic<uint32_t>& word, uint32_t value) {
#if defined(__linux__)
  syscall(SYS_futex, reinterpret_cast<uint32_t*>(&word), FUTEX_WAIT_PRIVATE, value, nullptr,
          nullptr, 0);
#else
  word.wait(value, std::memory_order_seq_cst);
#endif
}

void WakeAll(std::atomic<uint32_t>& word) {
#if defined(__linux__)
  syscall(SYS_futex, reinterpret_cast<uint32_t*>(&word), FUTEX_WAKE_PRIVATE, INT_MAX, nullptr,
          nullptr, 0);
#else
  word.notify_all();
#endif
}

void PinCurrentThread(int index) {
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (sched_getaffinity(0, sizeof(allowed), &allowed) != 0) return;
  const int count = CPU_COUNT(&allowed);
  if (count <= 0) return;
  int wanted = index % count;
  for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
    if (!CPU_ISSET(cpu, &allowed)) continue;
    if (wanted-- == 0) {
      cpu_set_t one;
      CPU_ZERO(&one);
      CPU_SET(cpu, &one);
      pthread_setaffinity_np(pthread_self(), sizeof(one), &one);
      return;
    }
  }
}

}  // namespace

ThreadPool::ThreadPool(int threads, bool pin, int spin_us)
    : spin_ns_(spin_us < 0 ? -1 : int64_t{spin_us} * 1000) {
  if (pin) PinCurrentThread(0);
  for (int i = 1; i < threads; ++i) {
    workers_.emplace_back([this, i, pin] {
      if (pin) PinCurrentThread(i);
      WorkerLoop();
    });
  }
}

ThreadPool::~ThreadPool() {
  stop_ = true;  // published by the bump below
  generation_.fetch_add(1, std::memory_order_seq_cst);
  WakeAll(generation_);
  for (std::thread& t : workers_) t.join();
}

void ThreadPool::WaitWhileEqual(std::atomic<uint32_t>& word, uint32_t value,
                                std::atomic<int>& sleepers) const {
  if (spin_ns_ != 0) {
    // The clock is read only every 256 tries, and never when spinning without a limit.
    const auto start = std::chrono::steady_clock::now();
    for (unsigned tries = 1;; ++tries) {
      if (word.load(std::memory_order_acquire) != value) return;
      CpuRelax();
      if (spin_ns_ > 0 && tries % 256 == 0 &&
          std::chrono::steady_clock::now() - start >= std::chrono::nanoseconds(spin_ns_)) {
        break;
      }
    }
  }
  // Announce the sleep before the last look, so that whoever changes the word and then reads
  // `sleepers` (both seq_cst) either is seen here or sees us and wakes us.
  sleepers.fetch_add(1, std::memory_order_seq_cst);
  while (word.load(std::memory_order_seq_cst) == value) SleepWhileEqual(word, value);
  sleepers.fetch_sub(1, std::memory_order_relaxed);
}

void ThreadPool::Work() {
  for (;;) {
    const int begin = next_.fetch_add(grain_, std::memory_order_relaxed);
    if (begin >= n_) return;
    const int end = begin + grain_ < n_ ? begin + grain_ : n_;
    fn_(ctx_, begin, end);
  }
}

void ThreadPool::WorkerLoop() {
  uint32_t seen = 0;
  for (;;) {
    WaitWhileEqual(generation_, seen, generation_sleepers_);
    seen = generation_.load(std::memory_order_acquire);
    if (stop_) return;
    Work();
    // The last worker out wakes the caller if it sleeps. The decrement releases this worker's
    // outputs to the caller, which acquires the final zero.
    if (pending_.fetch_sub(1, std::memory_order_seq_cst) == 1 &&
        pending_sleepers_.load(std::memory_order_seq_cst) > 0) {
      WakeAll(pending_);
    }
  }
}

void ThreadPool::ParallelFor(int n, Fn fn, void* ctx) {
  if (n <= 0) return;
  if (workers_.empty() || n == 1) {
    fn(ctx, 0, n);
    return;
  }
  // Every worker has finished the previous job (pending_ was zero), so nobody reads these now.
  fn_ = fn;
  ctx_ = ctx;
  n_ = n;
  // About four chunks per thread: balance against a core shared with other work.
  const int chunks = 4 * threads();
  grain_ = n / chunks > 0 ? n / chunks : 1;
  next_.store(0, std::memory_order_relaxed);
  pending_.store(static_cast<uint32_t>(workers_.size()), std::memory_order_relaxed);
  generation_.fetch_add(1, std::memory_order_seq_cst);
  if (generation_sleepers_.load(std::memory_order_seq_cst) > 0) WakeAll(generation_);
  Work();
  for (uint32_t left; (left = pending_.load(std::memory_order_acquire)) != 0;) {
    WaitWhileEqual(pending_, left, pending_sleepers_);
  }
}

}  // namespace sfrt
