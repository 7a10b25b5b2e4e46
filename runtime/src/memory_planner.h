// Arena planning: give every intermediate tensor an offset in one arena so that tensors alive at
// the same time never overlap.
//
// Algorithm (greedy by size, as in TFLite Micro's GreedyMemoryPlanner):
//   1. Sort requests by size, largest first (ties: earlier first use first).
//   2. For each request, collect the already placed requests whose lifetimes [first, last]
//      intersect its own, ordered by offset, and put it in the lowest gap (64-byte aligned) that
//      fits between them, or after the last one.
// Not optimal (the problem is NP-complete), but for a chain of layers it finds the two- or
// three-buffer ping-pong a person would write. Cost: O(n^2) in the number of requests, at load.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

namespace sfrt {

inline constexpr size_t kArenaAlignment = 64;

struct BufferRequest {
  size_t bytes = 0;
  int first_use = 0;  // step that writes it
  int last_use = 0;   // last step that reads it (>= first_use)
};

struct ArenaPlan {
  std::vector<size_t> offsets;  // one per request, multiples of kArenaAlignment
  size_t total_bytes = 0;       // arena size needed
};

ArenaPlan PlanArena(std::span<const BufferRequest> requests);

// True if two requests that are alive at the same step share any byte. For tests and debug
// checks of any plan.
bool PlanHasOverlap(std::span<const BufferRequest> requests, const ArenaPlan& plan);

}  // namespace sfrt
