#include "sfrt/pipeline/sources.h"

#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <utility>

#include "clock.h"
#include "sfrt/camera/image_file.h"
#include "sfrt/camera/v4l2/pixel_format.h"
#include "sfrt/pipeline/log.h"

namespace sfrt::pipeline {
namespace {

using detail::NowNs;

// ------------------------------------------------------------------------------------ replay

class ReplaySource : public FrameSource {
 public:
  explicit ReplaySource(ReplaySpec spec) : spec_(std::move(spec)) {}

  Result<cv::Size> Open() override {
    if (spec_.loops < 1) {
      return Status::Error("replay: loops is " + std::to_string(spec_.loops) + "; must be >= 1");
    }
    Result<cv::Size> size = OpenPass();
    if (size.ok() && total_) total_ = *total_ * spec_.loops;
    if (size.ok() && !quiet_) NoteImageFormat(window_->previous().left_path);
    return size;
  }

  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>& /*stop*/) override {
    const int64_t start = NowNs();
    if (!primed_) {
      Result<Fetch> next = Advance();
      if (next.ok() && *next == Fetch::kEnd && ++pass_ < spec_.loops) {
        const std::optional<int64_t> total = total_;
        Result<cv::Size> size = OpenPass();
        total_ = total;
        if (!size.ok()) return size.status();
        next = Fetch::kWindow;
      }
      if (!next.ok() || *next == Fetch::kEnd) return next;
    }
    primed_ = false;
    const camera::FramePair& prev = window_->previous();
    const camera::FramePair& cur = window_->current();
    prev.left.copyTo(item->left0);
    prev.right.copyTo(item->right0);
    cur.left.copyTo(item->left1);
    cur.right.copyTo(item->right1);
    FrameMeta& m = item->meta;
    m.sequence = cur.sequence;
    m.frame0 = prev.frame_number;
    m.frame1 = cur.frame_number;
    m.left0_path = prev.left_path;
    // Pair t is the last window's pair t+1 when the window moved on by one pair in this pass.
    m.continues = emitted_ > 0 && pass_ == last_pass_ && cur.sequence == last_sequence_ &&
                  prev.frame_number == last_frame1_ && prev.left_path == last_left1_path_;
    ++emitted_;
    last_pass_ = pass_;
    last_sequence_ = cur.sequence;
    last_frame1_ = cur.frame_number;
    last_left1_path_ = cur.left_path;
    const int64_t now = NowNs();
    m.capture_ns[0] = m.capture_ns[1] = now;
    m.start_ns(config::Stage::kSource) = start;
    return Fetch::kWindow;
  }

  std::string Describe() const override {
    std::string d = source_ ? source_->Describe() : std::string("replay (not open)");
    if (spec_.loops > 1) d += ", " + std::to_string(spec_.loops) + " passes";
    return d;
  }
  std::string kind() const override {
    switch (spec_.kind) {
      case ReplaySpec::Kind::kDataset:
        return "replay";
      case ReplaySpec::Kind::kPlain:
        return "replay-left/right";
      case ReplaySpec::Kind::kVideo:
        return "replay-video";
    }
    return "replay";
  }
  std::optional<int64_t> total_windows() const override { return total_; }
  bool live() const override { return false; }
  void ToJson(nlohmann::json* out) const override {
    nlohmann::json& j = *out;
    j["on_bad_frame"] = camera::BadFramePolicyName(spec_.on_bad_frame);
    if (spec_.kind == ReplaySpec::Kind::kDataset) j["root"] = spec_.root;
    if (spec_.kind == ReplaySpec::Kind::kPlain) {
      j["left"] = spec_.left;
      j["right"] = spec_.right;
    }
    if (spec_.kind == ReplaySpec::Kind::kVideo) j["video"] = spec_.video;
    if (total_) j["windows_expected"] = *total_;
    j["loops"] = spec_.loops;
    // Each image is decoded once: pair t+1 of a window is pair t of the next (camera::PairWindow),
    // so images_decoded equals images_listed when every pass ran to its end without bad frames.
    j["images_decoded"] = decoded_before_ + (source_ ? source_->images_decoded() : 0);
    j["images_listed"] = images_listed_;
  }
  std::vector<BadFrame> bad_frames() const override { return bad_; }
  camera::ChainCounts chain_counts() const override {
    camera::ChainCounts c = chain_before_;
    if (window_) c += window_->counts();
    return c;
  }

