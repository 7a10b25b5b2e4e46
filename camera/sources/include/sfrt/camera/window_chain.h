// The one rule every source of (t, t+1) windows follows (issue #38): a window is two consecutive
// pairs of one stream, so its time step is the stream's frame interval, never two of them, and
// never negative. Files, videos, cameras, bags and ROS topics all feed their pairs through a
// WindowChain and form a window only when it says so.
//
// The chain breaks, and the pair after the break opens no window (it becomes pair t of the next):
//   - kLost:      the source lost a frame before this pair: a missing file, a frame without its
//                 stereo partner, a bad frame skipped, a frame the driver or a queue dropped
//                 (the source calls Lose());
//   - kGap:       the pair's stamp is more than 1.5x the stream's frame interval after the last
//                 pair's. The interval is the source's nominal one (a camera's negotiated rate)
//                 or else the median of the last intervals seen (up to kIntervals, gaps
//                 included, so a lasting change of rate is learnt); with none seen yet, no gap can
//                 be told and the pair is taken;
//   - kBackwards: the stamp is not after the last pair's (a bag played again, a clock reset):
//                 the stream restarted.
// A new stream (another sequence of a dataset, another pass of a replay) starts with Restart(),
// which counts nothing and forgets the intervals.
//
// Stamps are any increasing measure of capture time in one unit per chain: nanoseconds for
// cameras, bags, topics and videos, frame numbers for image files.
//
// No allocation, no lock, no I/O: one object per source, used by one thread.
#pragma once

#include <array>
#include <cstdint>

namespace sfrt::camera {

enum class ChainLink {
  kWindow,     // the pair forms a window with the last pair
  kFirst,      // the first pair of a stream (after Restart())
  kLost,       // a frame was lost since the last pair
  kGap,        // the stamp step exceeds 1.5x the frame interval
  kBackwards,  // the stamp is not after the last pair's
};
// "window", "first", "lost frame", "gap", "backwards".
const char* ChainLinkName(ChainLink link);

// What a chain saw, for summary.json's "windows" and the console.
struct ChainCounts {
  int64_t windows = 0;          // windows formed
  int64_t broken_by_loss = 0;   // pairs that opened no window because a frame was lost
  int64_t skipped_for_gap = 0;  // pairs that opened no window because of a stamp gap
  int64_t stream_restarts = 0;  // pairs whose stamp went backwards
  int64_t breaks() const { return broken_by_loss + skipped_for_gap + stream_restarts; }
  ChainCounts& operator+=(const ChainCounts& other) {  // several passes or streams of a source
    windows += other.windows;
    broken_by_loss += other.broken_by_loss;
    skipped_for_gap += other.skipped_for_gap;
    stream_restarts += other.stream_restarts;
    return *this;
  }
};

class WindowChain {
 public:
  static constexpr int kIntervals = 15;  // intervals the median is taken over

  // nominal_interval: the stream's frame interval in the stamps' unit when the source knows it
  // (a camera's negotiated rate); 0 or less: the median of the intervals seen.
  explicit WindowChain(int64_t nominal_interval = 0) : nominal_(nominal_interval) {}

  // The next pair of the stream, by its stamp. kWindow: it forms a window with the last pair
  // offered; otherwise it only becomes pair t of the next window (and the reason is counted).
  ChainLink Offer(int64_t stamp);
  // A frame of the stream was lost: the next pair offered opens no window.
  void Lose() { lost_ = true; }
  // A new stream starts (nothing is counted; intervals are forgotten).
  void Restart();

  const ChainCounts& counts() const { return counts_; }
  // The interval a gap is judged against now: the nominal one, the median of those seen, or 0
  // when none is known yet.
  int64_t interval() const;

 private:
  void Remember(int64_t interval);

  int64_t nominal_;
  bool have_last_ = false;
  bool lost_ = false;
  int64_t last_ = 0;
  std::array<int64_t, kIntervals> intervals_{};  // a ring of the last positive intervals
  int seen_ = 0;                                 // how many of them hold one
  int next_ = 0;
  ChainCounts counts_;
};

}  // namespace sfrt::camera
