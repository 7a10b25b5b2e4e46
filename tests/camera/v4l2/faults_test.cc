// Every fault knob of the fake device, and the behaviour capture.h promises for it.
#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <atomic>
#include <map>
#include <string>
#include <vector>

#include "camera/v4l2/capture_test_util.h"

namespace sfrt::v4l2::testing {
namespace {

using camera::ErrorKind;
using camera::Status;

bool Contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

class Faults : public ::testing::Test {
 protected:
  void SetUp() override { dev_ = &sys_.AddDevice({}); }
  CaptureDevice& Cam(uint32_t fourcc = V4L2_PIX_FMT_GREY) {
    cam_ = std::make_unique<CaptureDevice>(MakeConfig("/dev/video0", fourcc, 64, 32), sys_);
    return *cam_;
  }
  // After a Read, every buffer belongs to the driver (queued or done): none leaked.
  void ExpectAllBuffersWithDriver() {
    EXPECT_EQ(dev_->buffers_queued() + dev_->buffers_done(), dev_->buffer_count());
  }
  FakeV4l2System sys_;
  FakeDevice* dev_ = nullptr;
  std::unique_ptr<CaptureDevice> cam_;
};

TEST_F(Faults, ErrorFlagFrameIsSkippedRequeuedAndCounted) {
  CaptureDevice& cam = Cam();
  ASSERT_TRUE(cam.Open().ok());
  dev_->faults().error_flag_next = 1;
  Frame f;
  ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(f.sequence, 1u) << "frame 0 carried V4L2_BUF_FLAG_ERROR";
  EXPECT_EQ(cam.stats().error_flag_frames, 1u);
  EXPECT_EQ(cam.stats().sequence_drops, 0u);
  ExpectAllBuffersWithDriver();
}

TEST_F(Faults, DroppedFramesAreCountedFromSequenceGaps) {
  CaptureDevice& cam = Cam();
  ASSERT_TRUE(cam.Open().ok());
  Frame f;
  ASSERT_TRUE(cam.Read(&f).ok());
  dev_->faults().drop_next = 3;
  ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(f.sequence, 4u);
  EXPECT_EQ(MaxDiffToGreyPattern(f, 4, 0), 0);
  EXPECT_EQ(cam.stats().sequence_drops, 3u);
  dev_->faults().drop_every = 2;  // every second slot from now on
  for (int i = 0; i < 10; ++i) ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(cam.stats().sequence_drops, dev_->stats().frames_dropped_by_knob);
  EXPECT_GE(cam.stats().sequence_drops, 12u);
}

TEST_F(Faults, EioLosesABufferAndCaptureRequeuesIt) {
  CaptureDevice& cam = Cam();
  ASSERT_TRUE(cam.Open().ok());
  dev_->faults().eio_next_dqbuf = 1;
  Frame f;
  ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(cam.stats().eio, 1u);
  EXPECT_EQ(cam.stats().eio_requeued, 1u);
  ExpectAllBuffersWithDriver();
  // Without the requeue the fake would run out of buffers within a few frames.
  for (int i = 0; i < 20; ++i) ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(dev_->stats().frames_dropped_no_buffer, 0u);
}

TEST_F(Faults, CancelFlagEndsTheReopenBackOffWithinASliceWithoutAnAttempt) {
  CaptureConfig config = MakeConfig("/dev/video0", V4L2_PIX_FMT_GREY, 64, 32);
  config.reopen_backoff_initial_ms = 2000;
  CaptureDevice cam(config, sys_);
  std::atomic<bool> stop{false};
  cam.set_cancel_flag(&stop);
  ASSERT_TRUE(cam.Open().ok());
  Frame f;
  ASSERT_TRUE(cam.Read(&f).ok());
  dev_->Unplug();
  ASSERT_EQ(cam.Read(&f).kind(), ErrorKind::kDisconnected);

  // A stop request 300 ms into the 2 s back-off, as a SIGTERM would set the pipeline's flag.
  const int64_t t0 = sys_.MonotonicNowNs();
  sys_.set_after_sleep([&](int64_t now) {
    if (now - t0 >= 300'000'000) stop.store(true);
  });
  Status s = cam.Read(&f);
  EXPECT_EQ(s.kind(), ErrorKind::kCancelled) << s.message();
  EXPECT_TRUE(Contains(s.message(), "/dev/video0")) << s.message();
  const int64_t slept = sys_.MonotonicNowNs() - t0;
  EXPECT_GE(slept, 300'000'000);
  EXPECT_LE(slept, 320'000'000) << "the back-off is slept in slices of at most 20 ms";
  EXPECT_EQ(cam.stats().reopen_attempts, 0u) << "no reopen once a stop was requested";
  EXPECT_TRUE(cam.disconnected());

  // Without the flag the back-off is slept whole and the reopen goes ahead.
  sys_.set_after_sleep(nullptr);
  stop.store(false);
  dev_->Replug();
  const int64_t t1 = sys_.MonotonicNowNs();
  ASSERT_TRUE(cam.Read(&f).ok()) << cam.stats().last_error;
  EXPECT_GE(sys_.MonotonicNowNs() - t1, 2'000'000'000);
  EXPECT_EQ(cam.stats().reopens, 1u);
}

TEST_F(Faults, UnplugIsReportedThenReopenedWithBackoff) {
  CaptureDevice& cam = Cam();
  ASSERT_TRUE(cam.Open().ok());
  Frame f;
  ASSERT_TRUE(cam.Read(&f).ok());
  dev_->Unplug();

  Status s = cam.Read(&f);  // poll sees POLLERR|POLLHUP, QUERYCAP confirms ENODEV
  EXPECT_EQ(s.kind(), ErrorKind::kDisconnected);
  EXPECT_TRUE(Contains(s.message(), "ENODEV")) << s.message();
  EXPECT_TRUE(cam.disconnected());
  EXPECT_EQ(cam.stats().disconnects, 1u);
  EXPECT_EQ(sys_.open_fds(), 0) << "the dead fd is closed";
  EXPECT_EQ(sys_.live_mappings(), 0) << "the buffers are unmapped";

  // Still unplugged: each attempt sleeps the back-off (100 ms, then 200 ms) and fails.
  int64_t t = sys_.MonotonicNowNs();
  s = cam.Read(&f);
  EXPECT_EQ(s.kind(), ErrorKind::kDisconnected);
  EXPECT_TRUE(Contains(s.message(), "reopen attempt 1 failed")) << s.message();
  EXPECT_EQ(sys_.MonotonicNowNs() - t, 100'000'000);
  t = sys_.MonotonicNowNs();
  EXPECT_EQ(cam.Read(&f).kind(), ErrorKind::kDisconnected);
  EXPECT_EQ(sys_.MonotonicNowNs() - t, 200'000'000);
  EXPECT_EQ(cam.stats().reopen_attempts, 2u);

  dev_->Replug();
  ASSERT_TRUE(cam.Read(&f).ok()) << cam.stats().last_error;
  EXPECT_FALSE(cam.disconnected());
  EXPECT_EQ(cam.stats().reopens, 1u);
  EXPECT_EQ(f.sequence, 0u) << "a new stream";
  EXPECT_EQ(sys_.open_fds(), 1);
}

TEST_F(Faults, UnplugSeenByDqbufIsADisconnect) {
  CaptureDevice& cam = Cam();
  ASSERT_TRUE(cam.Open().ok());
  dev_->Unplug();
  RawFrame raw;
  bool got = true;
  Status s = cam.DrainNewest(&raw, &got);
  EXPECT_EQ(s.kind(), ErrorKind::kDisconnected);
  EXPECT_TRUE(Contains(s.message(), "VIDIOC_DQBUF: ENODEV")) << s.message();
  EXPECT_FALSE(got);
  EXPECT_EQ(sys_.live_mappings(), 0);
}

TEST_F(Faults, StallFiresTheWatchdogThenRestartsTheStream) {
  CaptureDevice& cam = Cam();
  ASSERT_TRUE(cam.Open().ok());
  dev_->faults().stalled = true;
  Frame f;
  for (int i = 1; i <= 3; ++i) {
    const int64_t t = sys_.MonotonicNowNs();
    Status s = cam.Read(&f);
    EXPECT_EQ(s.kind(), ErrorKind::kTimeout);
    EXPECT_EQ(sys_.MonotonicNowNs() - t, 500'000'000) << "the watchdog is watchdog_ms";
    if (i == 3) {
      EXPECT_TRUE(Contains(s.message(), "stream restarted")) << s.message();
    }
  }
  EXPECT_EQ(cam.stats().watchdog_timeouts, 3u);
  EXPECT_EQ(cam.stats().stream_restarts, 1u);
  EXPECT_EQ(dev_->stats().streamons, 2u);
  dev_->faults().stalled = false;
  ASSERT_TRUE(cam.Read(&f).ok());
}

TEST_F(Faults, EnospcAtStreamonExplainsUsbBandwidth) {
  dev_->faults().nospc_on_streamon = true;
  CaptureDevice& cam = Cam(V4L2_PIX_FMT_YUYV);
  Status s = cam.Open();
  EXPECT_EQ(s.kind(), ErrorKind::kNoBandwidth);
  EXPECT_TRUE(Contains(s.message(), "VIDIOC_STREAMON: ENOSPC")) << s.message();
  EXPECT_TRUE(Contains(s.message(), "USB")) << s.message();
  EXPECT_TRUE(Contains(s.message(), "use MJPEG")) << s.message();
  EXPECT_EQ(sys_.open_fds(), 0);
  EXPECT_EQ(sys_.live_mappings(), 0);
  EXPECT_EQ(dev_->buffer_count(), 0u) << "REQBUFS(0) freed the buffers";
}

TEST_F(Faults, EbusyAtOpenAndAtSFmtMeanDeviceInUse) {
  dev_->faults().busy_on_open = true;
  Status s = Cam().Open();
  EXPECT_EQ(s.kind(), ErrorKind::kBusy);
  EXPECT_TRUE(Contains(s.message(), "in use")) << s.message();
  dev_->faults().busy_on_open = false;
  dev_->faults().busy_on_s_fmt = true;
  s = Cam().Open();
  EXPECT_EQ(s.kind(), ErrorKind::kBusy);
  EXPECT_TRUE(Contains(s.message(), "VIDIOC_S_FMT: EBUSY")) << s.message();
  EXPECT_EQ(sys_.open_fds(), 0);
}

TEST_F(Faults, SecondOpenerOfAStreamingDeviceGetsBusy) {
  CaptureDevice& first = Cam();
  ASSERT_TRUE(first.Open().ok());
  CaptureDevice second(MakeConfig("/dev/video0", V4L2_PIX_FMT_GREY, 64, 32), sys_);
  EXPECT_EQ(second.Open().kind(), ErrorKind::kBusy);
  EXPECT_EQ(sys_.open_fds(), 1);
  Frame f;
  EXPECT_TRUE(first.Read(&f).ok()) << "the first opener is unaffected";
}

TEST_F(Faults, ShortRawFrameIsSkippedAndCounted) {
  CaptureDevice& cam = Cam(V4L2_PIX_FMT_YUYV);
  ASSERT_TRUE(cam.Open().ok());
  dev_->faults().short_next = 1;
  Frame f;
  ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(f.sequence, 1u);
  EXPECT_EQ(cam.stats().short_frames, 1u);
  ExpectAllBuffersWithDriver();
}

TEST_F(Faults, ShortMjpegIsAFrameErrorThenCaptureGoesOn) {
  CaptureDevice& cam = Cam(V4L2_PIX_FMT_MJPEG);
  ASSERT_TRUE(cam.Open().ok());
  dev_->faults().short_next = 1;
  Frame f;
  Status s = cam.Read(&f);
  EXPECT_EQ(s.kind(), ErrorKind::kFrameError);
  EXPECT_TRUE(Contains(s.message(), "MJPEG frame 0")) << s.message();
  EXPECT_EQ(cam.stats().decode_errors, 1u);
  ExpectAllBuffersWithDriver();
  ASSERT_TRUE(cam.Read(&f).ok()) << cam.stats().last_error;
  EXPECT_EQ(f.sequence, 1u);
  EXPECT_LE(MaxDiffToPattern(f, 1, 0), 2);
}

TEST_F(Faults, CorruptMjpegIsAFrameErrorThenCaptureGoesOn) {
  CaptureDevice& cam = Cam(V4L2_PIX_FMT_MJPEG);
  ASSERT_TRUE(cam.Open().ok());
  dev_->faults().corrupt_jpeg_next = 2;
  Frame f;
  EXPECT_EQ(cam.Read(&f).kind(), ErrorKind::kFrameError);
  EXPECT_EQ(cam.Read(&f).kind(), ErrorKind::kFrameError);
  ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(f.sequence, 2u);
  EXPECT_EQ(cam.stats().decode_errors, 2u);
  EXPECT_EQ(cam.stats().frames_delivered, 1u);
}

TEST_F(Faults, RepeatedUnplugCyclesLeakNothing) {
  CaptureDevice& cam = Cam(V4L2_PIX_FMT_MJPEG);
  ASSERT_TRUE(cam.Open().ok());
  Frame f;
  for (int cycle = 0; cycle < 5; ++cycle) {
    ASSERT_TRUE(cam.Read(&f).ok());
    dev_->Unplug();
    EXPECT_EQ(cam.Read(&f).kind(), ErrorKind::kDisconnected);
    dev_->Replug();
    ASSERT_TRUE(cam.Read(&f).ok()) << cam.stats().last_error;
    EXPECT_EQ(sys_.open_fds(), 1);
    EXPECT_EQ(sys_.live_mappings(), 4);
  }
  EXPECT_EQ(cam.stats().disconnects, 5u);
  EXPECT_EQ(cam.stats().reopens, 5u);
  cam.Close();
  EXPECT_EQ(sys_.open_fds(), 0);
  EXPECT_EQ(sys_.live_mappings(), 0);
}

TEST_F(Faults, UnplugAfterDqbufsKnobUnplugsAfterTheNthFrameThenReplugsOnTime) {
  CaptureDevice& cam = Cam();
  ASSERT_TRUE(cam.Open().ok());
  dev_->faults().unplug_after_dqbufs = 3;
  dev_->faults().replug_after_ns = 250'000'000;
  Frame f;
  ASSERT_TRUE(cam.Read(&f).ok());
  ASSERT_TRUE(cam.Read(&f).ok());
  EXPECT_EQ(f.sequence, 1u);
  // The third DQBUF hands out a frame and unplugs the device: requeueing it fails with ENODEV.
  Status s = cam.Read(&f);
  EXPECT_EQ(s.kind(), ErrorKind::kDisconnected);
  EXPECT_TRUE(Contains(s.message(), "ENODEV")) << s.message();
  EXPECT_EQ(dev_->stats().frames_dequeued, 3u);
  EXPECT_EQ(cam.stats().disconnects, 1u);
  EXPECT_EQ(sys_.open_fds(), 0);
  EXPECT_EQ(sys_.live_mappings(), 0);
  // Back-off 100 ms: still away (250 ms not passed); then 200 ms more: back, a new stream.
  s = cam.Read(&f);
  EXPECT_EQ(s.kind(), ErrorKind::kDisconnected);
  EXPECT_TRUE(Contains(s.message(), "reopen attempt 1 failed")) << s.message();
  ASSERT_TRUE(cam.Read(&f).ok()) << cam.stats().last_error;
  EXPECT_EQ(cam.stats().reopens, 1u);
  EXPECT_EQ(cam.stats().reopen_attempts, 2u);
  EXPECT_EQ(f.sequence, 0u) << "a new stream";
  // The knob fired once: the device stays plugged in.
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(cam.Read(&f).ok()) << cam.stats().last_error;
  EXPECT_EQ(cam.stats().disconnects, 1u);
}

TEST_F(Faults, UnplugAfterDqbufsWithoutReplugStaysAway) {
  CaptureDevice& cam = Cam();
  ASSERT_TRUE(cam.Open().ok());
  dev_->faults().unplug_after_dqbufs = 1;
  Frame f;
  EXPECT_EQ(cam.Read(&f).kind(), ErrorKind::kDisconnected);
  for (int i = 1; i <= 6; ++i) {
    Status s = cam.Read(&f);  // back-off 100, 200, 400, 800, 1600, 2000 ms
    EXPECT_EQ(s.kind(), ErrorKind::kDisconnected);
    EXPECT_TRUE(Contains(s.message(), "ENOENT")) << s.message();
  }
  EXPECT_EQ(cam.stats().reopens, 0u);
  EXPECT_EQ(cam.stats().reopen_attempts, 6u);
}

// capture.h: "Every ioctl is retried on EINTR." Every ioctl the device sees is interrupted once
// and only its immediate retry is served, so one call that gives up on EINTR fails Open(), loses a
// frame, or (in Close(), which ignores errors) breaks the pairing of the call log checked below.
TEST_F(Faults, EveryIoctlInterruptedByASignalIsRetried) {
  struct Session {
    Status open;
    std::vector<Frame> frames;
    std::vector<std::string> log;
    CaptureStats stats;
  };
  const auto run = [](FakeV4l2System& sys) {
    Session out;
    CaptureDevice cam(MakeConfig("/dev/video0", V4L2_PIX_FMT_YUYV, 64, 32), sys);
    out.open = cam.Open();
    if (!out.open.ok()) return out;
    for (int i = 0; i < 6; ++i) {
      Frame f;
      const Status s = cam.Read(&f);
      if (!s.ok()) {
        ADD_FAILURE() << "Read " << i << ": " << s.message();
        break;
      }
      out.frames.push_back(f);
    }
    cam.Close();
    out.log = sys.call_log();
    out.stats = cam.stats();
    return out;
  };
  // The same session on a device that is never interrupted (the same virtual clock start).
  FakeV4l2System plain_sys;
  plain_sys.AddDevice({});
  const Session plain = run(plain_sys);
  ASSERT_TRUE(plain.open.ok()) << plain.open.message();

  dev_->faults().eintr_every_ioctl = true;
  const Session interrupted = run(sys_);
  ASSERT_TRUE(interrupted.open.ok()) << interrupted.open.message();
  EXPECT_EQ(interrupted.stats.last_error, "");
  EXPECT_EQ(sys_.open_fds(), 0);
  EXPECT_EQ(sys_.live_mappings(), 0);
  EXPECT_EQ(dev_->buffer_count(), 0u) << "REQBUFS(0) was served";

  // The frames are those of the uninterrupted session, pixel for pixel and stamp for stamp.
  ASSERT_EQ(interrupted.frames.size(), plain.frames.size());
  for (size_t i = 0; i < plain.frames.size(); ++i) {
    const Frame& a = interrupted.frames[i];
    const Frame& b = plain.frames[i];
    EXPECT_EQ(a.sequence, b.sequence) << "frame " << i;
    EXPECT_EQ(a.timestamp_ns, b.timestamp_ns) << "frame " << i;
    EXPECT_EQ(a.dequeue_ns, b.dequeue_ns) << "frame " << i;
    EXPECT_EQ(a.width, b.width);
    EXPECT_EQ(a.height, b.height);
    EXPECT_TRUE(a.bgr == b.bgr) << "frame " << i << " pixels differ";
  }
  EXPECT_EQ(interrupted.stats.frames_dequeued, plain.stats.frames_dequeued);
  EXPECT_EQ(interrupted.stats.eagain, plain.stats.eagain);

  // Each ioctl of the plain session appears twice in a row (interrupted, then retried and served);
  // open, mmap, munmap, poll and close are untouched.
  std::vector<std::string> expected;
  for (const std::string& call : plain.log) {
    expected.push_back(call);
    const bool ioctl =
        call != "open" && call != "close" && call != "mmap" && call != "munmap" && call != "poll";
    if (ioctl) expected.push_back(call);
  }
  size_t first_difference = 0;
  while (first_difference < expected.size() && first_difference < interrupted.log.size() &&
         interrupted.log[first_difference] == expected[first_difference]) {
    ++first_difference;
  }
  const auto around = [first_difference](const std::vector<std::string>& log) {
    std::string text;
    const size_t from = first_difference < 4 ? 0 : first_difference - 4;
    for (size_t i = from; i < log.size() && i < first_difference + 4; ++i) {
      text += (i == first_difference ? " [" : " ") + log[i] + (i == first_difference ? "]" : "");
    }
    return text;
  };
  EXPECT_TRUE(interrupted.log == expected)
      << "call " << first_difference << " of " << expected.size() << ": expected..."
      << around(expected) << "; got..." << around(interrupted.log);

  // Every kind of ioctl the canonical sequence, Read() and Close() use was interrupted.
  const std::map<std::string, uint64_t>& hits = dev_->stats().ioctls_interrupted;
  for (const char* name : {"QUERYCAP", "ENUM_FMT", "S_FMT", "G_PARM", "S_PARM", "REQBUFS",
                           "QUERYBUF", "QBUF", "DQBUF", "STREAMON", "STREAMOFF"}) {
    const auto it = hits.find(name);
    EXPECT_TRUE(it != hits.end() && it->second >= 1) << name << " was never interrupted";
  }
  uint64_t total = 0;
  for (const auto& [name, count] : hits) total += count;
  EXPECT_EQ(total, (expected.size() - plain.log.size())) << "one EINTR per ioctl served";
}

}  // namespace
}  // namespace sfrt::v4l2::testing