 private:
  // A note, once per run, when the first frame is not 8-bit colour: grayscale is used as BGR with
  // three equal channels, 16-bit is scaled to 8 bits (cv::IMREAD_COLOR).
  void NoteImageFormat(const std::string& path) const {
    if (path.empty()) return;
    // From the header: the first frame is not decoded a second time.
    camera::Result<camera::ImageHeader> header = camera::ReadImageHeader(path);
    const std::string what = header.ok() ? camera::NotEightBitColour(*header) : "";
    if (what.empty()) return;
    log().Write(LogLevel::kInfo, "note",
                "'" + path + "' is " + what +
                    "; frames are read as 8-bit BGR (grey copied to three channels, 16-bit "
                    "scaled to 8 bits)");
  }

  // Opens the files for one pass and reads the first pair of the first window.
  Result<cv::Size> OpenPass() {
    // Always skip inside camera/sources and apply the policy here, so a bad frame that stops
    // the run is recorded by path like a skipped one.
    camera::SourceOptions base;
    base.on_bad_frame = camera::BadFramePolicy::kSkip;
    base.on_bad_frame_callback = [this](const camera::BadFrame& bad) { bad_.push_back(bad); };
    if (source_) decoded_before_ += source_->images_decoded();  // the previous pass's
    if (window_) chain_before_ += window_->counts();
    switch (spec_.kind) {
      case ReplaySpec::Kind::kDataset: {
        camera::DatasetOptions options;
        static_cast<camera::SourceOptions&>(options) = base;
        options.pass = spec_.pass;
        options.sequences = spec_.sequences;
        auto info = camera::DetectDataset(spec_.root, options);
        if (!info.ok()) return info.status();
        const int64_t sequences = static_cast<int64_t>(info->sequences.size());
        total_ = std::max<int64_t>(0, info->pairs - sequences);
        auto source = camera::OpenDatasetSource(spec_.root, options);
        if (!source.ok()) return source.status();
        source_ = std::move(source).value();
        break;
      }
      case ReplaySpec::Kind::kPlain: {
        auto source = camera::OpenPlainSource(spec_.left, spec_.right, base);
        if (!source.ok()) return source.status();
        source_ = std::move(source).value();
        if (auto n = source_->size()) total_ = std::max<int64_t>(0, *n - 1);
        break;
      }
      case ReplaySpec::Kind::kVideo: {
        camera::VideoOptions options;
        static_cast<camera::SourceOptions&>(options) = base;
        options.left_first = spec_.video_left_first;
        auto source = camera::OpenSbsVideoSource(spec_.video, options);
        if (!source.ok()) return source.status();
        source_ = std::move(source).value();
        if (auto n = source_->size()) total_ = std::max<int64_t>(0, *n - 1);
        break;
      }
    }
    window_ = std::make_unique<camera::PairWindow>(source_.get());
    // Images each pass holds: two files per pair, one video frame per pair.
    if (auto n = source_->size())
      images_listed_ += *n * (spec_.kind == ReplaySpec::Kind::kVideo ? 1 : 2);
    Result<Fetch> first = Advance();
    if (!first.ok()) return first.status();
    if (*first == Fetch::kEnd) {
      std::string why;  // the bad frames that left no window, e.g. left and right sizes differ
      if (!bad_.empty()) {
        why = "; " + std::to_string(bad_.size()) + " bad frame(s), the first '" + bad_[0].path +
              "': " + bad_[0].reason;
      }
      return Status::Error(source_->Describe() +
                           ": no two consecutive stereo pairs to form a (t, t+1) window" + why);
    }
    primed_ = true;
    return window_->current().left.size();
  }

