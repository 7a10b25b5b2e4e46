// The counting allocator of counting_allocator.h: the global allocation functions, replaced.
#include "common/counting_allocator.h"

#include <malloc.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <new>

extern "C" void* __libc_malloc(size_t);
extern "C" void* __libc_calloc(size_t, size_t);
extern "C" void* __libc_realloc(void*, size_t);
extern "C" void* __libc_memalign(size_t, size_t);
extern "C" void __libc_free(void*);

namespace {
std::atomic<long> g_allocations{0};
std::atomic<long> g_tagged[sfrt::testing::kAllocationTags];
// The calling thread's tag; a trivial thread_local of the executable (static TLS), so reading it
// in malloc allocates nothing.
thread_local int t_tag = 0;

void Count() {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (t_tag != 0) g_tagged[t_tag].fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* malloc(size_t n) {
  Count();
  return __libc_malloc(n);
}
void* calloc(size_t n, size_t size) {
  Count();
  return __libc_calloc(n, size);
}
void* realloc(void* p, size_t n) {
  Count();
  return __libc_realloc(p, n);
}
void* aligned_alloc(size_t alignment, size_t n) {
  Count();
  return __libc_memalign(alignment, n);
}
int posix_memalign(void** out, size_t alignment, size_t n) {
  Count();
  *out = __libc_memalign(alignment, n);
  return *out != nullptr ? 0 : ENOMEM;
}
void free(void* p) { __libc_free(p); }
}

// operator new forwards to malloc in libstdc++, but replace it too so the count does not
// depend on that detail.
void* operator new(size_t n) {
  void* p = malloc(n == 0 ? 1 : n);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
void* operator new[](size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { free(p); }
void operator delete[](void* p) noexcept { free(p); }
void operator delete(void* p, size_t) noexcept { free(p); }
void operator delete[](void* p, size_t) noexcept { free(p); }

long sfrt::testing::AllocationCount() { return g_allocations.load(); }

bool sfrt::testing::CountingHooksAreLive() {
  static void* volatile sink = nullptr;
  const long before = AllocationCount();
  sink = std::malloc(64);
  std::free(sink);
  sink = ::operator new(64);
  ::operator delete(sink);
  return AllocationCount() - before == 2;
}

void sfrt::testing::SetThreadAllocationTag(int tag) {
  t_tag = tag > 0 && tag < kAllocationTags ? tag : 0;
}

long sfrt::testing::TaggedAllocationCount(int tag) {
  return tag > 0 && tag < kAllocationTags ? g_tagged[tag].load() : 0;
}
