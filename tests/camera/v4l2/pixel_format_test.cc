// Pixel format converters against real-valued references and hand-made buffers.
#include "sfrt/camera/v4l2/pixel_format.h"

#include <gtest/gtest.h>
#include <linux/videodev2.h>
#include <turbojpeg.h>

#include <cmath>
#include <vector>

#include "camera/v4l2/test_pattern.h"

namespace sfrt::v4l2 {
namespace {

using camera::ErrorKind;
using camera::Status;

using testing::PatternBgr;
using testing::YuvToBgr601Reference;

TEST(PixelFormat, YuvPixelWithinOneOfRealValuedBt601) {
  int worst = 0;
  for (int y = 0; y < 256; ++y) {
    for (int cb = 0; cb < 256; cb += 3) {
      for (int cr = 0; cr < 256; cr += 3) {
        uint8_t got[3];
        YuvToBgrPixel(y, cb, cr, got);
        double want[3];
        YuvToBgr601Reference(y, cb, cr, want);
        for (int c = 0; c < 3; ++c) {
          worst = std::max(worst, static_cast<int>(std::ceil(std::abs(got[c] - want[c]) - 0.5)));
        }
      }
    }
  }
  EXPECT_LE(worst, 1);
}

TEST(PixelFormat, YuvBlackWhiteGreyAreExact) {
  uint8_t p[3];
  YuvToBgrPixel(16, 128, 128, p);
  EXPECT_EQ(p[0], 0);
  EXPECT_EQ(p[2], 0);
  YuvToBgrPixel(235, 128, 128, p);
  EXPECT_EQ(p[0], 255);
  EXPECT_EQ(p[1], 255);
  EXPECT_EQ(p[2], 255);
  YuvToBgrPixel(0, 128, 128, p);  // below black clamps
  EXPECT_EQ(p[1], 0);
}

// A 4x2 YUYV image with a 12-byte stride (4 bytes of padding per row set to junk).
TEST(PixelFormat, YuyvHonoursStrideAndSharesChromaPerPair) {
  const int stride = 12;
  std::vector<uint8_t> src(stride * 2, 0xEE);
  const uint8_t row0[8] = {16, 90, 235, 240, 81, 90, 145, 54};
  const uint8_t row1[8] = {41, 240, 41, 110, 210, 16, 170, 166};
  std::copy(row0, row0 + 8, src.begin());
  std::copy(row1, row1 + 8, src.begin() + stride);
  std::vector<uint8_t> dst(4 * 2 * 3);
  YuyvToBgr(src.data(), stride, 4, 2, dst.data(), 12);
  for (int r = 0; r < 2; ++r) {
    const uint8_t* g = r == 0 ? row0 : row1;
    for (int x = 0; x < 4; ++x) {
      const uint8_t* q = g + (x / 2) * 4;
      double want[3];
      YuvToBgr601Reference(q[(x % 2) * 2], q[1], q[3], want);
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(dst[(r * 4 + x) * 3 + c], want[c], 1.0) << "row " << r << " x " << x;
      }
    }
  }
}

TEST(PixelFormat, Nv12HonoursStrideAndShares2x2Chroma) {
  const int w = 4, h = 4, stride = 8;
  std::vector<uint8_t> buf(stride * h + stride * h / 2, 0xEE);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) buf[y * stride + x] = static_cast<uint8_t>(30 + 40 * y + 10 * x);
  }
  uint8_t* uv = buf.data() + stride * h;
  const uint8_t chroma[2][4] = {{60, 200, 180, 90}, {128, 128, 16, 240}};  // Cb Cr Cb Cr
  for (int r = 0; r < 2; ++r) std::copy(chroma[r], chroma[r] + 4, uv + r * stride);
  std::vector<uint8_t> dst(w * h * 3);
  Nv12ToBgr(buf.data(), stride, uv, stride, w, h, dst.data(), w * 3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const uint8_t* c = chroma[y / 2] + (x / 2) * 2;
      double want[3];
      YuvToBgr601Reference(buf[y * stride + x], c[0], c[1], want);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(dst[(y * w + x) * 3 + k], want[k], 1.0);
    }
  }
}

TEST(PixelFormat, GreyBgrRgbAreExactWithPaddedStride) {
  const int w = 5, h = 3;
  RawFrame raw;
  raw.width = w;
  raw.height = h;
  PixelConverter conv;
  Frame out;
  // BGR24 and RGB24 with stride 16 (15 bytes of pixels + 1 junk).
  for (uint32_t fourcc : {V4L2_PIX_FMT_BGR24, V4L2_PIX_FMT_RGB24}) {
    raw.fourcc = fourcc;
    raw.bytesperline = 16;
    raw.bytes.assign(16 * h, 0xEE);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        uint8_t c[3];
        PatternBgr(8 * x, 8 * y, 0, 0, c);
        uint8_t* p = &raw.bytes[y * 16 + x * 3];
        p[0] = fourcc == V4L2_PIX_FMT_RGB24 ? c[2] : c[0];
        p[1] = c[1];
        p[2] = fourcc == V4L2_PIX_FMT_RGB24 ? c[0] : c[2];
      }
    }
    ASSERT_TRUE(conv.ToBgr(raw, &out).ok());
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        uint8_t c[3];
        PatternBgr(8 * x, 8 * y, 0, 0, c);
        for (int k = 0; k < 3; ++k) EXPECT_EQ(out.bgr[(y * w + x) * 3 + k], c[k]);
      }
    }
  }
  raw.fourcc = V4L2_PIX_FMT_GREY;
  raw.bytesperline = 8;
  raw.bytes.assign(8 * h, 0xEE);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) raw.bytes[y * 8 + x] = static_cast<uint8_t>(y * 50 + x);
  }
  ASSERT_TRUE(conv.ToBgr(raw, &out).ok());
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int k = 0; k < 3; ++k) EXPECT_EQ(out.bgr[(y * w + x) * 3 + k], y * 50 + x);
    }
  }
}