  // One PairWindow step, with --on-bad-frame stop applied.
  Result<Fetch> Advance() {
    const size_t bad_before = bad_.size();
    camera::Result<camera::Fetched> next = window_->Next();
    if (!next.ok()) return next.status();
    if (spec_.on_bad_frame == camera::BadFramePolicy::kSkip && !quiet_) {
      for (size_t i = bad_before; i < bad_.size(); ++i) {
        log().Write(LogLevel::kWarn, "warning",
                    "bad frame skipped: '" + bad_[i].path + "': " + bad_[i].reason);
      }
    }
    if (spec_.on_bad_frame == camera::BadFramePolicy::kStop && bad_.size() > bad_before) {
      const camera::BadFrame& bad = bad_[bad_before];
      return Status::Error("bad frame '" + bad.path + "': " + bad.reason +
                           " (--on-bad-frame stop)");
    }
    return *next == camera::Fetched::kPair ? Fetch::kWindow : Fetch::kEnd;
  }

  ReplaySpec spec_;
  std::unique_ptr<camera::StereoSource> source_;
  uint64_t decoded_before_ = 0;       // images decoded by earlier passes' sources
  camera::ChainCounts chain_before_;  // earlier passes' chains
  int64_t images_listed_ = 0;         // images of the passes opened so far
  std::unique_ptr<camera::PairWindow> window_;
  std::vector<camera::BadFrame> bad_;
  std::optional<int64_t> total_;
  int64_t pass_ = 0;
  bool primed_ = false;
  // The last window delivered: its pass and pair t+1 (for FrameMeta::continues).
  int64_t emitted_ = 0;
  int64_t last_pass_ = -1;
  std::string last_sequence_;
  int64_t last_frame1_ = -1;
  std::string last_left1_path_;

 public:
  bool quiet_ = false;  // ProbeReplay: no console lines
};

// ------------------------------------------------------------------------------------ camera

class CameraSource : public FrameSource {
 public:
  CameraSource(v4l2::StereoConfig config, camera::BadFramePolicy policy)
      : config_(std::move(config)), policy_(policy), cap_(config_) {}

  Result<cv::Size> Open() override {
    camera::Status s = cap_.Open();
    if (!s.ok()) return s;
    const v4l2::NegotiatedFormat& left = cap_.left().format();
    // The driver's rate is the interval a gap is judged against; without one, the stream's own.
    chain_ = camera::WindowChain(left.fps > 0 ? std::llround(1e9 / left.fps) : 0);
    if (sbs()) {
      if (left.width % 2 != 0) {
        return Status::Error(config_.left.device + ": side-by-side frame width " +
                             std::to_string(left.width) + " is odd");
      }
      return cv::Size(left.width / 2, left.height);
    }
    const v4l2::NegotiatedFormat& right = cap_.right().format();
    if (right.width != left.width || right.height != left.height) {
      return Status::Error(config_.right.device + ": the driver granted " +
                           std::to_string(right.height) + "x" + std::to_string(right.width) +
                           " (HxW) but " + config_.left.device + " has " +
                           std::to_string(left.height) + "x" + std::to_string(left.width) +
                           " (both cameras need one size)");
    }
    return cv::Size(left.width, left.height);
  }

  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>& stop) override {
    const int64_t start = NowNs();
    cap_.set_cancel_flag(&stop);  // a stop ends a reopen back-off at once
    while (!stop.load()) {
      // A device already lost before this call is being reopened: a success is a reconnection,
      // and a disconnect error that detected no new unplug is a failed reopen attempt (counted
      // apart from the unplugs).
      bool was_lost[2] = {false, false};
      for (int i = 0; i < devices(); ++i) was_lost[i] = device(i).disconnected();
      const uint64_t unplugs_before = Unplugs();
      camera::Status s = cap_.Next(&pair_);
      for (int i = 0; i < devices(); ++i) {
        if (was_lost[i] && !device(i).disconnected()) {
          log().Write(LogLevel::kInfo, "camera",
                      device(i).config().device + ": reconnected at reopen attempt " +
                          std::to_string(device(i).stats().reopen_attempts));
        }
      }
      if (s.kind() == camera::ErrorKind::kCancelled) break;  // stop requested
      if (!s.ok()) {
        if (Status fatal = CountError(s, unplugs_before); !fatal.ok()) return fatal;
        continue;
      }
      if (TakePair(item, start)) return Fetch::kWindow;
    }
    return Fetch::kEnd;
  }

