// A node's source: stereo pairs from a middleware's image topics (paired by the node's adapter:
// sfrt_ros with message_filters' ApproximateTime) as a FrameSource. The pairs arrive as
// ImageMessages (message_io.h), so the ROS 1 and ROS 2 nodes feed the same class.
//
// Handoff: OnPair() (the spinner's thread) converts both images to BGR8 into buffers of its own
// and swaps them into a ring of `input_queue` pairs; the source stage takes the oldest. When the
// ring is full the oldest waiting pair is dropped and counted (drops()): with the default of one
// slot the source stage always gets the newest pair. After the first pairs every buffer has the
// frame size and circulates by swapping: no allocation per pair.
//
// Windows: pair k and pair k+1 as delivered form a window by the rule of
// sfrt/camera/window_chain.h, on the left images' header stamps: a pair dropped from the input
// queue or skipped as bad, a stamp gap beyond 1.5x the median interval, or a stamp that is not
// after the last one (`rosbag play` again, or `-l`) breaks the chain, and the pair after it opens
// no window, so a published flow's t+1 is always after its t. Each pair is rectified once
// (FrameMeta::continues while the chain holds).
//
// Times: FrameMeta::stamp_ns are the left images' header stamps. capture_ns is the image's
// header stamp moved to CLOCK_MONOTONIC when the stamp is a plausible capture time (at most
// 2 s before its arrival and not after it, on the wall clock), so the end to end starts at the
// camera and the transport shows as capture_to_dequeue; otherwise (a bag played with its old
// stamps, or a clock off) the arrival of the pair.
//
// Bad pairs (an encoding it cannot convert, a corrupt JPEG, left and right or a later pair of
// another size) are skipped and counted; one warning naming the reason per `warn_period_s`, with
// the count skipped since the last one.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "sfrt/pipeline/log.h"
#include "sfrt/pipeline/message_io.h"
#include "sfrt/pipeline/pipeline.h"

namespace sfrt::pipeline {

struct TopicSourceOptions {
  std::string left_topic = "/left/image_rect";  // for messages and the summary
  std::string right_topic = "/right/image_rect";
  size_t input_queue = 1;    // pairs waiting for the source stage (>= 1)
  double warn_period_s = 5;  // the bad-pair warning at most this often
  // Open() waits for the first pair until this is set (null: until the first pair).
  const std::atomic<bool>* stop = nullptr;
  // Where OnPair()'s warnings go (it runs before RunPipeline() sets the source's log, so it has
  // its own); must take calls from any thread. Null: DefaultLog().
  LogSink* log = nullptr;
};

class TopicSource final : public FrameSource {
 public:
  explicit TopicSource(TopicSourceOptions options);

  // One ApproximateTime pair; called on the spinner's thread.
  void OnPair(const ImageMessage& left, const ImageMessage& right,
              const std::string& left_frame_id);

  // Waits for the first pair (logging that it waits) and returns its size.
  Result<cv::Size> Open() override;
  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>& stop) override;
  std::string Describe() const override;
  std::string kind() const override { return "ros-topics"; }
  bool live() const override { return true; }
  void ToJson(nlohmann::json* out) const override;
  uint64_t drops() const override { return dropped_.load(); }
  // Read once the source stage has ended (RunPipeline makes its summary after joining it).
  camera::ChainCounts chain_counts() const override { return chain_.counts(); }

  // The left images' frame_id, known once Open() has returned.
  const std::string& frame_id() const { return frame_id_; }
  uint64_t pairs() const { return pairs_.load(); }
  uint64_t bad_pairs() const { return bad_.load(); }
  // Pairs waiting in the input queue for Next().
  size_t queued() const;

 private:
  struct Pair {
    cv::Mat image[2];
    int64_t number = 0;
    int64_t stamp_ns = 0;    // the left header stamp
    int64_t capture_ns = 0;  // CLOCK_MONOTONIC (see above)
    int64_t arrival_ns = 0;  // OnPair() entered
    int64_t converted_ns = 0;
    bool after_loss = false;  // a pair before this one was dropped or skipped
  };
  void Skip(const std::string& reason);

  TopicSourceOptions options_;
  // The spinner's thread only.
  Pair scratch_;
  int64_t last_warn_ns_ = 0;
  uint64_t skipped_since_warn_ = 0;
  bool loss_pending_ = false;  // a pair was skipped since the last one pushed
  // Shared, under mu_.
  mutable std::mutex mu_;
  std::condition_variable ready_;
  std::vector<Pair> ring_;
  size_t head_ = 0;  // the oldest waiting pair
  size_t count_ = 0;
  cv::Size size_;  // the first pair's; later pairs must match
  std::string frame_id_;
  std::string last_bad_;  // the last reason a pair was skipped
  // The source stage's thread only.
  Pair prev_, cur_;
  camera::WindowChain chain_;
  bool continued_ = false;  // the last pair taken was pair t+1 of the last window
  int64_t windows_ = 0;
  // Counters, read from any thread.
  std::atomic<uint64_t> pairs_{0}, dropped_{0}, bad_{0};
};

}  // namespace sfrt::pipeline
