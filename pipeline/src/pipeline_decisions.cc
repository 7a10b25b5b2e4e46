// The pipeline's decisions that need no running pipeline (pipeline.h): the preprocessing a
// model's metadata asks for, the input size, the video path, the output files' stems, and how a
// window's end-to-end latency splits into parts.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/pipeline.h"

namespace sfrt::pipeline {
namespace {

double Ms(int64_t ns) { return static_cast<double>(ns) / 1e6; }

using profiling::FormatFixed;

// "a,b,c".
std::string JoinSlots(const std::vector<std::string>& slots) {
  std::string text;
  for (const std::string& slot : slots) text += (text.empty() ? "" : ",") + slot;
  return text;
}

}  // namespace

Result<std::string> ResolveVideoPath(const std::string& path) {
  Result<io::OutputTarget> target = io::ResolveOutputTarget(path);
  if (!target.ok()) return Status::Error("--video: " + target.message());
  if (target->kind != io::OutputTarget::Kind::kReplace) {
    return Status::Error("--video '" + path + "' is " + target->what +
                         ": the MJPG/AVI writer seeks back to finish the file, so it writes "
                         "only a regular file; give a file path");
  }
  return target->path;
}

Result<camera::PreprocessParams> PreprocessFromMetadata(const InputDesc& input) {
  if (input.is_rgbd()) {
    return Status::Error("the model reads two RGB-D frames (" + JoinSlots(input.image_order) +
                         "), and the pipeline reads stereo pairs; run it on files with sfrt "
                         "infer --color0 --depth0 --color1 --depth1, or feed it through "
                         "camera::RgbdPreprocessor");
  }
  if (input.channels != 3 * static_cast<int>(input.image_order.size()) ||
      input.image_order.size() != 4) {
    return Status::Error("the model takes " + std::to_string(input.channels) +
                         " input channels and its image order lists " +
                         std::to_string(input.image_order.size()) +
                         " images; expected 12 channels from left0, right0, left1, right1");
  }
  camera::PreprocessParams p;
  for (size_t g = 0; g < 4; ++g) {
    auto slot = camera::ParseImageSlot(input.image_order[g]);
    if (!slot.ok()) {
      return Status::Error("the model's image order names an unknown image '" +
                           input.image_order[g] + "' (known: left0, right0, left1, right1)");
    }
    p.image_order[g] = *slot;
  }
  auto order = camera::ParseImageOrder(input.image_order);
  if (!order.ok()) return Status::Error("the model's image order: " + order.message());
  auto color = camera::ParseColorOrder(input.color_order);
  if (!color.ok()) {
    return Status::Error("the model's color order '" + input.color_order +
                         "' is neither BGR nor RGB");
  }
  p.color_order = *color;
  p.scale = input.scale;
  for (int c = 0; c < 3; ++c) {
    if (!(input.std[c] != 0) || !std::isfinite(input.std[c])) {
      return Status::Error("the model's std[" + std::to_string(c) + "] is " +
                           FormatFixed(input.std[c], 6) + "; cannot normalise");
    }
    p.mean[c] = input.mean[c];
    p.std[c] = input.std[c];
  }
  return p;
}

const char* LatencyPartName(LatencyPart part) {
  static constexpr const char* kNames[kLatencyParts] = {
      "capture_to_dequeue", "stereo_partner", "convert", "source_handoff", "queue_preprocess",
      "preprocess",         "queue_infer",    "infer",   "queue_output",   "output"};
  const int i = static_cast<int>(part);
  return i >= 0 && i < kLatencyParts ? kNames[i] : "?";
}

void SplitLatency(const FrameMeta& m, double out_ms[kLatencyParts]) {
  // Boundaries on one clock, from the capture of pair t+1 to the end of the output stage. A live
  // source's dequeue, pairing and conversion times (0 for files) fall back to the previous
  // boundary, so a part a source does not have is 0.
  int64_t b[kLatencyParts + 1];
  b[0] = m.capture_ns[1];
  b[1] = m.dequeue_ns > 0 ? m.dequeue_ns : b[0];
  b[2] = m.paired_ns > 0 ? m.paired_ns : b[1];
  b[3] = m.converted_ns > 0 ? m.converted_ns : b[2];
  b[4] = m.end_ns(config::Stage::kSource);
  for (int st = 1; st < config::kStageCount; ++st) {
    b[2 * st + 3] = m.stage_ns[st][0];
    b[2 * st + 4] = m.stage_ns[st][1];
  }
  for (int p = 0; p < kLatencyParts; ++p) out_ms[p] = Ms(b[p + 1] - b[p]);
}

Result<InputSizeChoice> ChooseInputSize(const PipelineOptions& options, const ModelMetadata& model,
                                        int source_height, int source_width) {
  const InputDesc& input = model.input;
  const std::string source = std::to_string(source_height) + "x" + std::to_string(source_width);
  InputSizeChoice c;
  const bool asked_for = options.height > 0 && options.width > 0;
  if (asked_for) {
    c.height = options.height;
    c.width = options.width;
    c.reason = "as asked";
  } else if (input.traced_height > 0 && input.traced_width > 0 &&
             model.training == TrainingState::kTrained) {
    c.height = input.traced_height;
    c.width = input.traced_width;
    c.reason =
        "the size the trained model records (traced at; its training camera's focal length is "
        "for this size); the frames are " +
        source + ", --size sets another";
  } else {
    c.height = source_height;
    c.width = source_width;
    c.reason = model.training != TrainingState::kTrained
                   ? "the frames' size (the model is not marked trained: no training size to match)"
                   : "the frames' size (the model records none)";
    return c;
  }
  // Aspect ratios as width / height; a size that swaps the source's is most likely WxH for HxW.
  const double frames = static_cast<double>(source_width) / source_height;
  const double asked = static_cast<double>(c.width) / c.height;
  auto off = [](double a, double b) { return std::fabs(a / b - 1.0); };
  if (off(asked, frames) <= kAspectTolerance) return c;
  const std::string size = std::to_string(c.height) + "x" + std::to_string(c.width);
  if (asked_for && off(1.0 / asked, frames) <= kAspectTolerance && !options.allow_aspect_change) {
    return Status::Error("--size " + size + " squeezes the " + source +
                         " (HxW) frames to the inverse aspect; did you mean " +
                         std::to_string(c.width) + "x" + std::to_string(c.height) +
                         " (HxW)? (--allow-aspect-change if it is meant)");
  }
  c.aspect_note = "the input size " + size + " has another aspect than the " + source +
                  " (HxW) frames: the images are stretched " +
                  FormatFixed(100 * off(asked, frames), 0) + "% to fit";
  return c;
}

std::string OutputStem(const FrameMeta& meta) {
  char num[32];
  std::snprintf(num, sizeof(num), "%06lld", static_cast<long long>(meta.frame0));
  if (meta.sequence.empty()) return std::string("frame_") + num;
  std::string seq = meta.sequence;
  for (char& c : seq) {
    if (c == '/' || c == '\\' || c == ' ') c = '_';
  }
  return seq + "_" + num;
}

}  // namespace sfrt::pipeline