  std::string Describe() const override {
    if (sbs()) return "side-by-side camera " + config_.left.device;
    return "stereo cameras " + config_.left.device + " (left), " + config_.right.device +
           " (right)";
  }
  std::string kind() const override { return sbs() ? "sbs-camera" : "camera"; }
  bool live() const override { return true; }

  uint64_t drops() const override {
    uint64_t n = cap_.stats().unpaired_left + cap_.stats().unpaired_right;
    for (int i = 0; i < (sbs() ? 1 : 2); ++i) {
      const v4l2::CaptureStats& s = i == 0 ? cap_.left().stats() : cap_.right().stats();
      n += s.sequence_drops + s.stale_dropped;
    }
    return n;
  }

  void ToJson(nlohmann::json* out) const override {
    nlohmann::json& j = *out;
    j["mode"] = sbs() ? "side-by-side" : "two devices";
    j["pairs"] = cap_.stats().pairs;
    if (sbs()) {
      j["sbs_left_first"] = config_.sbs_left_first;
    } else {
      j["pair_tolerance_ms"] = static_cast<double>(config_.pair_tolerance_ns) / 1e6;
      j["unpaired_left"] = cap_.stats().unpaired_left;
      j["unpaired_right"] = cap_.stats().unpaired_right;
    }
    j["disconnects"] = disconnects_;
    j["reopen_failures"] = reopen_failures_;
    j["timeouts"] = timeouts_;
    j["io_errors"] = io_errors_;
    j["frame_errors"] = frame_errors_;
    j["on_bad_frame"] = camera::BadFramePolicyName(policy_);
    nlohmann::json devices = nlohmann::json::array();
    for (int i = 0; i < (sbs() ? 1 : 2); ++i) {
      const v4l2::CaptureDevice& d = i == 0 ? cap_.left() : cap_.right();
      const v4l2::NegotiatedFormat& f = d.format();
      const v4l2::CaptureStats& s = d.stats();
      nlohmann::json dev;
      dev["device"] = d.config().device;
      dev["role"] = sbs() ? "both" : (i == 0 ? "left" : "right");
      dev["format"] = v4l2::FourccToString(f.fourcc);
      dev["width"] = f.width;
      dev["height"] = f.height;
      dev["fps"] = f.fps;
      dev["buffers"] = f.buffer_count;
      dev["driver"] = f.driver;
      dev["card"] = f.card;
      dev["adjustments"] = f.adjustments;
      dev["frames_dequeued"] = s.frames_dequeued;
      dev["frames_delivered"] = s.frames_delivered;
      dev["sequence_drops"] = s.sequence_drops;
      dev["stale_dropped"] = s.stale_dropped;
      dev["error_flag_frames"] = s.error_flag_frames;
      dev["short_frames"] = s.short_frames;
      dev["decode_errors"] = s.decode_errors;
      dev["eio"] = s.eio;
      dev["watchdog_timeouts"] = s.watchdog_timeouts;
      dev["disconnects"] = s.disconnects;
      dev["reopen_attempts"] = s.reopen_attempts;
      dev["reopens"] = s.reopens;
      if (have_seq_) {
        dev["first_sequence"] = first_seq_[i];
        dev["last_sequence"] = last_seq_[i];
      }
      devices.push_back(dev);
    }
    j["devices"] = devices;
  }

