#include "sfrt/pipeline/topic_source.h"

#include <chrono>
#include <ctime>
#include <nlohmann/json.hpp>
#include <utility>

#include "clock.h"
#include "sfrt/pipeline/log.h"
#include "sfrt/pipeline/message_io.h"

namespace sfrt::pipeline {
namespace {

std::string SizeText(const cv::Size& s) {
  return std::to_string(s.height) + "x" + std::to_string(s.width) + " (HxW)";
}

}  // namespace

TopicSource::TopicSource(TopicSourceOptions options) : options_(std::move(options)) {
  if (options_.input_queue < 1) options_.input_queue = 1;
  ring_.resize(options_.input_queue);
}

void TopicSource::Skip(const std::string& reason) {
  ++bad_;
  ++skipped_since_warn_;
  loss_pending_ = true;  // the next pair must not form a window with the one before this
  {
    std::lock_guard<std::mutex> lock(mu_);
    last_bad_ = reason;
  }
  const int64_t now = detail::NowNs();
  const auto period = static_cast<int64_t>(options_.warn_period_s * 1e9);
  if (last_warn_ns_ != 0 && now - last_warn_ns_ < period) return;
  LogSink& sink = options_.log != nullptr ? *options_.log : DefaultLog();
  sink.Write(LogLevel::kWarn, "warning",
             "skipped " + std::to_string(skipped_since_warn_) + " stereo pair(s) on '" +
                 options_.left_topic + "' and '" + options_.right_topic + "': " + reason +
                 " (this warning repeats at most every " +
                 std::to_string(static_cast<int>(options_.warn_period_s)) + " s)");
  last_warn_ns_ = now;
  skipped_since_warn_ = 0;
}

void TopicSource::OnPair(const ImageMessage& left, const ImageMessage& right,
                         const std::string& left_frame_id) {
  Pair& p = scratch_;
  p.arrival_ns = detail::NowNs();
  const int64_t wall = detail::WallNs();
  const ImageMessage* views[2] = {&left, &right};
  const std::string* topics[2] = {&options_.left_topic, &options_.right_topic};
  for (int side = 0; side < 2; ++side) {
    if (std::string why = ImageMessageToBgr(*views[side], &p.image[side]); !why.empty()) {
      Skip(*topics[side] + ": " + why);
      return;
    }
  }
  if (p.image[0].size() != p.image[1].size()) {
    Skip("the left image is " + SizeText(p.image[0].size()) + ", the right " +
         SizeText(p.image[1].size()));
    return;
  }
  p.converted_ns = detail::NowNs();
  p.stamp_ns = left.stamp_ns;
  // The stamp as a capture time when it is one: not after the arrival, at most 2 s before it.
  const int64_t age = wall - left.stamp_ns;
  p.capture_ns = age >= 0 && age <= 2'000'000'000 ? p.arrival_ns - age : p.arrival_ns;
  cv::Size first;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (size_.area() == 0) {
      size_ = p.image[0].size();
      frame_id_ = left_frame_id;
    }
    first = size_;
  }
  if (p.image[0].size() != first) {
    Skip("the images are " + SizeText(p.image[0].size()) + ", the first pair's were " +
         SizeText(first));
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    p.number = static_cast<int64_t>(pairs_.load());
    p.after_loss = loss_pending_;
    loss_pending_ = false;
    if (count_ == ring_.size()) {  // full: the oldest waiting pair gives way
      head_ = (head_ + 1) % ring_.size();
      --count_;
      ++dropped_;
      // The pair after it, the oldest left (or this one), follows a lost pair.
      (count_ > 0 ? ring_[head_] : p).after_loss = true;
    }
    std::swap(ring_[(head_ + count_) % ring_.size()], p);
    ++count_;
    ++pairs_;
  }
  ready_.notify_one();
}

Result<cv::Size> TopicSource::Open() {
  log().Write(LogLevel::kInfo, "note",
              "waiting for stereo pairs on '" + options_.left_topic + "' and '" +
                  options_.right_topic + "'");
  std::unique_lock<std::mutex> lock(mu_);
  while (count_ == 0) {
    if (options_.stop != nullptr && options_.stop->load()) {
      return Status::Error("stopped before the first stereo pair arrived on '" +
                           options_.left_topic + "' and '" + options_.right_topic + "'");
    }
    ready_.wait_for(lock, std::chrono::milliseconds(100));
  }
  return size_;
}

Result<Fetch> TopicSource::Next(WindowItem* item, const std::atomic<bool>& stop) {
  while (true) {
    {
      std::unique_lock<std::mutex> lock(mu_);
      while (count_ == 0) {
        if (stop.load()) return Fetch::kEnd;
        ready_.wait_for(lock, std::chrono::milliseconds(100));
      }
      std::swap(cur_, ring_[head_]);
      head_ = (head_ + 1) % ring_.size();
      --count_;
    }
    const int64_t taken = detail::NowNs();
    // Header stamps: a gap or a bag played again (stamps going back) breaks the chain too.
    if (cur_.after_loss) chain_.Lose();
    if (chain_.Offer(cur_.stamp_ns) != camera::ChainLink::kWindow) {
      std::swap(prev_, cur_);
      continued_ = false;
      continue;
    }
    FrameMeta& m = item->meta;
    m.window = windows_;
    m.sequence.clear();
    m.frame0 = prev_.number;
    m.frame1 = cur_.number;
    m.continues = continued_;
    m.left0_path.clear();
    m.capture_ns[0] = prev_.capture_ns;
    m.capture_ns[1] = cur_.capture_ns;
    m.stamp_ns[0] = prev_.stamp_ns;
    m.stamp_ns[1] = cur_.stamp_ns;
    m.dequeue_ns = cur_.arrival_ns;
    m.paired_ns = cur_.arrival_ns;
    m.converted_ns = cur_.converted_ns;
    m.start_ns(config::Stage::kSource) = taken;
    // Pair t's buffers go to the window (the item's come back for reuse); pair t+1 is copied,
    // as it is also the next window's pair t.
    std::swap(item->left0, prev_.image[0]);
    std::swap(item->right0, prev_.image[1]);
    cur_.image[0].copyTo(item->left1);
    cur_.image[1].copyTo(item->right1);
    std::swap(prev_, cur_);
    ++windows_;
    continued_ = true;
    return Fetch::kWindow;
  }
}

size_t TopicSource::queued() const {
  std::lock_guard<std::mutex> lock(mu_);
  return count_;
}

std::string TopicSource::Describe() const {
  return "ROS topics " + options_.left_topic + ", " + options_.right_topic;
}

void TopicSource::ToJson(nlohmann::json* out) const {
  std::lock_guard<std::mutex> lock(mu_);
  (*out)["topics"] = {{"left", options_.left_topic}, {"right", options_.right_topic}};
  (*out)["frame_id"] = frame_id_;
  (*out)["pairs"] = pairs_.load();
  (*out)["pairs_dropped"] = dropped_.load();
  (*out)["bad_pairs"] = bad_.load();
  if (!last_bad_.empty()) (*out)["last_bad_pair"] = last_bad_;
  (*out)["input_queue"] = options_.input_queue;
}

}  // namespace sfrt::pipeline
