// CaptureDevice against the fake device: the canonical sequence, format negotiation, every pixel
// format end to end, and the newest-frame policy.
#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <algorithm>
#include <string>
#include <vector>

#include "camera/v4l2/capture_test_util.h"

namespace sfrt::v4l2::testing {
namespace {

using camera::ErrorKind;
using camera::Status;

// The call log with runs of the same call collapsed ("QBUF x4" -> "QBUF").
std::vector<std::string> Collapse(const std::vector<std::string>& log) {
  std::vector<std::string> out;
  for (const auto& s : log) {
    if (out.empty() || out.back() != s) out.push_back(s);
  }
  return out;
}

TEST(Capture, RunsTheCanonicalSequenceAndReleasesEverything) {
  FakeV4l2System sys;
  sys.AddDevice({});
  CaptureDevice cam(MakeConfig("/dev/video0", V4L2_PIX_FMT_YUYV, 640, 480), sys);
  ASSERT_TRUE(cam.Open().ok());
  EXPECT_EQ(sys.live_mappings(), 4);
  Frame f;
  ASSERT_TRUE(cam.Read(&f).ok());
  cam.Close();
  EXPECT_EQ(sys.open_fds(), 0);
  EXPECT_EQ(sys.live_mappings(), 0);

  const std::vector<std::string> log = sys.call_log();
  // QUERYBUF and mmap alternate per buffer, then four QBUFs.
  EXPECT_EQ(std::count(log.begin(), log.end(), "QUERYBUF"), 4);
  EXPECT_EQ(std::count(log.begin(), log.end(), "mmap"), 4);
  EXPECT_EQ(std::count(log.begin(), log.end(), "munmap"), 4);
  EXPECT_EQ(std::count(log.begin(), log.end(), "ENUM_FMT"), 7);  // 6 formats + the EINVAL end
  const std::vector<std::string> want = {
      "open",      "QUERYCAP", "ENUM_FMT", "S_FMT",    "G_PARM", "S_PARM",   "G_PARM",
      "REQBUFS",   "QUERYBUF", "mmap",     "QUERYBUF", "mmap",   "QUERYBUF", "mmap",
      "QUERYBUF",  "mmap",     "QBUF",     "STREAMON", "poll",   "DQBUF",    "QBUF",
      "STREAMOFF", "munmap",   "REQBUFS",  "close"};
  std::vector<std::string> got = Collapse(log);
  // Between STREAMON and STREAMOFF: poll, then DQBUF until EAGAIN, and the requeue.
  EXPECT_EQ(got, want);
}

TEST(Capture, ReportsWhatTheDriverAdjusted) {
  FakeV4l2System sys;
  FakeDeviceConfig dev;
  dev.max_width = 800;
  dev.max_height = 600;
  dev.max_fps = 30;
  dev.max_buffers = 6;
  sys.AddDevice(dev);
  CaptureConfig c = MakeConfig("/dev/video0", V4L2_PIX_FMT_YUYV, 1001, 701);
  c.fps = 45;
  c.buffer_count = 20;
  CaptureDevice cam(c, sys);
  ASSERT_TRUE(cam.Open().ok());
  const NegotiatedFormat& f = cam.format();
  EXPECT_EQ(f.width, 800);
  EXPECT_EQ(f.height, 600);
  EXPECT_EQ(f.bytesperline, 1600);
  EXPECT_DOUBLE_EQ(f.fps, 30.0);
  EXPECT_EQ(f.buffer_count, 6);
  EXPECT_EQ(f.adjustments, "size 1001x701 -> 800x600; fps 45 -> 30; buffers 20 -> 6");
  EXPECT_EQ(f.driver, "sfrt_fake");
  Frame frame;
  ASSERT_TRUE(cam.Read(&frame).ok());
  EXPECT_EQ(frame.width, 800);
  EXPECT_EQ(frame.bgr.size(), 800u * 600 * 3);
}

TEST(Capture, PicksTheFirstConvertibleFormatWhenNoneRequested) {
  FakeV4l2System sys;
  FakeDeviceConfig dev;
  dev.formats = {V4L2_PIX_FMT_YUV420, V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV};
  sys.AddDevice(dev);
  CaptureDevice cam(MakeConfig("/dev/video0", 0, 320, 240), sys);
  ASSERT_TRUE(cam.Open().ok());
  EXPECT_EQ(cam.format().fourcc, static_cast<uint32_t>(V4L2_PIX_FMT_MJPEG));
}

TEST(Capture, RejectsAFormatTheDeviceDoesNotOffer) {
  FakeV4l2System sys;
  FakeDeviceConfig dev;
  dev.formats = {V4L2_PIX_FMT_YUYV};
  sys.AddDevice(dev);
  CaptureDevice cam(MakeConfig("/dev/video0", V4L2_PIX_FMT_MJPEG, 320, 240), sys);
  Status s = cam.Open();
  EXPECT_EQ(s.kind(), ErrorKind::kUnsupported);
  EXPECT_NE(s.message().find("offers [YUYV]"), std::string::npos) << s.message();
  EXPECT_EQ(sys.open_fds(), 0);
  EXPECT_FALSE(cam.is_open());
}

TEST(Capture, MissingDeviceIsReportedByPath) {
  FakeV4l2System sys;
  CaptureDevice cam(MakeConfig("/dev/video7", V4L2_PIX_FMT_YUYV, 320, 240), sys);
  Status s = cam.Open();
  EXPECT_EQ(s.kind(), ErrorKind::kDisconnected);
  EXPECT_EQ(s.message().rfind("/dev/video7: open: ENOENT", 0), 0u) << s.message();
}

struct FormatCase {
  uint32_t fourcc;
  int tolerance;  // max |channel difference| to the pattern
  bool grey;
};

class CaptureFormat : public ::testing::TestWithParam<FormatCase> {};

// Width 100 makes every raw format's stride padded (64-byte alignment): YUYV 200 -> 256,
// GREY/NV12 100 -> 128, BGR24/RGB24 300 -> 320.
TEST_P(CaptureFormat, ConvertsTheFakePatternToBgr) {
  const FormatCase fc = GetParam();
  FakeV4l2System sys;
  sys.AddDevice({});
  CaptureDevice cam(MakeConfig("/dev/video0", fc.fourcc, 100, 40), sys);
  ASSERT_TRUE(cam.Open().ok());
  EXPECT_EQ(cam.format().fourcc, fc.fourcc);
  if (fc.fourcc != V4L2_PIX_FMT_MJPEG) {
    EXPECT_GT(cam.format().bytesperline, MinBytesPerLine(fc.fourcc, 100));
  }
  for (int i = 0; i < 3; ++i) {
    Frame f;
    ASSERT_TRUE(cam.Read(&f).ok()) << cam.stats().last_error;
    ASSERT_EQ(f.width, 100);
    ASSERT_EQ(f.height, 40);
    EXPECT_EQ(f.sequence, static_cast<uint32_t>(i));
    const int diff =
        fc.grey ? MaxDiffToGreyPattern(f, f.sequence, 0) : MaxDiffToPattern(f, f.sequence, 0);
    EXPECT_LE(diff, fc.tolerance) << FourccToString(fc.fourcc);
    // The pattern moves one block per frame: comparing with the wrong frame must fail.
    const int wrong = fc.grey ? MaxDiffToGreyPattern(f, f.sequence + 1, 0)
                              : MaxDiffToPattern(f, f.sequence + 1, 0);
    EXPECT_GT(wrong, 20);
  }
  EXPECT_EQ(cam.stats().frames_delivered, 3u);
}

// Tolerances: BGR24/RGB24/GREY exact; YUYV/NV12 round trip through 8-bit BT.601 limited range
// (quantisation of Y to 219 and chroma to 224 levels, then fixed-point decode): 2, measured 2;
// MJPEG at quality 95, 4:4:4, flat 8x8 blocks (DC quantisation only): 2, measured 1.
INSTANTIATE_TEST_SUITE_P(AllFormats, CaptureFormat,
                         ::testing::Values(FormatCase{V4L2_PIX_FMT_BGR24, 0, false},
                                           FormatCase{V4L2_PIX_FMT_RGB24, 0, false},
                                           FormatCase{V4L2_PIX_FMT_GREY, 0, true},
                                           FormatCase{V4L2_PIX_FMT_YUYV, 2, false},
                                           FormatCase{V4L2_PIX_FMT_NV12, 2, false},
                                           FormatCase{V4L2_PIX_FMT_MJPEG, 2, false}),
                         [](const auto& p) { return FourccToString(p.param.fourcc); });

TEST(Capture, DeliversTheNewestFrameAndRequeuesTheOlderOnes) {
  FakeV4l2System sys;
  FakeDevice& dev = sys.AddDevice({});
  CaptureDevice cam(MakeConfig("/dev/video0", V4L2_PIX_FMT_BGR24, 64, 32), sys);
  ASSERT_TRUE(cam.Open().ok());
  // The consumer was busy for 3.5 frame periods: frames 0, 1, 2 wait in the queue.
  sys.AdvanceClock(kPeriod30 * 7 / 2);
  Frame f;
  ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(f.sequence, 2u);
  EXPECT_EQ(MaxDiffToPattern(f, 2, 0), 0);
  EXPECT_EQ(cam.stats().stale_dropped, 2u);
  EXPECT_EQ(dev.buffers_queued(), 4u) << "every buffer goes back to the driver";

  // A longer stall: the driver fills the 4 buffers (frames 3..6) and drops 7..12 for want of
  // a buffer, as a real driver does. The newest available is 6; the next is 13.
  sys.AdvanceClock(kPeriod30 * 10);
  ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(f.sequence, 6u);
  EXPECT_EQ(cam.stats().stale_dropped, 5u);
  ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(f.sequence, 13u);
  EXPECT_EQ(cam.stats().sequence_drops, 6u);
  EXPECT_EQ(dev.stats().frames_dropped_no_buffer, 6u);
}

TEST(Capture, TimestampsAreTheDriversMonotonicStamps) {
  FakeV4l2System sys;
  FakeDeviceConfig dc;
  dc.phase_ns = 1'000'000;
  sys.AddDevice(dc);
  CaptureDevice cam(MakeConfig("/dev/video0", V4L2_PIX_FMT_GREY, 64, 32), sys);
  const int64_t t0 = sys.MonotonicNowNs();
  ASSERT_TRUE(cam.Open().ok());
  RawFrame a, b;
  ASSERT_TRUE(cam.ReadRaw(&a).ok());
  ASSERT_TRUE(cam.ReadRaw(&b).ok());
  // Microsecond resolution (struct timeval).
  EXPECT_NEAR(static_cast<double>(a.timestamp_ns - t0), kPeriod30 + 1'000'000, 1000);
  EXPECT_NEAR(static_cast<double>(b.timestamp_ns - a.timestamp_ns), kPeriod30, 1000);
  EXPECT_EQ(cam.stats().timestamp_fallbacks, 0u);
}

TEST(Capture, UnknownTimestampFallsBackToDequeueTime) {
  FakeV4l2System sys;
  FakeDeviceConfig dc;
  dc.monotonic_timestamps = false;
  sys.AddDevice(dc);
  CaptureDevice cam(MakeConfig("/dev/video0", V4L2_PIX_FMT_GREY, 64, 32), sys);
  ASSERT_TRUE(cam.Open().ok());
  RawFrame a;
  ASSERT_TRUE(cam.ReadRaw(&a).ok());
  EXPECT_EQ(a.timestamp_ns, sys.MonotonicNowNs());
  EXPECT_EQ(cam.stats().timestamp_fallbacks, 1u);
}

TEST(Capture, NonZeroFirstSequenceIsNotADrop) {
  FakeV4l2System sys;
  FakeDeviceConfig dc;
  dc.first_sequence = 5000;
  sys.AddDevice(dc);
  CaptureDevice cam(MakeConfig("/dev/video0", V4L2_PIX_FMT_GREY, 64, 32), sys);
  ASSERT_TRUE(cam.Open().ok());
  RawFrame a;
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(cam.ReadRaw(&a).ok());
  EXPECT_EQ(a.sequence, 5002u);
  EXPECT_EQ(cam.stats().sequence_drops, 0u);
}

TEST(Capture, ReadBeforeOpenIsAnError) {
  FakeV4l2System sys;
  sys.AddDevice({});
  CaptureDevice cam(MakeConfig("/dev/video0", V4L2_PIX_FMT_GREY, 64, 32), sys);
  Frame f;
  EXPECT_EQ(cam.Read(&f).kind(), ErrorKind::kInvalidArgument);
  CaptureConfig bad = MakeConfig("/dev/video0", V4L2_PIX_FMT_GREY, 64, 32);
  bad.buffer_count = 1;
  CaptureDevice cam2(bad, sys);
  EXPECT_EQ(cam2.Open().kind(), ErrorKind::kInvalidArgument);
}

}  // namespace
}  // namespace sfrt::v4l2::testing
