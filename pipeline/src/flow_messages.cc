#include "sfrt/pipeline/flow_messages.h"

#include <chrono>

#include "clock.h"

namespace sfrt::pipeline {

std::string WriteFlowMessages(const FlowFrame& frame, int64_t stamp_t0, int64_t stamp_t1,
                              const std::string& frame_id, const FlowTopics& topics,
                              FlowRenderer* renderer, MessageWriter* writer) {
  const auto seq = static_cast<uint32_t>(frame.meta->window);
  const auto row = static_cast<uint32_t>(frame.width * frame.channels * sizeof(float));
  const std::string encoding = "32FC" + std::to_string(frame.channels);
  std::string e = writer->WriteImage(
      topics.flow, stamp_t0, seq, frame_id, encoding, static_cast<uint32_t>(frame.height),
      static_cast<uint32_t>(frame.width), row, reinterpret_cast<const uint8_t*>(frame.flow.data()));
  if (e.empty()) e = writer->WriteHeader(topics.t1, stamp_t1, seq, frame_id);
  if (e.empty() && renderer != nullptr) {
    e = WriteVisMessage(frame, stamp_t0, frame_id, topics.vis, renderer, writer);
  }
  return e;
}

std::string WriteVisMessage(const FlowFrame& frame, int64_t stamp_t0, const std::string& frame_id,
                            const std::string& topic, FlowRenderer* renderer,
                            MessageWriter* writer) {
  const cv::Mat& canvas = renderer->Render(frame);
  return writer->WriteImage(topic, stamp_t0, static_cast<uint32_t>(frame.meta->window), frame_id,
                            "bgr8", static_cast<uint32_t>(canvas.rows),
                            static_cast<uint32_t>(canvas.cols),
                            static_cast<uint32_t>(canvas.step[0]), canvas.data);
}

void FlowRecorder::Start() {
  realtime_minus_monotonic_ns_ = detail::WallNs() - detail::NowNs();
  if (options_.vis) renderer_.emplace(options_.vis_options);
}

int64_t FlowRecorder::WallStamp(const FrameMeta& m, int pair) const {
  if (m.stamp_ns[pair] != 0) return m.stamp_ns[pair];
  return m.capture_ns[pair] + realtime_minus_monotonic_ns_;
}

Status FlowRecorder::Fail(const std::string& error) {
  failed_ = true;
  return Status::Error(error);
}

Status FlowRecorder::Write(const FlowFrame& frame, MessageWriter* writer) {
  std::lock_guard<std::mutex> lock(mu_);
  if (failed_) return Status::Error("the bag '" + options_.path + "' failed earlier");
  const FrameMeta& m = *frame.meta;
  const FlowTopics topics{options_.flow_topic, options_.t1_topic, options_.vis_topic};
  const std::string e =
      WriteFlowMessages(frame, WallStamp(m, 0), WallStamp(m, 1), options_.frame_id, topics,
                        renderer_ ? &*renderer_ : nullptr, writer);
  if (!e.empty()) return Fail(e);
  ++windows_;
  return Status::Ok();
}

Status FlowRecorder::WriteInputs(const WindowItem& item, MessageWriter* writer) {
  std::lock_guard<std::mutex> lock(mu_);
  if (failed_) return Status::Error("the bag '" + options_.path + "' failed earlier");
  const FrameMeta& m = item.meta;
  const cv::Mat* pairs[2][2] = {{&item.left0, &item.right0}, {&item.left1, &item.right1}};
  const int64_t frames[2] = {m.frame0, m.frame1};
  for (int pair = m.continues ? 1 : 0; pair < 2; ++pair) {
    const auto seq = static_cast<uint32_t>(frames[pair] < 0 ? 0 : frames[pair]);
    for (int side = 0; side < 2; ++side) {
      const cv::Mat& image = *pairs[pair][side];
      if (image.type() != CV_8UC3) return Fail("an input image is not BGR8");
      const std::string e = writer->WriteImage(
          side == 0 ? options_.left_topic : options_.right_topic, WallStamp(m, pair), seq,
          side == 0 ? options_.frame_id : options_.right_frame_id, "bgr8",
          static_cast<uint32_t>(image.rows), static_cast<uint32_t>(image.cols),
          static_cast<uint32_t>(image.step[0]), image.data);
      if (!e.empty()) return Fail(e);
    }
    ++input_pairs_;
  }
  return Status::Ok();
}

bool FlowRecorder::failed() const {
  std::lock_guard<std::mutex> lock(mu_);
  return failed_;
}

int64_t FlowRecorder::windows() const {
  std::lock_guard<std::mutex> lock(mu_);
  return windows_;
}

int64_t FlowRecorder::input_pairs() const {
  std::lock_guard<std::mutex> lock(mu_);
  return input_pairs_;
}

namespace {

class RecordingSource final : public FrameSource {
 public:
  RecordingSource(std::unique_ptr<FrameSource> source, InputRecorder* recorder)
      : source_(std::move(source)), recorder_(recorder) {}
  Result<cv::Size> Open() override {
    source_->set_log(&log());
    return source_->Open();
  }
  Result<Fetch> Next(WindowItem* item, const std::atomic<bool>& stop) override {
    Result<Fetch> fetch = source_->Next(item, stop);
    if (!fetch.ok() || *fetch != Fetch::kWindow) return fetch;
    if (!source_->live() && item->meta.stamp_ns[0] == 0 && item->meta.stamp_ns[1] == 0) {
      StampOnFixedClock(&item->meta);
    }
    if (Status s = recorder_->RecordInputs(*item); !s.ok()) {
      return Status::Error("recording the input images: " + s.message());
    }
    return fetch;
  }
  std::string Describe() const override { return source_->Describe(); }
  std::string kind() const override { return source_->kind(); }
  std::optional<int64_t> total_windows() const override { return source_->total_windows(); }
  bool live() const override { return source_->live(); }
  void ToJson(nlohmann::json* out) const override { source_->ToJson(out); }
  uint64_t drops() const override { return source_->drops(); }
  std::vector<BadFrame> bad_frames() const override { return source_->bad_frames(); }
  camera::ChainCounts chain_counts() const override { return source_->chain_counts(); }

 private:
  // Files: pair t+1 one period after pair t; pair t the last window's pair t+1 when the window
  // continues it, else a break after it (kRecordedBreakNs).
  void StampOnFixedClock(FrameMeta* m) {
    if (last_stamp_ns_ == 0) {
      last_stamp_ns_ = std::chrono::duration_cast<std::chrono::nanoseconds>(
                           std::chrono::system_clock::now().time_since_epoch())
                           .count();
      m->stamp_ns[0] = last_stamp_ns_;
    } else {
      m->stamp_ns[0] = m->continues ? last_stamp_ns_ : last_stamp_ns_ + kRecordedBreakNs;
    }
    m->stamp_ns[1] = m->stamp_ns[0] + kRecordedFramePeriodNs;
    last_stamp_ns_ = m->stamp_ns[1];
  }

  std::unique_ptr<FrameSource> source_;
  InputRecorder* recorder_;
  int64_t last_stamp_ns_ = 0;  // pair t+1 of the last window, on the fixed clock
};

}  // namespace

std::unique_ptr<FrameSource> MakeRecordingSource(std::unique_ptr<FrameSource> source,
                                                 InputRecorder* recorder) {
  return std::make_unique<RecordingSource>(std::move(source), recorder);
}

}  // namespace sfrt::pipeline
