// Counts every heap allocation of the test program that links counting_allocator.cc, which
// replaces the global allocation functions (operator new/delete and the C allocator) with
// counting ones. For tests of "allocates nothing" promises; not for sanitized builds, whose
// runtimes own the allocator.
#pragma once

namespace sfrt::testing {

// Allocations so far (malloc, calloc, realloc, aligned_alloc, posix_memalign, operator new).
long AllocationCount();

}  // namespace sfrt::testing