  std::vector<BadFrame> bad_frames() const override { return bad_; }
  camera::ChainCounts chain_counts() const override { return chain_.counts(); }

 private:
  bool sbs() const { return config_.mode == v4l2::StereoConfig::Mode::kSideBySide; }
  int devices() const { return sbs() ? 1 : 2; }
  const v4l2::CaptureDevice& device(int i) const { return i == 0 ? cap_.left() : cap_.right(); }
  uint64_t Unplugs() const {
    uint64_t n = 0;
    for (int i = 0; i < devices(); ++i) n += device(i).stats().disconnects;
    return n;
  }
  void Log(const std::string& message) const { log().Write(LogLevel::kWarn, "camera", message); }
  // A capture error, counted (and logged where the console should see it): Ok where capture
  // goes on (a timeout, an unplug and its reopening, a bad frame skipped), else the error that
  // ends the run.
  Status CountError(const camera::Status& s, uint64_t unplugs_before) {
    const bool lost = cap_.left().disconnected() || (!sbs() && cap_.right().disconnected());
    switch (s.kind()) {
      case camera::ErrorKind::kDisconnected:
        ++(Unplugs() > unplugs_before ? disconnects_ : reopen_failures_);
        chain_.Lose();
        Log(s.message());
        return Status::Ok();
      case camera::ErrorKind::kTimeout:
        ++timeouts_;
        Log(s.message());
        return Status::Ok();
      case camera::ErrorKind::kIo:
        ++io_errors_;
        return Status::Ok();
      case camera::ErrorKind::kFrameError:
        ++frame_errors_;
        bad_.push_back(
            {config_.left.device + (sbs() ? "" : "," + config_.right.device), s.message()});
        if (policy_ == camera::BadFramePolicy::kStop) {
          return Status::Error("bad frame: " + s.message() + " (--on-bad-frame stop)");
        }
        chain_.Lose();  // the window would skip a frame
        return Status::Ok();
      default:
        if (lost) {  // reopening after an unplug: keep trying with the back-off
          ++reopen_failures_;
          Log(s.message());
          return Status::Ok();
        }
        return s;
    }
  }

  // The pair just captured as pair t+1: whether it ends a window (then written into `item`,
  // with pair t); either way it becomes the next window's pair t.
  bool TakePair(WindowItem* item, int64_t start) {
    const v4l2::Frame& l = pair_.left;
    const v4l2::Frame& r = pair_.right;
    for (int i = 0; i < 2; ++i) {
      const uint32_t seq = i == 0 ? l.sequence : r.sequence;
      if (!have_seq_) first_seq_[i] = seq;
      last_seq_[i] = seq;
    }
    have_seq_ = true;
    const cv::Mat lm(l.height, l.width, CV_8UC3, const_cast<uint8_t*>(l.bgr.data()));
    const cv::Mat rm(r.height, r.width, CV_8UC3, const_cast<uint8_t*>(r.bgr.data()));
    const int64_t ts = std::max(l.timestamp_ns, r.timestamp_ns);
    // A sequence number that skips is a frame the driver dropped, one this process passed over
    // for a newer one, or one left without its partner: the window would span it.
    if (have_prev_ &&
        (l.sequence != prev_seq_[0] + 1 || (!sbs() && r.sequence != prev_seq_[1] + 1))) {
      chain_.Lose();
    }
    // A pair t of another size (a device reopened with a new format) starts a new stream.
    if (have_prev_ && (prev_size_[0] != lm.size() || prev_size_[1] != rm.size())) {
      chain_.Restart();
    }
    const bool emit = chain_.Offer(ts) == camera::ChainLink::kWindow;
    if (emit) {
      const cv::Mat pl(prev_size_[0], CV_8UC3, prev_bgr_[0].data());
      const cv::Mat pr(prev_size_[1], CV_8UC3, prev_bgr_[1].data());
      pl.copyTo(item->left0);
      pr.copyTo(item->right0);
      lm.copyTo(item->left1);
      rm.copyTo(item->right1);
      FrameMeta& m = item->meta;
      m.sequence.clear();
      m.frame0 = prev_seq_[0];
      m.frame1 = l.sequence;
      m.left0_path.clear();
      m.capture_ns[0] = prev_ts_;
      m.capture_ns[1] = ts;
      m.start_ns(config::Stage::kSource) = start;
      m.dequeue_ns = l.timestamp_ns >= r.timestamp_ns ? l.dequeue_ns : r.dequeue_ns;
      m.paired_ns = pair_.paired_ns;
      m.converted_ns = pair_.converted_ns;
      m.continues = prev_was_emitted_;  // pair t was the last window's pair t+1
    }
    prev_was_emitted_ = emit;
    // Pair t+1 becomes the next window's pair t by swapping buffers, not copying; the next
    // conversion writes into the old pair t's (same size: no allocation).
    std::swap(prev_bgr_[0], pair_.left.bgr);
    std::swap(prev_bgr_[1], pair_.right.bgr);
    prev_size_[0] = lm.size();
    prev_size_[1] = rm.size();
    prev_seq_[0] = l.sequence;
    prev_seq_[1] = r.sequence;
    prev_ts_ = ts;
    have_prev_ = true;
    return emit;
  }

