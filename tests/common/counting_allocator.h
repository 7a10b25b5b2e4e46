// Counts every heap allocation of the test program that links counting_allocator.cc, which
// replaces the global allocation functions (operator new/delete and the C allocator) with
// counting ones. For tests of "allocates nothing" promises; not for sanitized builds, whose
// runtimes own the allocator.
#pragma once

namespace sfrt::testing {

// Allocations so far (malloc, calloc, realloc, aligned_alloc, posix_memalign, operator new).
long AllocationCount();

// Whether the counting functions are the ones in use: one malloc and one operator new, made
// where the compiler cannot pair and drop them, must count 2. A test of "allocates nothing"
// proves nothing without it.
bool CountingHooksAreLive();

// Allocations attributed to threads: a thread that calls SetThreadAllocationTag(tag) counts its
// later allocations under `tag` (1 .. kAllocationTags - 1; 0 = untagged, the default), e.g. a
// pipeline stage's thread tagged from PipelineOptions::on_stage_start. Counted in addition to
// AllocationCount().
inline constexpr int kAllocationTags = 8;
void SetThreadAllocationTag(int tag);
long TaggedAllocationCount(int tag);

}  // namespace sfrt::testing
