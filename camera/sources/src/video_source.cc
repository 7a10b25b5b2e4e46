// Side-by-side stereo video files through cv::VideoCapture.
#include <cstdio>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <opencv2/videoio/registry.hpp>
#include <system_error>

#include "sfrt/camera/stereo_source.h"

namespace sfrt::camera {
namespace {

class SbsVideoSource final : public StereoSource {
 public:
  SbsVideoSource(std::string path, cv::VideoCapture capture, int64_t announced,
                 VideoOptions options)
      : path_(std::move(path)),
        capture_(std::move(capture)),
        announced_(announced),
        options_(std::move(options)) {
    try {
      backend_ = capture_.getBackendName();
    } catch (const cv::Exception&) {
      backend_ = "unknown";
    }
  }

  Result<Fetched> Next(FramePair* pair) override {
    if (!stopped_.ok()) return stopped_;
    if (ended_) return Fetched::kEnd;
    const int64_t frame = next_frame_;
    ++images_decoded_;
    if (!capture_.read(frame_) || frame_.empty()) {
      ended_ = true;
      if (announced_ > 0 && frame < announced_) {
        BadFrame bad{path_ + "#" + std::to_string(frame),
                     "could not be decoded; the container announced " + std::to_string(announced_) +
                         " frames, so the stream ended early",
                     frame};
        if (options_.on_bad_frame == BadFramePolicy::kStop) {
          stopped_ = Status::Error("bad frame " + bad.path + ": " + bad.reason);
          return stopped_;
        }
        skipped_.push_back(bad);
        if (options_.on_bad_frame_callback) options_.on_bad_frame_callback(bad);
      }
      return Fetched::kEnd;
    }
    ++next_frame_;
    // After read(), the position is the presentation time of the frame just decoded.
    const double position_ms = capture_.get(cv::CAP_PROP_POS_MSEC);
    if (frame_.cols % 2 != 0) {
      stopped_ = Status::Error(path_ + ": frame width " + std::to_string(frame_.cols) +
                               " is odd, so it cannot hold two side-by-side views");
      return stopped_;
    }
    const int eye = frame_.cols / 2;
    const cv::Rect first(0, 0, eye, frame_.rows);
    const cv::Rect second(eye, 0, eye, frame_.rows);
    const cv::Mat left_view = frame_(options_.left_first ? first : second);
    const cv::Mat right_view = frame_(options_.left_first ? second : first);
    if (frame_.type() == CV_8UC3) {
      left_view.copyTo(pair->left);  // no allocation once pair holds images of this size
      right_view.copyTo(pair->right);
    } else if (frame_.type() == CV_8UC1) {
      cv::cvtColor(left_view, pair->left, cv::COLOR_GRAY2BGR);
      cv::cvtColor(right_view, pair->right, cv::COLOR_GRAY2BGR);
    } else {
      stopped_ = Status::Error(path_ + ": frame " + std::to_string(frame) +
                               " decoded to an unsupported pixel type " +
                               std::to_string(frame_.type()) + " (expected 8-bit BGR or grey)");
      return stopped_;
    }
    pair->index = frame;
    pair->sequence.clear();
    pair->frame_number = frame;
    if (position_ms >= 0) {
      pair->timestamp_s = position_ms / 1000.0;
    } else {
      pair->timestamp_s.reset();
    }
    // Into the pair's own strings: once they have grown, no allocation per frame.
    char number[24];
    std::snprintf(number, sizeof(number), "#%lld", static_cast<long long>(frame));
    for (std::string* name : {&pair->left_path, &pair->right_path}) {
      const bool left_half = (name == &pair->left_path) == options_.left_first;
      name->assign(path_).append(number).append(left_half ? " (left half)" : " (right half)");
    }
    return Fetched::kPair;
  }

  std::string Describe() const override {
    return "side-by-side video " + path_ + " (" +
           (announced_ > 0 ? std::to_string(announced_) : std::string("unknown number of")) +
           " frames, " + (options_.left_first ? "left view first" : "right view first") +
           ", OpenCV backend " + backend_ + ")";
  }
  std::optional<int64_t> size() const override {
    if (announced_ > 0) return announced_;
    return std::nullopt;
  }

 private:
  std::string path_;
  cv::VideoCapture capture_;
  int64_t announced_;
  VideoOptions options_;
  std::string backend_;
  cv::Mat frame_;  // decoder output, reused
  int64_t next_frame_ = 0;
  bool ended_ = false;
  Status stopped_;
};

}  // namespace

Result<std::unique_ptr<StereoSource>> OpenSbsVideoSource(const std::string& path,
                                                         const VideoOptions& options) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Status::Error("video file '" + path + "' does not exist or is not a regular file");
  }
  // File backends only, in this order (CAP_ANY would also try CAP_IMAGES, which treats the name
  // as an image-sequence pattern and logs errors for every ordinary file).
  cv::VideoCapture capture;
  std::string tried;
  for (const cv::VideoCaptureAPIs api : {cv::CAP_FFMPEG, cv::CAP_OPENCV_MJPEG, cv::CAP_GSTREAMER}) {
    if (!cv::videoio_registry::hasBackend(api)) continue;
    tried += (tried.empty() ? "" : ", ") + cv::videoio_registry::getBackendName(api);
    try {
      if (capture.open(path, api)) break;
    } catch (const cv::Exception&) {
      capture.release();
    }
  }
  if (!capture.isOpened()) {
    return Status::Error("video file '" + path +
                         "' could not be opened by OpenCV VideoCapture (tried backends: " + tried +
                         "; unknown container or codec in this OpenCV build)");
  }
  const double count = capture.get(cv::CAP_PROP_FRAME_COUNT);
  const int64_t announced = count > 0 && count < 1e12 ? static_cast<int64_t>(count) : 0;
  std::unique_ptr<StereoSource> source =
      std::make_unique<SbsVideoSource>(path, std::move(capture), announced, options);
  return source;
}

Result<std::unique_ptr<StereoSource>> OpenSbsVideoSource(const std::string& path) {
  return OpenSbsVideoSource(path, VideoOptions());
}

}  // namespace sfrt::camera
