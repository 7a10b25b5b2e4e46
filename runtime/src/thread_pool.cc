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
  stop_.store(true, std::memory_order_seq_cst);
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

namespace {

constexpr uint32_t kClosed = 0xffffffffu;  // the item field of a closed job

constexpr uint64_t Claim(uint32_t generation, uint32_t next) {
  return uint64_t{generation} << 32 | next;
}

}  // namespace

// Why the job's fields may be read before the claim succeeds: the caller writes them only while
// the job is closed (claim_ holds kClosed, stored before the writes), and every access here and
// there is seq_cst. If this thread's read of a field saw the next job's value, that write, and
// so the closing store before it, precede this thread's compare-and-swap in the single total
// order, so the swap compares against a closed word and fails. A successful swap therefore
// means the fields read belong to `generation`, and the items [begin, end) are this thread's.
void ThreadPool::Work(uint32_t generation) {
  for (;;) {
    uint64_t claim = claim_.load(std::memory_order_seq_cst);
    if (static_cast<uint32_t>(claim >> 32) != generation) return;
    const uint32_t begin = static_cast<uint32_t>(claim);
    if (begin == kClosed) return;
    const int n = n_.load(std::memory_order_seq_cst);
    const int grain = grain_.load(std::memory_order_seq_cst);
    const Fn fn = fn_.load(std::memory_order_seq_cst);
    void* ctx = ctx_.load(std::memory_order_seq_cst);
    if (begin >= static_cast<uint32_t>(n)) return;
    const uint32_t end = begin + grain < static_cast<uint32_t>(n) ? begin + grain : n;
    if (!claim_.compare_exchange_weak(claim, Claim(generation, end), std::memory_order_seq_cst)) {
      continue;
    }
    fn(ctx, static_cast<int>(begin), static_cast<int>(end));
    // The last chunk wakes the caller if it sleeps. The add releases this chunk's outputs to the
    // caller, which acquires the final count.
    const uint32_t finished = done_.fetch_add(end - begin, std::memory_order_seq_cst) + end - begin;
    if (finished == static_cast<uint32_t>(n) &&
        done_sleepers_.load(std::memory_order_seq_cst) > 0) {
      WakeAll(done_);
    }
  }
}

void ThreadPool::WorkerLoop() {
  uint32_t seen = 0;
  for (;;) {
    WaitWhileEqual(generation_, seen, generation_sleepers_);
    seen = generation_.load(std::memory_order_acquire);
    if (stop_.load(std::memory_order_acquire)) return;
    Work(seen);
  }
}

void ThreadPool::ParallelFor(int n, Fn fn, void* ctx) {
  if (n <= 0) return;
  if (workers_.empty() || n == 1) {
    fn(ctx, 0, n);
    return;
  }
  // The previous job is complete (every item done), so closing it stops nothing; a worker that
  // wakes late for it finds it closed and claims nothing.
  claim_.store(Claim(jobs_, kClosed), std::memory_order_seq_cst);
  const uint32_t generation = ++jobs_;
  fn_.store(fn, std::memory_order_seq_cst);
  ctx_.store(ctx, std::memory_order_seq_cst);
  n_.store(n, std::memory_order_seq_cst);
  // About four chunks per thread: balance against a core shared with other work.
  const int chunks = 4 * threads();
  grain_.store(n / chunks > 0 ? n / chunks : 1, std::memory_order_seq_cst);
  done_.store(0, std::memory_order_seq_cst);
  claim_.store(Claim(generation, 0), std::memory_order_seq_cst);  // open
  generation_.store(generation, std::memory_order_seq_cst);
  if (generation_sleepers_.load(std::memory_order_seq_cst) > 0) WakeAll(generation_);
  Work(generation);
  // Only chunks that a worker claimed can still be running.
  for (uint32_t finished;
       (finished = done_.load(std::memory_order_acquire)) != static_cast<uint32_t>(n);) {
    WaitWhileEqual(done_, finished, done_sleepers_);
  }
}

}  // namespace sfrt
