// Proves the promise of session.h that Run() takes no lock, and with the pool's waits inside
// SessionOptions::spin_us makes no system call: this program defines the pthread lock and wait
// functions and syscall(2)'s libc wrapper (through which futex sleeps and wakes go) itself,
// counting every call from any thread and forwarding it to libc. The runtime is linked
// statically, so its calls bind here; the executable exports the symbols, so calls from shared
// libraries bind here too.
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <pthread.h>
#include <stdarg.h>
#include <sys/syscall.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/bf16_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "common/unet_spec.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/isa.h"
#include "sfrt/session.h"

namespace {

std::atomic<long> g_mutex_locks{0};
std::atomic<long> g_cond_waits{0};
std::atomic<long> g_syscalls{0};
std::atomic<long> g_futex_calls{0};

template <typename F>
F Next(const char* name) {
  void* f = dlsym(RTLD_NEXT, name);
  if (f == nullptr) abort();
  return reinterpret_cast<F>(f);
}

}  // namespace

extern "C" {
int pthread_mutex_lock(pthread_mutex_t* m) {
  static const auto next = Next<int (*)(pthread_mutex_t*)>("pthread_mutex_lock");
  g_mutex_locks.fetch_add(1, std::memory_order_relaxed);
  return next(m);
}
int pthread_mutex_trylock(pthread_mutex_t* m) {
  static const auto next = Next<int (*)(pthread_mutex_t*)>("pthread_mutex_trylock");
  g_mutex_locks.fetch_add(1, std::memory_order_relaxed);
  return next(m);
}
int pthread_cond_wait(pthread_cond_t* c, pthread_mutex_t* m) {
  static const auto next = Next<int (*)(pthread_cond_t*, pthread_mutex_t*)>("pthread_cond_wait");
  g_cond_waits.fetch_add(1, std::memory_order_relaxed);
  return next(c, m);
}
int pthread_cond_timedwait(pthread_cond_t* c, pthread_mutex_t* m, const struct timespec* t) {
  static const auto next = Next<int (*)(pthread_cond_t*, pthread_mutex_t*, const struct timespec*)>(
      "pthread_cond_timedwait");
  g_cond_waits.fetch_add(1, std::memory_order_relaxed);
  return next(c, m, t);
}
long syscall(long number, ...) {
  static const auto next = Next<long (*)(long, ...)>("syscall");
  va_list ap;
  va_start(ap, number);
  long a[6];
  for (long& v : a) v = va_arg(ap, long);
  va_end(ap);
  g_syscalls.fetch_add(1, std::memory_order_relaxed);
  if (number == SYS_futex) g_futex_calls.fetch_add(1, std::memory_order_relaxed);
  return next(number, a[0], a[1], a[2], a[3], a[4], a[5]);
}
}

