#include "sfrt/pipeline/bag_replay.h"

#include <cmath>
#include <nlohmann/json.hpp>
#include <utility>
#include <vector>

#include "clock.h"
#include "sfrt/camera/window_chain.h"
#include "sfrt/pipeline/log.h"

namespace sfrt::pipeline {
namespace {

class BagSource final : public FrameSource {
 public:
  BagSource(BagReplaySpec spec, std::unique_ptr<ImageBag> bag)
      : spec_(std::move(spec)), bag_(std::move(bag)) {}

  Result<cv::Size> Open() override {
    Result<BagProbe> probe = ProbeBag(spec_, bag_.get());
    if (!probe.ok()) return probe.status();
    probe_ = *probe;
    topics_[0] = AbsoluteTopic(spec_.left_topic);
    topics_[1] = AbsoluteTopic(spec_.right_topic);
    Result<bool> first = NextPair();  // pair t of the first window
    if (!first.ok()) return first.status();
    if (!*first) {
      return Status::Error("'" + spec_.path + "': no stereo pair within " +
                           std::to_string(spec_.pair_tolerance_ms) + " ms on '" + topics_[0] +
                           "' and '" + topics_[1] + "'");
    }
    (void)chain_.Offer(pair_stamp_);
    KeepAsPrevious();
    return size_;
  }

  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>& /*stop*/) override {
    const int64_t start = detail::NowNs();
    while (true) {
      Result<bool> pair = NextPair();
      if (!pair.ok()) return pair.status();
      if (!*pair) return Fetch::kEnd;
      // A lost frame (unpaired, bad), a stamp gap or a stamp going back: this pair starts the
      // next window.
      if (chain_.Offer(pair_stamp_) != camera::ChainLink::kWindow) {
        KeepAsPrevious();
        continues_ = false;
        continue;
      }
      prev_[0].copyTo(item->left0);
      prev_[1].copyTo(item->right0);
      pair_[0].copyTo(item->left1);
      pair_[1].copyTo(item->right1);
      FrameMeta& m = item->meta;
      m.sequence.clear();
      // The left images' message numbers on their topic: the bag's own index, never a count of
      // the windows written.
      m.frame0 = prev_index_;
      m.frame1 = pair_index_;
      m.left0_path = spec_.path + ":" + topics_[0] + ":" + std::to_string(prev_index_);
      m.continues = continues_;
      m.capture_ns[0] = m.capture_ns[1] = detail::NowNs();
      m.stamp_ns[0] = prev_stamp_;
      m.stamp_ns[1] = pair_stamp_;
      m.start_ns(config::Stage::kSource) = start;
      KeepAsPrevious();
      continues_ = true;
      return Fetch::kWindow;
    }
  }

  std::string Describe() const override {
    return "bag " + spec_.path + " (" + topics_[0] + ", " + topics_[1] + ")";
  }
  std::string kind() const override { return "replay-bag"; }
  bool live() const override { return false; }
  uint64_t drops() const override { return unpaired_[0] + unpaired_[1]; }
  std::vector<BadFrame> bad_frames() const override { return bad_; }
  camera::ChainCounts chain_counts() const override { return chain_.counts(); }

  void ToJson(nlohmann::json* out) const override {
    (*out)["bag"] = spec_.path;
    (*out)["topics"] = {{"left", topics_[0]}, {"right", topics_[1]}};
    (*out)["format"] = probe_.format;
    (*out)["types"] = {{"left", probe_.left_type}, {"right", probe_.right_type}};
    (*out)["messages"] = {{"left", probe_.left_messages}, {"right", probe_.right_messages}};
    (*out)["messages_read"] = {{"left", read_[0]}, {"right", read_[1]}};
    (*out)["pairs"] = pairs_;
    (*out)["unpaired_left"] = unpaired_[0];
    (*out)["unpaired_right"] = unpaired_[1];
    (*out)["pair_tolerance_ms"] = spec_.pair_tolerance_ms;
  }

