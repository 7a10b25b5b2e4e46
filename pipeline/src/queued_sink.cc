#include "sfrt/pipeline/queued_sink.h"

#include <algorithm>
#include <chrono>
#include <nlohmann/json.hpp>

namespace sfrt::pipeline {
namespace {

double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace

QueuedSink::QueuedSink(std::string name, std::vector<FlowSink*> inner, size_t depth,
                       QueuePolicy policy)
    : name_(std::move(name)),
      inner_(std::move(inner)),
      depth_(std::max<size_t>(1, depth)),
      policy_(policy),
      slots_(depth_ + 1) {
  free_.reserve(slots_.size());
  queue_.reserve(depth_);
  for (size_t i = 0; i < slots_.size(); ++i) free_.push_back(i);
}

QueuedSink::~QueuedSink() {
  if (worker_.joinable()) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      stopping_ = true;
    }
    cv_.notify_all();
    worker_.join();
  }
}

Status QueuedSink::Start() {
  for (size_t i = 0; i < inner_.size(); ++i) {
    if (Status s = inner_[i]->Start(); !s.ok()) {
      for (size_t j = 0; j < i; ++j) (void)inner_[j]->Stop();
      return s;
    }
  }
  started_ = true;
  worker_ = std::thread([this] { Work(); });
  return Status::Ok();
}

Status QueuedSink::Write(const FlowFrame& frame) {
  std::unique_lock<std::mutex> lock(mu_);
  if (!error_.ok()) {  // an earlier window failed on the sink's thread: report it now
    Status e = error_;
    error_ = Status::Ok();
    return e;
  }
  if (free_.empty()) {
    if (policy_ == QueuePolicy::kBlock) {
      cv_.wait(lock, [this] { return !free_.empty(); });
    } else {
      // Newest wins: the oldest window still waiting gives its slot to this one.
      free_.push_back(queue_.front());
      queue_.erase(queue_.begin());
      ++dropped_;
    }
  }
  const size_t index = free_.back();
  free_.pop_back();
  lock.unlock();
  // The slot is this thread's until it is queued: copy outside the lock.
  Slot& slot = slots_[index];
  slot.meta = *frame.meta;
  slot.flow.assign(frame.flow.begin(), frame.flow.end());
  frame.left_image->copyTo(slot.left);
  slot.height = frame.height;
  slot.width = frame.width;
  slot.channels = frame.channels;
  slot.latency_ms = frame.latency_ms;
  slot.over_budget = frame.over_budget;
  lock.lock();
  slot.seq = ++written_seq_;
  queue_.push_back(index);
  lock.unlock();
  cv_.notify_all();
  return Status::Ok();
}

void QueuedSink::Retract() {
  std::unique_lock<std::mutex> lock(mu_);
  for (size_t i = 0; i < queue_.size(); ++i) {
    if (slots_[queue_[i]].seq == written_seq_) {  // still waiting: it is never written
      free_.push_back(queue_[i]);
      queue_.erase(queue_.begin() + static_cast<std::ptrdiff_t>(i));
      cv_.notify_all();
      return;
    }
  }
  retract_seq_ = written_seq_;  // being written or written: retracted once done
  lock.unlock();
  cv_.notify_all();
}

// The inner sinks in order; one that fails has those before it retract (all or nothing).
bool QueuedSink::WriteInner(Slot& slot, Status* error) {
  FlowFrame frame;
  frame.meta = &slot.meta;
  frame.flow = std::span<const float>(slot.flow.data(), slot.flow.size());
  frame.height = slot.height;
  frame.width = slot.width;
  frame.channels = slot.channels;
  frame.left_image = &slot.left;
  frame.latency_ms = slot.latency_ms;
  frame.over_budget = slot.over_budget;
  for (size_t i = 0; i < inner_.size(); ++i) {
    Status s = inner_[i]->Write(frame);
    if (!s.ok()) {
      for (size_t j = 0; j < i; ++j) inner_[j]->Retract();
      *error = Status::Error(inner_[i]->name() + " of window " + OutputStem(slot.meta) +
                             " (reported with a later window): " + s.message());
      return false;
    }
  }
  return true;
}

void QueuedSink::Work() {
  std::unique_lock<std::mutex> lock(mu_);
  while (true) {
    if (retract_seq_ != 0 && done_seq_ >= retract_seq_) {
      const bool undo = last_ok_seq_ == retract_seq_;
      retract_seq_ = 0;
      if (undo) {
        lock.unlock();
        for (FlowSink* sink : inner_) sink->Retract();
        lock.lock();
      }
      continue;
    }
    if (!queue_.empty()) {
      const size_t index = queue_.front();
      queue_.erase(queue_.begin());
      lock.unlock();
      Slot& slot = slots_[index];
      const auto start = std::chrono::steady_clock::now();
      Status failure = Status::Ok();
      const bool ok = WriteInner(slot, &failure);
      const double ms = MsSince(start);
      lock.lock();
      write_ms_.Add(ms);
      done_seq_ = slot.seq;
      if (ok) {
        last_ok_seq_ = slot.seq;
        ++windows_;
      } else if (error_.ok()) {
        error_ = failure;
      }
      free_.push_back(index);
      cv_.notify_all();
      continue;
    }
    if (stopping_) break;
    cv_.wait(lock);
  }
}

Status QueuedSink::Stop() {
  if (!started_) return Status::Ok();
  started_ = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    stopping_ = true;  // the worker finishes the queue first
  }
  cv_.notify_all();
  worker_.join();
  Status first = error_;
  error_ = Status::Ok();
  for (FlowSink* sink : inner_) {
    Status s = sink->Stop();
    if (!s.ok() && first.ok()) first = s;
  }
  return first;
}

uint64_t QueuedSink::dropped() const {
  std::lock_guard<std::mutex> lock(mu_);
  return dropped_;
}

profiling::Summary QueuedSink::write_ms() const {
  std::lock_guard<std::mutex> lock(mu_);
  return profiling::Summarize(write_ms_.Values());
}

std::vector<double> QueuedSink::write_ms_values() const {
  std::lock_guard<std::mutex> lock(mu_);
  return write_ms_.Values();
}

void QueuedSink::ToJson(nlohmann::json* out) const {
  const profiling::Summary w = write_ms();
  std::lock_guard<std::mutex> lock(mu_);
  nlohmann::json inner = nlohmann::json::array();
  for (const FlowSink* sink : inner_) inner.push_back(sink->name());
  (*out)["queued"] = depth_;
  (*out)["policy"] = policy_ == QueuePolicy::kBlock ? "block" : "newest-wins";
  (*out)["inner"] = inner;
  (*out)["windows"] = windows_;
  (*out)["dropped"] = dropped_;
  (*out)["write_ms"] = {
      {"p50", w.p50}, {"p90", w.p90}, {"p99", w.p99}, {"max", w.max}, {"count", w.count}};
}

}  // namespace sfrt::pipeline
