// The side-by-side video source reuses the memory behind pair.left / pair.right (stereo_source.h):
// in steady state Next() decodes into the images the pair already holds, and allocates nothing
// beyond what cv::VideoCapture itself allocates per frame (FFmpeg's packets and frame pool, or
// OpenCV's MJPEG codec's image). Image allocations are counted by a cv::MatAllocator installed as
// OpenCV's default, heap allocations by the counting global allocator
// (tests/common/counting_allocator.h), so the file is its own executable and not built under the
// sanitizers.
#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>
#include <opencv2/videoio/registry.hpp>
#include <string>

#include "camera/sources/test_util.h"
#include "common/counting_allocator.h"
#include "sfrt/camera/stereo_source.h"

namespace sfrt::camera {
namespace {

using testing::TempDir;

constexpr int kEyeWidth = 64;
constexpr int kHeight = 48;
constexpr int kFrames = 12;

// Counts every cv::Mat data allocation made through the default allocator (cv::Mat::create on a
// Mat without its own allocator), and hands the work to OpenCV's standard allocator.
class CountingMatAllocator final : public cv::MatAllocator {
 public:
  cv::UMatData* allocate(int dims, const int* sizes, int type, void* data, size_t* step,
                         cv::AccessFlag flags, cv::UMatUsageFlags usage) const override {
    count_.fetch_add(1, std::memory_order_relaxed);
    return std_->allocate(dims, sizes, type, data, step, flags, usage);
  }
  bool allocate(cv::UMatData* data, cv::AccessFlag flags, cv::UMatUsageFlags usage) const override {
    return std_->allocate(data, flags, usage);
  }
  void deallocate(cv::UMatData* data) const override { std_->deallocate(data); }
  long count() const { return count_.load(); }