TEST(PixelFormat, ShortRawFrameIsFrameError) {
  RawFrame raw;
  raw.fourcc = V4L2_PIX_FMT_YUYV;
  raw.width = 8;
  raw.height = 4;
  raw.bytesperline = 16;
  raw.bytes.assign(16 * 3 + 15, 0);  // one byte short of a full frame
  PixelConverter conv;
  Frame out;
  Status s = conv.ToBgr(raw, &out);
  EXPECT_EQ(s.kind(), ErrorKind::kFrameError);
  EXPECT_NE(s.message().find("short"), std::string::npos) << s.message();
  raw.bytes.push_back(0);
  EXPECT_TRUE(conv.ToBgr(raw, &out).ok());
}

std::vector<uint8_t> EncodeJpeg(int w, int h) {
  std::vector<uint8_t> bgr(w * h * 3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) PatternBgr(x, y, 0, 0, &bgr[(y * w + x) * 3]);
  }
  tjhandle tj = tjInitCompress();
  unsigned char* jpeg = nullptr;
  unsigned long size = 0;
  EXPECT_EQ(tjCompress2(tj, bgr.data(), w, 0, h, TJPF_BGR, &jpeg, &size, TJSAMP_444, 95, 0), 0);
  std::vector<uint8_t> out(jpeg, jpeg + size);
  tjFree(jpeg);
  tjDestroy(tj);
  return out;
}

TEST(PixelFormat, MjpegDecodesAndRejectsTruncatedCorruptEmptyAndWrongSize) {
  RawFrame raw;
  raw.fourcc = V4L2_PIX_FMT_MJPEG;
  raw.width = 64;
  raw.height = 32;
  const std::vector<uint8_t> good = EncodeJpeg(64, 32);
  PixelConverter conv;
  Frame out;
  raw.bytes = good;
  ASSERT_TRUE(conv.ToBgr(raw, &out).ok());
  int worst = 0;
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 64; ++x) {
      uint8_t c[3];
      PatternBgr(x, y, 0, 0, c);
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::abs(out.bgr[(y * 64 + x) * 3 + k] - c[k]));
    }
  }
  EXPECT_LE(worst, 2);  // quality 95, 4:4:4, flat 8x8 blocks: only DC quantisation error

  raw.bytes.assign(good.begin(), good.begin() + good.size() / 2);
  EXPECT_EQ(conv.ToBgr(raw, &out).kind(), ErrorKind::kFrameError);
  raw.bytes = good;
  for (size_t i = good.size() / 2; i < good.size() / 2 + 32; ++i)
    raw.bytes[i] = i % 2 ? 0xD9 : 0xFF;
  EXPECT_EQ(conv.ToBgr(raw, &out).kind(), ErrorKind::kFrameError);
  raw.bytes.clear();
  EXPECT_EQ(conv.ToBgr(raw, &out).kind(), ErrorKind::kFrameError);
  raw.bytes.assign(200, 0x5A);  // no SOI marker at all
  EXPECT_EQ(conv.ToBgr(raw, &out).kind(), ErrorKind::kFrameError);
  raw.bytes = good;
  raw.width = 32;  // the negotiated size disagrees with the JPEG's
  EXPECT_EQ(conv.ToBgr(raw, &out).kind(), ErrorKind::kFrameError);
  raw.width = 64;
  EXPECT_TRUE(conv.ToBgr(raw, &out).ok()) << "the decoder must stay usable after errors";
}

TEST(PixelFormat, SideBySideSplitHonoursOrder) {
  Frame both;
  both.width = 4;
  both.height = 2;
  both.timestamp_ns = 77;
  both.sequence = 9;
  both.bgr.resize(4 * 2 * 3);
  for (size_t i = 0; i < both.bgr.size(); ++i) both.bgr[i] = static_cast<uint8_t>(i);
  Frame l, r;
  ASSERT_TRUE(SplitSideBySide(both, true, &l, &r).ok());
  ASSERT_EQ(l.width, 2);
  EXPECT_EQ(l.bgr[0], 0);
  EXPECT_EQ(r.bgr[0], 6);
  EXPECT_EQ(l.bgr[6], 12);  // second row starts at byte 4*3
  EXPECT_EQ(r.bgr[6], 18);
  EXPECT_EQ(r.timestamp_ns, 77);
  EXPECT_EQ(r.sequence, 9u);
  ASSERT_TRUE(SplitSideBySide(both, false, &l, &r).ok());
  EXPECT_EQ(l.bgr[0], 6);
  EXPECT_EQ(r.bgr[0], 0);
  both.width = 3;
  EXPECT_EQ(SplitSideBySide(both, true, &l, &r).kind(), ErrorKind::kInvalidArgument);
}

TEST(PixelFormat, FourccNames) {
  EXPECT_EQ(FourccToString(V4L2_PIX_FMT_YUYV), "YUYV");
  EXPECT_EQ(FourccToString(V4L2_PIX_FMT_MJPEG), "MJPG");
  EXPECT_TRUE(IsSupportedFourcc(V4L2_PIX_FMT_NV12));
  EXPECT_FALSE(IsSupportedFourcc(V4L2_PIX_FMT_YUV420));
}

}  // namespace
}  // namespace sfrt::v4l2
