#include "sfrt/pipeline/flow_messages.h"

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

Status FlowRecorder::Write(const FlowFrame& frame, MessageWriter* writer) {
  if (failed_) return Status::Error("the bag '" + options_.path + "' failed earlier");
  const FrameMeta& m = *frame.meta;
  const FlowTopics topics{options_.flow_topic, options_.t1_topic, options_.vis_topic};
  const std::string e =
      WriteFlowMessages(frame, WallStamp(m, 0), WallStamp(m, 1), options_.frame_id, topics,
                        renderer_ ? &*renderer_ : nullptr, writer);
  if (!e.empty()) {
    failed_ = true;
    return Status::Error(e);
  }
  ++windows_;
  return Status::Ok();
}

}  // namespace sfrt::pipeline