 private:
  cv::MatAllocator* std_ = cv::Mat::getStdAllocator();
  mutable std::atomic<long> count_{0};
};

CountingMatAllocator& Counting() {
  static CountingMatAllocator* allocator = [] {
    auto* a = new CountingMatAllocator();  // lives as long as any Mat it made
    cv::Mat::setDefaultAllocator(a);
    return a;
  }();
  return *allocator;
}

// Frame f: left half B = 200, G = 20 f, right half R = 200, G = 20 f (MJPEG keeps flat colours
// within a few levels), so every frame differs from the one before.
void WriteSbsVideo(const std::string& path) {
  cv::VideoWriter writer(path, cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'),
                         10.0, cv::Size(2 * kEyeWidth, kHeight));
  ASSERT_TRUE(writer.isOpened()) << path;
  for (int f = 0; f < kFrames; ++f) {
    cv::Mat frame(kHeight, 2 * kEyeWidth, CV_8UC3);
    frame(cv::Rect(0, 0, kEyeWidth, kHeight)).setTo(cv::Scalar(200, 20 * f, 30));
    frame(cv::Rect(kEyeWidth, 0, kEyeWidth, kHeight)).setTo(cv::Scalar(30, 20 * f, 200));
    writer.write(frame);
  }
}

double Green(const cv::Mat& image) { return cv::mean(image)[1]; }

// The source and a bare cv::VideoCapture on the same file with the backend the source chose.
struct SourceAndBareCapture {
  std::unique_ptr<StereoSource> source;
  cv::VideoCapture bare;
  std::string backend;
};

void OpenBoth(const std::string& path, SourceAndBareCapture* both) {
  Result<std::unique_ptr<StereoSource>> source = OpenSbsVideoSource(path);
  ASSERT_TRUE(source.ok()) << source.message();
  both->source = std::move(source).value();
  // The backend order of OpenSbsVideoSource; the first that opens is the source's.
  for (const cv::VideoCaptureAPIs api : {cv::CAP_FFMPEG, cv::CAP_OPENCV_MJPEG, cv::CAP_GSTREAMER}) {
    if (cv::videoio_registry::hasBackend(api) && both->bare.open(path, api)) break;
  }
  ASSERT_TRUE(both->bare.isOpened());
  both->backend = both->bare.getBackendName();
  ASSERT_NE(both->source->Describe().find("OpenCV backend " + both->backend + ")"),
            std::string::npos)
      << both->source->Describe() << " vs " << both->backend;
}

TEST(VideoAllocation, CountingMatAllocatorSeesAnImageAllocation) {
  const long before = Counting().count();
  cv::Mat image(kHeight, kEyeWidth, CV_8UC3);
  EXPECT_EQ(Counting().count() - before, 1);
}

// Copies of pair.left / pair.right taken before Next() keep the old buffers alive, so a source
// that released and reallocated the images could not get the same address back: equal data
// pointers mean Next() wrote into the very memory the pair held. The copies then show the new
// frame, which is why the header says to clone an image kept past the next call.
TEST(VideoAllocation, SteadyStateNextWritesIntoThePairsImageMemory) {
  TempDir tmp;
  const std::string path = tmp / "sbs.avi";
  WriteSbsVideo(path);
  Result<std::unique_ptr<StereoSource>> source = OpenSbsVideoSource(path);
  ASSERT_TRUE(source.ok()) << source.message();
  FramePair pair;
  Result<Fetched> got = (*source)->Next(&pair);
  ASSERT_TRUE(got.ok() && *got == Fetched::kPair) << got.message();
  ASSERT_EQ(pair.left.size(), cv::Size(kEyeWidth, kHeight));
  ASSERT_EQ(pair.right.size(), cv::Size(kEyeWidth, kHeight));
  for (int f = 1; f < kFrames; ++f) {
    const cv::Mat kept_left = pair.left;  // shares the buffer (a reference, not a clone)
    const cv::Mat kept_right = pair.right;
    got = (*source)->Next(&pair);
    ASSERT_TRUE(got.ok() && *got == Fetched::kPair) << "frame " << f << ": " << got.message();
    EXPECT_EQ(pair.left.data, kept_left.data) << "frame " << f << ": left image reallocated";
    EXPECT_EQ(pair.right.data, kept_right.data) << "frame " << f << ": right image reallocated";
    EXPECT_NEAR(Green(kept_left), 20 * f, 6) << "frame " << f << ": the kept left is the new frame";
    EXPECT_NEAR(Green(kept_right), 20 * f, 6) << "frame " << f;
  }
}

// Next() against a bare cv::VideoCapture on the same file and backend, frame by frame: the
// source allocates no image of its own once the pair holds images of the right size (the first
// call allocates left, right and the decoded frame). What the decoder allocates is its business:
// none per frame with FFmpeg, one cv::Mat per frame with OpenCV's built-in MJPEG backend.
TEST(VideoAllocation, SteadyStateNextAllocatesNoImageBeyondTheDecoders) {
  TempDir tmp;
  const std::string path = tmp / "sbs.avi";
  WriteSbsVideo(path);
  Counting();  // installed before any Mat of the source exists
  SourceAndBareCapture both;
  ASSERT_NO_FATAL_FAILURE(OpenBoth(path, &both));
  FramePair pair;
  cv::Mat bare_frame;
  for (int f = 0; f < kFrames; ++f) {
    long before = Counting().count();
    const Result<Fetched> got = both.source->Next(&pair);
    const long by_source = Counting().count() - before;
    ASSERT_TRUE(got.ok() && *got == Fetched::kPair) << "frame " << f << ": " << got.message();
    before = Counting().count();
    ASSERT_TRUE(both.bare.read(bare_frame)) << "frame " << f;
    const long by_decoder = Counting().count() - before;
    if (f == 0) {
      EXPECT_GE(by_source - by_decoder, 2) << "the first call allocates left and right";
    } else {
      EXPECT_EQ(by_source, by_decoder) << "frame " << f << " (backend " << both.backend << ")";
    }
  }
}

// The same comparison on the heap: after the first frame Next() adds no allocation to the
// decoder's (its frame names are written into the pair's strings, which keep their capacity).
TEST(VideoAllocation, SteadyStateNextMakesNoHeapAllocationBeyondTheDecoders) {
  ASSERT_TRUE(sfrt::testing::CountingHooksAreLive());
  TempDir tmp;
  const std::string path = tmp / "sbs.avi";
  WriteSbsVideo(path);
  SourceAndBareCapture both;
  ASSERT_NO_FATAL_FAILURE(OpenBoth(path, &both));
  FramePair pair;
  cv::Mat bare_frame;
  for (int f = 0; f < kFrames; ++f) {
    long before = sfrt::testing::AllocationCount();
    const Result<Fetched> got = both.source->Next(&pair);
    const long by_source = sfrt::testing::AllocationCount() - before;
    ASSERT_TRUE(got.ok() && *got == Fetched::kPair) << "frame " << f << ": " << got.message();
    before = sfrt::testing::AllocationCount();
    ASSERT_TRUE(both.bare.read(bare_frame)) << "frame " << f;
    const long by_decoder = sfrt::testing::AllocationCount() - before;
    if (f > 0) {
      EXPECT_EQ(by_source, by_decoder) << "frame " << f << " (backend " << both.backend << ")";
    }
  }
}

}  // namespace
}  // namespace sfrt::camera