namespace sfrt {
namespace {

struct Counts {
  long mutex_locks, cond_waits, syscalls, futex_calls;
};

Counts Snapshot() {
  return {g_mutex_locks.load(), g_cond_waits.load(), g_syscalls.load(), g_futex_calls.load()};
}

Counts Since(const Counts& before) {
  const Counts now = Snapshot();
  return {now.mutex_locks - before.mutex_locks, now.cond_waits - before.cond_waits,
          now.syscalls - before.syscalls, now.futex_calls - before.futex_calls};
}

// Steady-state runs per case on the SIMD paths: 100 natively. Under qemu or the sanitizers, where
// a run is 10-50x slower, 25: a lock or system call taken at every run, or every few, still shows
// there, and the native run of the same test covers the rarer ones.
constexpr int kSteadyRuns = SFRT_TEST_EMULATED || SFRT_TEST_SANITIZED ? 25 : 100;
// The scalar reference is ~50x slower than the SIMD paths: fewer runs there.
constexpr int kSteadyRunsOfReference = 10;

class NoLock : public ::testing::Test {
 protected:
  // Runs `runs` frames at 96x128 after `warm_up` frames; returns what was called meanwhile.
  // precision: the model in it (int8: uint8 tensors, the quantising step, the int8 kernels;
  // bf16: bf16 tensors, the converting step, the bf16 kernels). graph: SceneEDNet-U with a
  // residual Add instead (float32; skip tensors, Concat and Add steps).
  Counts CountDuringRuns(const SessionOptions& options, int warm_up, int runs,
                         Precision precision = Precision::kFloat32, bool graph = false) {
    auto model = testing::LoadOrDie(
        graph                               ? testing::SceneEdNetUSpec(16, 1, true)
        : precision == Precision::kInt8     ? testing::Int8Spec(exporter::SceneEdNetSpec(16))
        : precision == Precision::kBFloat16 ? testing::Bf16Spec(exporter::SceneEdNetSpec(16))
                                            : exporter::SceneEdNetSpec(16));
    auto session = Session::Create(model, options);
    EXPECT_TRUE(session.ok()) << session.message();
    if (!session.ok()) return {};
    std::vector<float> input(96 * 128 * 12, 100.0f), output(96 * 128 * 3);
    for (int i = 0; i < warm_up; ++i) EXPECT_TRUE((*session)->Run(input, 96, 128, output).ok());
    const Counts before = Snapshot();
    bool all_ok = true;
    for (int i = 0; i < runs; ++i) all_ok &= (*session)->Run(input, 96, 128, output).ok();
    const Counts during = Since(before);
    EXPECT_TRUE(all_ok);
    return during;
  }
};

TEST_F(NoLock, CountingHooksSeeAMutexAndAFutex) {
  // The hooks must be live, or the tests below prove nothing.
  const Counts before = Snapshot();
  std::mutex m;
  m.lock();
  m.unlock();
  EXPECT_GE(Since(before).mutex_locks, 1);

  // A pool that sleeps at once, given time to fall asleep before each run: its worker's futex
  // sleeps (and the caller's wakes) must be counted. Without the pauses a worker descheduled
  // throughout would leave every run to the caller, and nothing to count.
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  SessionOptions sleepy;
  sleepy.max_height = 96;
  sleepy.max_width = 128;
  sleepy.threads = 2;
  sleepy.spin_us = 0;
  auto session = Session::Create(model, sleepy);
  ASSERT_TRUE(session.ok()) << session.message();
  std::vector<float> input(96 * 128 * 12, 100.0f), output(96 * 128 * 3);
  const Counts pool_before = Snapshot();
  for (int i = 0; i < 20; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ASSERT_TRUE((*session)->Run(input, 96, 128, output).ok());
  }
  EXPECT_GT(Since(pool_before).futex_calls, 0);
}

TEST_F(NoLock, RunAtTwoThreadsTakesNoLockAndMakesNoSystemCallInSteadyState) {
  for (Isa isa : SupportedIsas()) {
    for (Precision precision : {Precision::kFloat32, Precision::kInt8, Precision::kBFloat16}) {
      SCOPED_TRACE(std::string(IsaName(isa)) + " " + PrecisionName(precision));
      SessionOptions options;
      options.max_height = 96;
      options.max_width = 128;
      options.isa = isa;
      options.threads = 2;
      options.spin_us = -1;  // never sleep: the steady state of a busy pipeline, made certain
      // The bf16 reference kernel sums in double: as slow as the reference wherever it runs.
      const bool slow =
          isa == Isa::kRef || (precision == Precision::kBFloat16 && !Bf16KernelsAvailable(isa));
      const Counts c =
          CountDuringRuns(options, 5, slow ? kSteadyRunsOfReference : kSteadyRuns, precision);
      EXPECT_EQ(c.mutex_locks, 0);
      EXPECT_EQ(c.cond_waits, 0);
      EXPECT_EQ(c.futex_calls, 0);
      EXPECT_EQ(c.syscalls, 0);
    }
    SCOPED_TRACE(std::string(IsaName(isa)) + " graph");
    SessionOptions options;
    options.max_height = 96;
    options.max_width = 128;
    options.isa = isa;
    options.threads = 2;
    options.spin_us = -1;
    const Counts c = CountDuringRuns(
        options, 5, isa == Isa::kRef ? kSteadyRunsOfReference : kSteadyRuns, Precision::kFloat32,
        /*graph=*/true);
    EXPECT_EQ(c.mutex_locks, 0);
    EXPECT_EQ(c.cond_waits, 0);
    EXPECT_EQ(c.futex_calls, 0);
    EXPECT_EQ(c.syscalls, 0);
  }
}

TEST_F(NoLock, RunAtTwoThreadsWithTheDefaultSpinTakesNoMutex) {
  // Under the default policy a worker preempted past spin_us sleeps on a futex, which is a
  // system call but not a lock; mutexes and condition variables never appear.
  SessionOptions options;
  options.max_height = 96;
  options.max_width = 128;
  options.threads = 2;
  const Counts c = CountDuringRuns(options, 5, kSteadyRuns);
  EXPECT_EQ(c.mutex_locks, 0);
  EXPECT_EQ(c.cond_waits, 0);
}

TEST_F(NoLock, EverySpinPolicyComputesTheSameOutput) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(16));
  std::vector<float> input(67 * 121 * 12);
  for (size_t i = 0; i < input.size(); ++i) input[i] = static_cast<float>((i * 37) % 255);
  std::vector<float> reference(67 * 121 * 3);
  {
    SessionOptions one;
    one.max_height = 96;
    one.max_width = 128;
    auto session = Session::Create(model, one);
    ASSERT_TRUE(session.ok()) << session.message();
    ASSERT_TRUE((*session)->Run(input, 67, 121, reference).ok());
  }
  for (int spin_us : {-1, 0, 1000}) {
    SCOPED_TRACE("spin_us " + std::to_string(spin_us));
    SessionOptions options;
    options.max_height = 96;
    options.max_width = 128;
    options.threads = 2;
    options.spin_us = spin_us;
    auto session = Session::Create(model, options);
    ASSERT_TRUE(session.ok()) << session.message();
    std::vector<float> output(reference.size());
    for (int run = 0; run < 3; ++run) {
      ASSERT_TRUE((*session)->Run(input, 67, 121, output).ok());
      EXPECT_EQ(output, reference) << "run " << run;
    }
  }
}

}  // namespace
}  // namespace sfrt
