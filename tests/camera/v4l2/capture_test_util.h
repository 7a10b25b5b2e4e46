// Helpers shared by the capture tests: configs for the fake device and pattern comparisons.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <string>

#include "camera/v4l2/fake_v4l2.h"
#include "camera/v4l2/test_pattern.h"
#include "sfrt/camera/v4l2/capture.h"

namespace sfrt::v4l2::testing {

constexpr int64_t kPeriod30 = 33'333'333;  // ns per frame at 30 fps (the fake rounds the same)

inline CaptureConfig MakeConfig(const std::string& path, uint32_t fourcc, int w, int h) {
  CaptureConfig c;
  c.device = path;
  c.pixel_format = fourcc;
  c.width = w;
  c.height = h;
  c.fps = 30;
  c.buffer_count = 4;
  c.watchdog_ms = 500;
  return c;
}

// Largest |channel difference| between a frame and the pattern of (seq, side), with x offset
// dx into the pattern (side-by-side halves).
inline int MaxDiffToPattern(const Frame& f, uint32_t seq, int side) {
  int worst = 0;
  for (int y = 0; y < f.height; ++y) {
    for (int x = 0; x < f.width; ++x) {
      uint8_t want[3];
      PatternBgr(x, y, seq, side, want);
      const uint8_t* got = &f.bgr[(static_cast<size_t>(y) * f.width + x) * 3];
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(got[c] - want[c]));
    }
  }
  return worst;
}

inline int MaxDiffToGreyPattern(const Frame& f, uint32_t seq, int side) {
  int worst = 0;
  for (int y = 0; y < f.height; ++y) {
    for (int x = 0; x < f.width; ++x) {
      const int want = PatternGrey(x, y, seq, side);
      const uint8_t* got = &f.bgr[(static_cast<size_t>(y) * f.width + x) * 3];
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(got[c] - want));
    }
  }
  return worst;
}

}  // namespace sfrt::v4l2::testing
