// Runs the production seam (LibcSyscalls: ::open, ::ioctl, ::mmap, ::poll ...) on "/dev/video0"
// and "/dev/video1". Meant to run under the LD_PRELOAD shim (preload_shim.cc) with
//   SFRT_FAKE_V4L2='/dev/video0:side=0;/dev/video1:side=1,phase_ms=2,drop_every=4'
// Without the shim the devices do not exist on this machine and the tests fail (by design).
#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <cstdlib>

#include "camera/v4l2/test_pattern.h"
#include "sfrt/camera/v4l2/stereo.h"

namespace sfrt::v4l2 {
namespace {

using camera::Status;

int MaxGreyDiff(const Frame& f, int side) {
  int worst = 0;
  for (int y = 0; y < f.height; ++y) {
    for (int x = 0; x < f.width; ++x) {
      const int want = testing::PatternGrey(x, y, f.sequence, side);
      worst = std::max(worst, std::abs(f.bgr[(static_cast<size_t>(y) * f.width + x) * 3] - want));
    }
  }
  return worst;
}

CaptureConfig Config(const char* path) {
  CaptureConfig c;
  c.device = path;
  c.pixel_format = V4L2_PIX_FMT_GREY;
  c.width = 160;
  c.height = 120;
  c.fps = 30;
  c.watchdog_ms = 2000;
  return c;
}

TEST(PreloadShim, UnmodifiedCaptureCodeStreamsFromTheFakeDevice) {
  CaptureDevice cam(Config("/dev/video0"));  // the production seam
  Status s = cam.Open();
  ASSERT_TRUE(s.ok()) << s.message() << " (is LD_PRELOAD set to the shim?)";
  EXPECT_EQ(cam.format().driver, "sfrt_fake");
  Frame f;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(cam.Read(&f).ok()) << cam.stats().last_error;
    EXPECT_EQ(MaxGreyDiff(f, 0), 0);
  }
}

TEST(PreloadShim, StereoPairCountsTheRightCamerasDrops) {
  StereoConfig config;
  config.left = Config("/dev/video0");
  config.right = Config("/dev/video1");
  config.pair_tolerance_ns = 8'000'000;
  config.timeout_ms = 2000;
  StereoCapture cap(config);
  Status s = cap.Open();
  ASSERT_TRUE(s.ok()) << s.message();
  StereoPair p;
  for (int i = 0; i < 12; ++i) {
    ASSERT_TRUE(cap.Next(&p).ok());
    EXPECT_LE(std::llabs(p.skew_ns), config.pair_tolerance_ns);
    EXPECT_EQ(MaxGreyDiff(p.left, 0), 0);
    EXPECT_EQ(MaxGreyDiff(p.right, 1), 0);
  }
  // drop_every=4 on the right camera: over >= 12 frame periods at least 2 drops, each one
  // visible as a sequence gap and none on the left.
  EXPECT_GE(cap.right().stats().sequence_drops, 2u);
  EXPECT_EQ(cap.left().stats().sequence_drops, 0u);
}

}  // namespace
}  // namespace sfrt::v4l2
