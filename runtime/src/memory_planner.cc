#include "memory_planner.h"

#include <algorithm>
#include <numeric>

namespace sfrt {
namespace {

size_t AlignUp(size_t n) { return (n + kArenaAlignment - 1) / kArenaAlignment * kArenaAlignment; }

bool LifetimesIntersect(const BufferRequest& a, const BufferRequest& b) {
  return a.first_use <= b.last_use && b.first_use <= a.last_use;
}

}  // namespace

ArenaPlan PlanArena(std::span<const BufferRequest> requests) {
  const size_t n = requests.size();
  ArenaPlan plan;
  plan.offsets.assign(n, 0);

  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    if (requests[a].bytes != requests[b].bytes) return requests[a].bytes > requests[b].bytes;
    return requests[a].first_use < requests[b].first_use;
  });

  std::vector<size_t> placed;  // indices already given an offset
  std::vector<size_t> conflicts;
  for (size_t idx : order) {
    const BufferRequest& req = requests[idx];
    conflicts.clear();
    for (size_t other : placed) {
      if (LifetimesIntersect(req, requests[other])) conflicts.push_back(other);
    }
    std::sort(conflicts.begin(), conflicts.end(),
              [&](size_t a, size_t b) { return plan.offsets[a] < plan.offsets[b]; });
    size_t candidate = 0;
    for (size_t other : conflicts) {
      const size_t other_begin = plan.offsets[other];
      const size_t other_end = AlignUp(other_begin + requests[other].bytes);
      if (candidate + req.bytes <= other_begin) break;  // fits in the gap before `other`
      candidate = std::max(candidate, other_end);
    }
    plan.offsets[idx] = candidate;
    plan.total_bytes = std::max(plan.total_bytes, AlignUp(candidate + req.bytes));
    placed.push_back(idx);
  }
  return plan;
}

bool PlanHasOverlap(std::span<const BufferRequest> requests, const ArenaPlan& plan) {
  for (size_t i = 0; i < requests.size(); ++i) {
    for (size_t j = i + 1; j < requests.size(); ++j) {
      if (!LifetimesIntersect(requests[i], requests[j])) continue;
      if (requests[i].bytes == 0 || requests[j].bytes == 0) continue;
      const size_t a0 = plan.offsets[i], a1 = a0 + requests[i].bytes;
      const size_t b0 = plan.offsets[j], b1 = b0 + requests[j].bytes;
      if (a0 < b1 && b0 < a1) return true;
    }
  }
  return false;
}

}  // namespace sfrt