 private:
  // Reads messages until left and right form a pair (into pair_, stamps in pending_stamp_).
  // False at the end of the bag.
  Result<bool> NextPair() {
    const int64_t tolerance = static_cast<int64_t>(std::llround(spec_.pair_tolerance_ms * 1e6));
    while (true) {
      while (has_[0] && has_[1]) {
        const int64_t skew = pending_stamp_[0] - pending_stamp_[1];
        if (std::llabs(skew) <= tolerance) {
          has_[0] = has_[1] = false;
          std::swap(pair_[0], pending_[0]);
          std::swap(pair_[1], pending_[1]);
          pair_index_ = pending_index_[0];
          pair_stamp_ = pending_stamp_[0];
          ++pairs_;
          return true;
        }
        const int older = skew < 0 ? 0 : 1;  // it can never find a partner
        has_[older] = false;
        ++unpaired_[older];
        chain_.Lose();
      }
      Result<bool> more = bag_->Next(&message_);
      if (!more.ok()) return more.status();
      if (!*more) return false;
      const int side = message_.side;
      const int64_t index = message_.index;
      read_[side] = index + 1;
      const int64_t stamp = message_.message.stamp_ns;
      std::string bad = ImageMessageToBgr(message_.message, &pending_[side]);
      if (bad.empty() && size_.area() > 0 && pending_[side].size() != size_) {
        bad = "its size " + std::to_string(pending_[side].rows) + "x" +
              std::to_string(pending_[side].cols) + " (HxW) differs from the first image's " +
              std::to_string(size_.height) + "x" + std::to_string(size_.width);
      }
      const std::string where = topics_[side] + " message " + std::to_string(index);
      if (!bad.empty()) {
        bad_.push_back({spec_.path + ":" + where, bad});
        if (spec_.on_bad_frame == camera::BadFramePolicy::kStop) {
          return Status::Error("bad frame in '" + spec_.path + "', " + where + ": " + bad +
                               " (--on-bad-frame stop)");
        }
        log().Write(LogLevel::kWarn, "warning",
                    "bad frame skipped: '" + spec_.path + "', " + where + ": " + bad);
        has_[side] = false;
        chain_.Lose();  // the window would skip a frame
        continue;
      }
      if (size_.area() == 0) size_ = pending_[side].size();
      if (has_[side]) {  // the one waiting is overtaken without a partner
        ++unpaired_[side];
        chain_.Lose();
      }
      has_[side] = true;
      pending_stamp_[side] = stamp;
      pending_index_[side] = index;
    }
  }

  // The pair just formed becomes pair t of the next window.
  void KeepAsPrevious() {
    std::swap(prev_[0], pair_[0]);
    std::swap(prev_[1], pair_[1]);
    prev_index_ = pair_index_;
    prev_stamp_ = pair_stamp_;
  }

  BagReplaySpec spec_;
  std::unique_ptr<ImageBag> bag_;
  BagImage message_;  // the last message read
  BagProbe probe_;
  std::string topics_[2];
  cv::Size size_;
  cv::Mat pending_[2];  // the newest unpaired image of each side
  bool has_[2] = {false, false};
  int64_t pending_stamp_[2] = {0, 0};
  int64_t pending_index_[2] = {0, 0};
  cv::Mat pair_[2];         // the pair just formed
  int64_t pair_index_ = 0;  // the left image's message number
  int64_t pair_stamp_ = 0;  // the left image's header stamp
  cv::Mat prev_[2];         // pair t of the next window
  bool continues_ = false;
  int64_t prev_index_ = 0;
  int64_t prev_stamp_ = 0;
  int64_t pairs_ = 0;
  camera::WindowChain chain_;  // stamps: the left images' header stamps
  int64_t read_[2] = {0, 0};
  uint64_t unpaired_[2] = {0, 0};
  std::vector<BadFrame> bad_;
};

}  // namespace

std::string AbsoluteTopic(const std::string& topic) {
  return !topic.empty() && topic.front() != '/' ? "/" + topic : topic;
}

Result<BagProbe> ProbeBag(const BagReplaySpec& spec, ImageBag* bag) {
  const std::string left = AbsoluteTopic(spec.left_topic);
  const std::string right = AbsoluteTopic(spec.right_topic);
  if (left.empty() || right.empty()) {
    return Status::Error("give both the left and the right image topic");
  }
  if (left == right) return Status::Error("the left and right topics are both '" + left + "'");
  return bag->Open(spec.path, left, right);
}

std::unique_ptr<FrameSource> MakeBagReplaySource(const BagReplaySpec& spec,
                                                 std::unique_ptr<ImageBag> bag) {
  return std::make_unique<BagSource>(spec, std::move(bag));
}

}  // namespace sfrt::pipeline
