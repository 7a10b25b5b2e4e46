// The SIMD raw converters (AVX2 on x86-64, NEON on aarch64) against the scalar loop, which the
// v4l2 tests check against the real-valued BT.601 formula: every (Y, Cb, Cr), every row tail
// and padded strides.
#include "sfrt/camera/v4l2/yuv_to_bgr.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace sfrt::v4l2 {
namespace {

bool CpuHasSimdPath() {
#if defined(__x86_64__)
  return __builtin_cpu_supports("avx2");
#elif defined(__aarch64__)
  return true;
#else
  return false;
#endif
}

TEST(RawConvert, FastestPathIsSimdWhereTheCpuHasIt) {
  if (!CpuHasSimdPath()) GTEST_SKIP() << "no AVX2 or NEON: the scalar loop is the only path";
  EXPECT_STRNE(RawConvertPathName(), "scalar");
}

// Row r = Cb * 256 + Cr holds the 256 luma values with that chroma: all 2^24 triples.
TEST(RawConvert, YuyvFastestMatchesScalarForEveryYCbCr) {
  const int w = 256, h = 256 * 256, stride = 2 * w;
  std::vector<uint8_t> src(static_cast<size_t>(stride) * h);
  for (int r = 0; r < h; ++r) {
    uint8_t* s = src.data() + static_cast<size_t>(r) * stride;
    for (int x = 0; x < w; x += 2) {
      s[2 * x] = static_cast<uint8_t>(x);
      s[2 * x + 1] = static_cast<uint8_t>(r >> 8);
      s[2 * x + 2] = static_cast<uint8_t>(x + 1);
      s[2 * x + 3] = static_cast<uint8_t>(r & 255);
    }
  }
  std::vector<uint8_t> fast(static_cast<size_t>(w) * h * 3), slow(fast.size());
  YuyvToBgr(src.data(), stride, w, h, fast.data(), 3 * w, RawConvertPath::kFastest);
  YuyvToBgr(src.data(), stride, w, h, slow.data(), 3 * w, RawConvertPath::kScalar);
  for (size_t i = 0; i < fast.size(); ++i) {
    const size_t px = i / 3;
    ASSERT_EQ(fast[i], slow[i]) << RawConvertPathName() << ": Y " << px % w << " Cb "
                                << (px / w >> 8) << " Cr " << (px / w & 255) << " channel "
                                << i % 3;
  }
  // And the scalar loop is the per-pixel formula (Y 16..235, Cb 90, Cr 240 here).
  uint8_t want[3];
  const size_t row = 90 * 256 + 240;
  for (int y = 0; y < 256; ++y) {
    YuvToBgrPixel(y, 90, 240, want);
    ASSERT_EQ(0, std::memcmp(want, &slow[(row * w + y) * 3], 3)) << "Y " << y;
  }
}

// NV12: Cb fixed per block of rows; chroma row k (luma rows 2k, 2k+1) has Cr = k.
TEST(RawConvert, Nv12FastestMatchesScalarForEveryYCbCr) {
  const int w = 256, h = 512;
  std::vector<uint8_t> y_plane(static_cast<size_t>(w) * h), uv(static_cast<size_t>(w) * h / 2);
  for (int r = 0; r < h; ++r) {
    for (int x = 0; x < w; ++x) y_plane[static_cast<size_t>(r) * w + x] = static_cast<uint8_t>(x);
  }
  std::vector<uint8_t> fast(static_cast<size_t>(w) * h * 3), slow(fast.size());
  for (int cb = 0; cb < 256; ++cb) {
    for (int k = 0; k < h / 2; ++k) {
      for (int x = 0; x < w; x += 2) {
        uv[static_cast<size_t>(k) * w + x] = static_cast<uint8_t>(cb);
        uv[static_cast<size_t>(k) * w + x + 1] = static_cast<uint8_t>(k);
      }
    }
    Nv12ToBgr(y_plane.data(), w, uv.data(), w, w, h, fast.data(), 3 * w, RawConvertPath::kFastest);
    Nv12ToBgr(y_plane.data(), w, uv.data(), w, w, h, slow.data(), 3 * w, RawConvertPath::kScalar);
    for (size_t i = 0; i < fast.size(); ++i) {
      const size_t px = i / 3;
      ASSERT_EQ(fast[i], slow[i]) << RawConvertPathName() << ": Y " << px % w << " Cb " << cb
                                  << " Cr " << px / w / 2 << " channel " << i % 3;
    }
  }
}

// Widths 1..80 (every tail after whole 16-pixel steps, odd ones too), padded source and
// destination strides, random bytes; the padding of the destination is left alone.
TEST(RawConvert, FastestMatchesScalarAtEveryWidthAndStride) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  const int h = 5;
  for (int w = 1; w <= 80; ++w) {
    const int dst_stride = 3 * w + 5;
    for (const bool nv12 : {false, true}) {
      const int stride = (nv12 ? w + 1 : 2 * w) + 7;
      std::vector<uint8_t> src(static_cast<size_t>(stride) * (h + (h + 1) / 2));
      for (uint8_t& b : src) b = static_cast<uint8_t>(byte(rng));
      std::vector<uint8_t> fast(static_cast<size_t>(dst_stride) * h, 0xAB), slow(fast);
      for (const bool fastest : {true, false}) {
        const RawConvertPath path = fastest ? RawConvertPath::kFastest : RawConvertPath::kScalar;
        uint8_t* dst = fastest ? fast.data() : slow.data();
        if (nv12) {
          Nv12ToBgr(src.data(), stride, src.data() + static_cast<size_t>(stride) * h, stride, w, h,
                    dst, dst_stride, path);
        } else {
          YuyvToBgr(src.data(), stride, w, h, dst, dst_stride, path);
        }
      }
      ASSERT_EQ(fast, slow) << (nv12 ? "NV12" : "YUYV") << " width " << w;
      for (int r = 0; r < h; ++r) {
        for (int i = 3 * w; i < dst_stride; ++i) {
          ASSERT_EQ(fast[static_cast<size_t>(r) * dst_stride + i], 0xAB) << "width " << w;
        }
      }
    }
  }
}

}  // namespace
}  // namespace sfrt::v4l2
