// The test pattern the fake V4L2 device renders, and real-valued colour references.
//
// The pattern is flat over 8x8 blocks (so 4:2:2 / 4:2:0 chroma subsampling and 8x8 JPEG blocks
// keep it intact) and shifts one block per frame, so a frame's pixels identify its sequence
// number. `side` (0 = left camera, 1 = right) changes every colour, so L and R are told apart.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace sfrt::v4l2::testing {

inline void PatternBgr(int x, int y, uint32_t seq, int side, uint8_t* bgr) {
  const uint32_t bx = static_cast<uint32_t>(x / 8) + seq;
  const uint32_t by = static_cast<uint32_t>(y / 8);
  const uint32_t s = static_cast<uint32_t>(side);
  bgr[0] = static_cast<uint8_t>((bx * 37 + by * 11 + s * 90) & 0xff);
  bgr[1] = static_cast<uint8_t>((bx * 17 + by * 53 + s * 45) & 0xff);
  bgr[2] = static_cast<uint8_t>((bx * 91 + by * 23 + s * 150) & 0xff);
}

// Full-range luma of the pattern: what a GREY (Y8) frame holds.
inline uint8_t PatternGrey(int x, int y, uint32_t seq, int side) {
  uint8_t c[3];
  PatternBgr(x, y, seq, side, c);
  return static_cast<uint8_t>((29 * c[0] + 150 * c[1] + 77 * c[2] + 128) >> 8);
}

// BT.601 limited-range encoding, real-valued and rounded (ITU-R BT.601 coefficients).
inline void BgrToYuv601(const uint8_t* bgr, int* y, int* cb, int* cr) {
  const double b = bgr[0], g = bgr[1], r = bgr[2];
  auto q = [](double v) { return static_cast<int>(std::lround(std::clamp(v, 0.0, 255.0))); };
  *y = q(16.0 + (65.481 * r + 128.553 * g + 24.966 * b) / 255.0);
  *cb = q(128.0 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255.0);
  *cr = q(128.0 + (112.0 * r - 93.786 * g - 18.214 * b) / 255.0);
}

// BT.601 limited-range decoding, real-valued (the exact inverse matrix), clamped to [0, 255].
inline void YuvToBgr601Reference(int y, int cb, int cr, double* bgr) {
  const double c = 255.0 / 219.0 * (y - 16);
  const double d = 255.0 / 224.0 * (cb - 128);
  const double e = 255.0 / 224.0 * (cr - 128);
  const double r = c + 1.402 * e;
  const double g = c - 0.344136 * d - 0.714136 * e;
  const double b = c + 1.772 * d;
  bgr[0] = std::clamp(b, 0.0, 255.0);
  bgr[1] = std::clamp(g, 0.0, 255.0);
  bgr[2] = std::clamp(r, 0.0, 255.0);
}

}  // namespace sfrt::v4l2::testing
