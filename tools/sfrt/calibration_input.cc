#include "sfrt/calibration_input.h"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "sfrt/camera/preprocess.h"
#include "sfrt/camera/rectifier.h"
#include "sfrt/config/limits.h"
#include "sfrt/pipeline/io/npy.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/sources.h"

namespace sfrt::tools {

Result<exporter::CalibrationSet> ReadCalibrationNpy(const std::string& path, int channels,
                                                    int max_frames) {
  Result<io::NpyArray> array = io::ReadNpy(path);
  if (!array.ok()) return array.status();
  const std::vector<int64_t>& shape = array->shape;
  const std::string expected = " is not (H, W, " + std::to_string(channels) + ") or (N, H, W, " +
                               std::to_string(channels) + ")";
  if (shape.size() != 3 && shape.size() != 4) {
    return Status::Error(path + ": shape " + array->ShapeString() + expected);
  }
  const size_t first = shape.size() - 3;
  const int64_t frames = shape.size() == 4 ? shape[0] : 1;
  if (frames == 0) {
    return Status::Error(path + ": shape " + array->ShapeString() +
                         " holds no frames; the calibration set is empty");
  }
  for (size_t d = 0; d < shape.size(); ++d) {
    if (shape[d] <= 0 || shape[d] > std::numeric_limits<int>::max()) {
      return Status::Error(path + ": shape " + array->ShapeString() + expected);
    }
  }
  if (std::string problem =
          config::CheckSize(config::kInputSide, path + ": shape " + array->ShapeString(),
                            shape[first], shape[first + 1]);
      !problem.empty()) {
    return Status::Error(problem);
  }
  if (shape[first + 2] != channels) {
    return Status::Error(path + ": shape " + array->ShapeString() + " has " +
                         std::to_string(shape[first + 2]) + " channels but the model takes " +
                         std::to_string(channels));
  }
  exporter::CalibrationSet set;
  set.frames = static_cast<int>(std::min<int64_t>(frames, max_frames));
  set.height = static_cast<int>(shape[first]);
  set.width = static_cast<int>(shape[first + 1]);
  set.channels = channels;
  set.values = std::move(array->data);
  set.values.resize(static_cast<size_t>(set.frames) * static_cast<size_t>(set.height) *
                    static_cast<size_t>(set.width) * static_cast<size_t>(channels));
  return set;
}

Result<exporter::CalibrationSet> ReadCalibrationDirectory(const std::string& path,
                                                          const InputDesc& input, int height,
                                                          int width, int max_frames,
                                                          std::string* described) {
  Result<camera::PreprocessParams> params = pipeline::PreprocessFromMetadata(input);
  if (!params.ok()) return Status::Error("the model's input: " + params.message());
  auto pre = camera::Preprocessor::Create(*params, height, width);
  if (!pre.ok()) return pre.status();

  pipeline::ReplaySpec spec;
  spec.kind = pipeline::ReplaySpec::Kind::kDataset;
  spec.root = path;
  spec.on_bad_frame = camera::BadFramePolicy::kStop;
  Result<int64_t> windows = pipeline::ProbeReplay(spec);
  if (!windows.ok()) return Status::Error(path + ": " + windows.message());
  if (*windows <= 0) {
    return Status::Error(path + ": no (t, t+1) window of consecutive stereo pairs");
  }
  std::unique_ptr<pipeline::FrameSource> source = pipeline::MakeReplaySource(spec);
  Result<cv::Size> size = source->Open();
  if (!size.ok()) return Status::Error(path + ": " + size.message());

  exporter::CalibrationSet set;
  set.height = height;
  set.width = width;
  set.channels = camera::Preprocessor::kChannels;
  const size_t per_frame = pre->output_floats();
  const std::atomic<bool> stop{false};
  pipeline::WindowItem item;
  std::optional<camera::StereoRectifier> resize;
  cv::Size resize_from;
  cv::Mat l0, r0, l1, r1;
  std::string first_window;
  while (set.frames < max_frames) {
    Result<pipeline::Fetch> next = source->Next(&item, stop);
    if (!next.ok()) return Status::Error(path + ": " + next.message());
    if (*next == pipeline::Fetch::kEnd) break;
    const cv::Size from = item.left0.size();
    if (!resize || from != resize_from) {
      auto made = camera::StereoRectifier::CreateResizeOnly(from, cv::Size(width, height));
      if (!made.ok()) return Status::Error(path + ": " + made.message());
      resize.emplace(std::move(made).value());
      resize_from = from;
    }
    camera::Status s = resize->Apply(item.left0, item.right0, &l0, &r0);
    if (s.ok()) s = resize->Apply(item.left1, item.right1, &l1, &r1);
    if (!s.ok()) return Status::Error(item.meta.left0_path + ": " + s.message());
    set.values.resize(per_frame * static_cast<size_t>(set.frames + 1));
    s = pre->Run(l0, r0, l1, r1, set.values.data() + per_frame * static_cast<size_t>(set.frames),
                 per_frame);
    if (!s.ok()) return Status::Error(item.meta.left0_path + ": " + s.message());
    if (set.frames == 0) {
      first_window = item.meta.left0_path + " (" + std::to_string(from.height) + "x" +
                     std::to_string(from.width) + ")";
    }
    ++set.frames;
  }
  if (set.frames == 0) {
    return Status::Error(path + ": no (t, t+1) window of consecutive stereo pairs");
  }
  *described = std::to_string(set.frames) + " of " + std::to_string(*windows) + " windows of " +
               source->Describe() + ", from " + first_window + ", resized to " +
               std::to_string(height) + "x" + std::to_string(width);
  return set;
}

}  // namespace sfrt::tools
