// StereoCapture: timestamp pairing with tolerance and drop accounting, side-by-side split,
// newest-pair policy, and a camera unplugged mid-stream.
#include "sfrt/camera/v4l2/stereo.h"

#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <cstdlib>

#include "camera/v4l2/capture_test_util.h"

namespace sfrt::v4l2::testing {
namespace {

using camera::ErrorKind;
using camera::Status;

struct Rig {
  FakeV4l2System sys;
  FakeDevice* left = nullptr;
  FakeDevice* right = nullptr;
  StereoConfig config;

  Rig(int64_t left_phase, int64_t right_phase, int64_t jitter = 0) {
    FakeDeviceConfig l;
    l.path = "/dev/video0";
    l.side = 0;
    l.phase_ns = left_phase;
    l.jitter_ns = jitter;
    FakeDeviceConfig r = l;
    r.path = "/dev/video1";
    r.side = 1;
    r.phase_ns = right_phase;
    left = &sys.AddDevice(l);
    right = &sys.AddDevice(r);
    config.left = MakeConfig("/dev/video0", V4L2_PIX_FMT_GREY, 64, 32);
    config.right = MakeConfig("/dev/video1", V4L2_PIX_FMT_GREY, 64, 32);
    config.pair_tolerance_ns = 8'000'000;
    config.timeout_ms = 500;
  }
};

TEST(Stereo, PairsFramesWithinToleranceDespitePhaseOffset) {
  Rig rig(0, 5'000'000);
  StereoCapture cap(rig.config, rig.sys);
  ASSERT_TRUE(cap.Open().ok());
  StereoPair p;
  for (uint32_t i = 0; i < 10; ++i) {
    ASSERT_TRUE(cap.Next(&p).ok());
    EXPECT_EQ(p.left.sequence, i);
    EXPECT_EQ(p.right.sequence, i);
    EXPECT_NEAR(static_cast<double>(p.skew_ns), -5'000'000, 1000);
    EXPECT_EQ(MaxDiffToGreyPattern(p.left, i, 0), 0) << "left image is the left camera's";
    EXPECT_EQ(MaxDiffToGreyPattern(p.right, i, 1), 0) << "right image is the right camera's";
  }
  EXPECT_EQ(cap.stats().pairs, 10u);
  EXPECT_EQ(cap.stats().unpaired_left + cap.stats().unpaired_right, 0u);
  EXPECT_EQ(cap.left().stats().frames_delivered, 10u) << "each camera delivered a frame a pair";
  EXPECT_EQ(cap.right().stats().frames_delivered, 10u);
}

TEST(Stereo, JitteredCamerasStillPairWithinTolerance) {
  Rig rig(0, 1'000'000, 3'000'000);
  StereoCapture cap(rig.config, rig.sys);
  ASSERT_TRUE(cap.Open().ok());
  StereoPair p;
  for (int i = 0; i < 30; ++i) {
    ASSERT_TRUE(cap.Next(&p).ok());
    EXPECT_LE(std::llabs(p.skew_ns), rig.config.pair_tolerance_ns);
    EXPECT_EQ(p.left.sequence, p.right.sequence);
  }
}

TEST(Stereo, FramesOneCameraDroppedLeaveUnpairedPartnersCounted) {
  Rig rig(0, 2'000'000);
  StereoCapture cap(rig.config, rig.sys);
  ASSERT_TRUE(cap.Open().ok());
  StereoPair p;
  ASSERT_TRUE(cap.Next(&p).ok());
  rig.right->faults().drop_next = 2;  // the right driver drops frames 1 and 2
  ASSERT_TRUE(cap.Next(&p).ok());
  EXPECT_EQ(p.left.sequence, 3u);
  EXPECT_EQ(p.right.sequence, 3u);
  EXPECT_EQ(cap.stats().unpaired_left, 2u) << "left frames 1 and 2 had no partner";
  EXPECT_EQ(cap.right().stats().sequence_drops, 2u);
  EXPECT_EQ(cap.left().stats().sequence_drops, 0u);
  EXPECT_EQ(cap.stats().unpaired_right, 0u);
}

TEST(Stereo, CamerasNeverWithinToleranceTimeOut) {
  Rig rig(0, 16'000'000);  // half a period apart; tolerance 8 ms
  StereoCapture cap(rig.config, rig.sys);
  ASSERT_TRUE(cap.Open().ok());
  StereoPair p;
  Status s = cap.Next(&p);
  EXPECT_EQ(s.kind(), ErrorKind::kTimeout);
  EXPECT_NE(s.message().find("no pair within 8000 us"), std::string::npos) << s.message();
  EXPECT_GT(cap.stats().unpaired_left + cap.stats().unpaired_right, 10u);
  EXPECT_EQ(cap.stats().pairs, 0u);
}

TEST(Stereo, ReturnsTheNewestPairAfterTheConsumerFellBehind) {
  Rig rig(0, 3'000'000);
  StereoCapture cap(rig.config, rig.sys);
  ASSERT_TRUE(cap.Open().ok());
  rig.sys.AdvanceClock(kPeriod30 * 3 + 10'000'000);  // frames 0, 1, 2 ready on both
  StereoPair p;
  ASSERT_TRUE(cap.Next(&p).ok());
  EXPECT_EQ(p.left.sequence, 2u);
  EXPECT_EQ(p.right.sequence, 2u);
  EXPECT_EQ(cap.left().stats().stale_dropped, 2u);
  EXPECT_EQ(cap.right().stats().stale_dropped, 2u);
}

TEST(Stereo, SilentCameraChargesItsWatchdog) {
  Rig rig(0, 0);
  StereoCapture cap(rig.config, rig.sys);
  ASSERT_TRUE(cap.Open().ok());
  rig.right->faults().stalled = true;
  StereoPair p;
  Status s = cap.Next(&p);
  EXPECT_EQ(s.kind(), ErrorKind::kTimeout);
  EXPECT_NE(s.message().find("/dev/video1: no frame"), std::string::npos) << s.message();
  EXPECT_EQ(cap.right().stats().watchdog_timeouts, 1u);
  EXPECT_EQ(cap.left().stats().watchdog_timeouts, 0u);
}

TEST(Stereo, UnpluggedCameraIsReportedThenReconnected) {
  Rig rig(0, 1'000'000);
  StereoCapture cap(rig.config, rig.sys);
  ASSERT_TRUE(cap.Open().ok());
  StereoPair p;
  ASSERT_TRUE(cap.Next(&p).ok());
  rig.right->Unplug();
  EXPECT_EQ(cap.Next(&p).kind(), ErrorKind::kDisconnected);
  rig.right->Replug();
  ASSERT_TRUE(cap.Next(&p).ok());
  EXPECT_EQ(cap.right().stats().reopens, 1u);
  EXPECT_LE(std::llabs(p.skew_ns), rig.config.pair_tolerance_ns);
}

TEST(Stereo, SideBySideSplitsAndHonoursTheConfiguredOrder) {
  for (bool left_first : {true, false}) {
    FakeV4l2System sys;
    FakeDeviceConfig dc;
    dc.side_by_side = true;
    sys.AddDevice(dc);
    StereoConfig config;
    config.mode = StereoConfig::Mode::kSideBySide;
    config.left = MakeConfig("/dev/video0", V4L2_PIX_FMT_BGR24, 2 * 48, 32);
    config.sbs_left_first = left_first;
    StereoCapture cap(config, sys);
    ASSERT_TRUE(cap.Open().ok());
    StereoPair p;
    for (uint32_t i = 0; i < 3; ++i) {
      ASSERT_TRUE(cap.Next(&p).ok());
      ASSERT_EQ(p.left.width, 48);
      ASSERT_EQ(p.right.width, 48);
      EXPECT_EQ(p.left.sequence, i);
      EXPECT_EQ(p.left.timestamp_ns, p.right.timestamp_ns);
      EXPECT_EQ(MaxDiffToPattern(p.left, i, left_first ? 0 : 1), 0);
      EXPECT_EQ(MaxDiffToPattern(p.right, i, left_first ? 1 : 0), 0);
    }
    EXPECT_EQ(cap.stats().pairs, 3u);
  }
}

}  // namespace
}  // namespace sfrt::v4l2::testing