  v4l2::StereoConfig config_;
  camera::BadFramePolicy policy_;
  v4l2::StereoCapture cap_;
  v4l2::StereoPair pair_;
  std::vector<uint8_t> prev_bgr_[2];  // BGR of the previous pair (left, right)
  cv::Size prev_size_[2];
  bool prev_was_emitted_ = false;  // the previous pair was pair t+1 of the last window
  bool have_prev_ = false;
  uint32_t prev_seq_[2] = {0, 0};  // the V4L2 sequence numbers of the previous pair
  int64_t prev_ts_ = 0;
  camera::WindowChain chain_;
  bool have_seq_ = false;
  uint32_t first_seq_[2] = {0, 0};
  uint32_t last_seq_[2] = {0, 0};
  uint64_t disconnects_ = 0, timeouts_ = 0, io_errors_ = 0, frame_errors_ = 0;
  uint64_t reopen_failures_ = 0;  // failed reopen attempts after a disconnect (logged each)
  std::vector<BadFrame> bad_;
};

}  // namespace

Result<int64_t> ProbeReplay(const ReplaySpec& spec) {
  if (spec.kind == ReplaySpec::Kind::kPlain) {
    auto left = camera::ListFrameFiles(spec.left);
    if (!left.ok()) return Status::Error("left frames: " + left.message());
    auto right = camera::ListFrameFiles(spec.right);
    if (!right.ok()) return Status::Error("right frames: " + right.message());
    if (left->size() != right->size()) {
      return Status::Error("left frames '" + spec.left + "' has " + std::to_string(left->size()) +
                           " images but right frames '" + spec.right + "' has " +
                           std::to_string(right->size()) +
                           "; left and right pair by position, so the counts must match");
    }
  }
  ReplaySpec once = spec;
  once.loops = 1;
  once.on_bad_frame = camera::BadFramePolicy::kSkip;
  ReplaySource probe(once);
  probe.quiet_ = true;
  Result<cv::Size> size = probe.Open();
  if (!size.ok()) return size.status();
  return probe.total_windows().value_or(0);
}

std::unique_ptr<FrameSource> MakeReplaySource(const ReplaySpec& spec) {
  return std::make_unique<ReplaySource>(spec);
}

std::unique_ptr<FrameSource> MakeCameraSource(const v4l2::StereoConfig& config,
                                              camera::BadFramePolicy on_bad_frame) {
  return std::make_unique<CameraSource>(config, on_bad_frame);
}

}  // namespace sfrt::pipeline
