// LatestQueue: a bounded queue between two pipeline stages that never lets the consumer fall
// behind on stale items.
//
// The queue owns `capacity` slots, each a T created once at construction (give a factory so
// every slot starts with its buffers allocated). Items move by swapping, never by copying:
//   Push(&item)  swaps *item into the newest slot. The producer gets back whatever the slot held
//                (an old buffer to refill), so steady-state traffic does not allocate.
//   Pop(&item)   waits for an item and swaps the oldest slot with *item; the consumer's previous
//                buffer goes back into the queue's storage.
// When the queue is full, Push() behaves per Policy:
//   kNewestWins  the oldest queued item is discarded (counted in drops()) and the new one is
//                queued; Push() never blocks. Live cameras: the consumer always gets the newest.
//   kBlock       Push() waits until the consumer makes room (or the queue is closed). Replays:
//                every item is processed.
// Close() ends the stream: Push() refuses further items (returns false); Pop() returns the items
// still queued and then false. Discard() also throws away the queued items (counted in
// discarded()), for a stop that must not wait for them.
//
// Thread-safety: any number of producers and consumers; one mutex, two condition variables.
// T must be default-constructible and swappable (std::swap) without allocating (std::vector,
// cv::Mat and structs of them are).
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <utility>
#include <vector>

namespace sfrt::pipeline {

enum class QueuePolicy { kNewestWins, kBlock };

template <typename T>
class LatestQueue {
 public:
  LatestQueue(size_t capacity, QueuePolicy policy)
      : policy_(policy), slots_(capacity ? capacity : 1) {}
  // make(): returns a T with its buffers allocated (a deep copy per slot: cv::Mat copies share
  // pixels, so slots are made one by one rather than copied from a prototype).
  template <typename Make>
  LatestQueue(size_t capacity, QueuePolicy policy, Make make) : LatestQueue(capacity, policy) {
    for (T& slot : slots_) slot = make();
  }
  LatestQueue(const LatestQueue&) = delete;
  LatestQueue& operator=(const LatestQueue&) = delete;

  // Queues *item (swapped in; *item receives a recycled buffer). False if the queue is closed
  // (then *item is untouched).
  bool Push(T* item) {
    std::unique_lock<std::mutex> lock(mu_);
    if (policy_ == QueuePolicy::kBlock) {
      not_full_.wait(lock, [&] { return closed_ || count_ < slots_.size(); });
    }
    if (closed_) return false;
    if (count_ == slots_.size()) {  // kNewestWins: discard the oldest
      head_ = (head_ + 1) % slots_.size();
      --count_;
      ++drops_;
    }
    using std::swap;
    swap(slots_[(head_ + count_) % slots_.size()], *item);
    ++count_;
    ++pushed_;
    not_empty_.notify_one();
    return true;
  }

  // Waits for an item and swaps it into *item. False once the queue is closed and empty.
  bool Pop(T* item) {
    std::unique_lock<std::mutex> lock(mu_);
    not_empty_.wait(lock, [&] { return closed_ || count_ > 0; });
    if (count_ == 0) return false;
    using std::swap;
    swap(slots_[head_], *item);
    head_ = (head_ + 1) % slots_.size();
    --count_;
    ++popped_;
    not_full_.notify_one();
    return true;
  }

  void Close() {
    std::lock_guard<std::mutex> lock(mu_);
    closed_ = true;
    not_empty_.notify_all();
    not_full_.notify_all();
  }

  // Close() and forget every queued item.
  void Discard() {
    std::lock_guard<std::mutex> lock(mu_);
    closed_ = true;
    discarded_ += count_;
    count_ = 0;
    not_empty_.notify_all();
    not_full_.notify_all();
  }

  size_t capacity() const { return slots_.size(); }
  QueuePolicy policy() const { return policy_; }
  size_t size() const {
    std::lock_guard<std::mutex> lock(mu_);
    return count_;
  }
  bool closed() const {
    std::lock_guard<std::mutex> lock(mu_);
    return closed_;
  }
  uint64_t pushed() const {
    std::lock_guard<std::mutex> lock(mu_);
    return pushed_;
  }
  uint64_t popped() const {
    std::lock_guard<std::mutex> lock(mu_);
    return popped_;
  }
  // Items discarded by kNewestWins because a newer one arrived.
  uint64_t drops() const {
    std::lock_guard<std::mutex> lock(mu_);
    return drops_;
  }
  // Items thrown away by Discard().
  uint64_t discarded() const {
    std::lock_guard<std::mutex> lock(mu_);
    return discarded_;
  }

 private:
  const QueuePolicy policy_;
  mutable std::mutex mu_;
  std::condition_variable not_empty_;
  std::condition_variable not_full_;
  std::vector<T> slots_;
  size_t head_ = 0;
  size_t count_ = 0;
  bool closed_ = false;
  uint64_t pushed_ = 0;
  uint64_t popped_ = 0;
  uint64_t drops_ = 0;
  uint64_t discarded_ = 0;
};

}  // namespace sfrt::pipeline
