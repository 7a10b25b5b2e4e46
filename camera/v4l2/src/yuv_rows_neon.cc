// YUYV and NV12 rows to BGR8 with NEON, 16 pixels a step, bit for bit the scalar fixed-point
// formula (yuv_to_bgr.h): widening multiplies into 32-bit lanes, arithmetic shift, saturating
// narrow to 0..255. The even and odd pixels of each chroma pair are computed apart and zipped.
#include <arm_neon.h>

#include "yuv_rows.h"

namespace sfrt::v4l2::detail {
namespace {

// Chroma terms of 8 samples (with the rounding constant), low and high 4 lanes.
struct Terms {
  int32x4_t b[2], g[2], r[2];
};

inline Terms ChromaTerms(uint8x8_t cb, uint8x8_t cr) {
  const int16x8_t d = vreinterpretq_s16_u16(vsubl_u8(cb, vdup_n_u8(128)));
  const int16x8_t e = vreinterpretq_s16_u16(vsubl_u8(cr, vdup_n_u8(128)));
  const int32x4_t round = vdupq_n_s32(128);
  Terms t;
  for (int h = 0; h < 2; ++h) {
    const int16x4_t dh = h == 0 ? vget_low_s16(d) : vget_high_s16(d);
    const int16x4_t eh = h == 0 ? vget_low_s16(e) : vget_high_s16(e);
    t.b[h] = vmlal_n_s16(round, dh, 516);
    t.g[h] = vmlal_n_s16(vmlal_n_s16(round, dh, -100), eh, -208);
    t.r[h] = vmlal_n_s16(round, eh, 409);
  }
  return t;
}

inline uint8x8_t Clamp(int32x4_t lo, int32x4_t hi) {
  return vqmovun_s16(vcombine_s16(vshrn_n_s32(lo, 8), vshrn_n_s32(hi, 8)));
}

// 8 pixels that use the 8 chroma samples of `t`, one each: B, G, R.
inline uint8x8x3_t Pixels(uint8x8_t y, const Terms& t) {
  const int16x8_t yv = vreinterpretq_s16_u16(vsubl_u8(y, vdup_n_u8(16)));
  const int32x4_t c0 = vmull_n_s16(vget_low_s16(yv), 298);
  const int32x4_t c1 = vmull_n_s16(vget_high_s16(yv), 298);
  uint8x8x3_t p;
  p.val[0] = Clamp(vaddq_s32(c0, t.b[0]), vaddq_s32(c1, t.b[1]));
  p.val[1] = Clamp(vaddq_s32(c0, t.g[0]), vaddq_s32(c1, t.g[1]));
  p.val[2] = Clamp(vaddq_s32(c0, t.r[0]), vaddq_s32(c1, t.r[1]));
  return p;
}

// 16 pixels from the even and odd luma of 8 chroma pairs, stored as 48 bytes of BGR.
inline void SixteenPixels(uint8x8_t y_even, uint8x8_t y_odd, uint8x8_t cb, uint8x8_t cr,
                          uint8_t* dst) {
  const Terms t = ChromaTerms(cb, cr);
  const uint8x8x3_t even = Pixels(y_even, t);
  const uint8x8x3_t odd = Pixels(y_odd, t);
  uint8x16x3_t out;
  for (int c = 0; c < 3; ++c) {
    const uint8x8x2_t z = vzip_u8(even.val[c], odd.val[c]);
    out.val[c] = vcombine_u8(z.val[0], z.val[1]);
  }
  vst3q_u8(dst, out);
}

}  // namespace

int YuyvRowToBgrNeon(const uint8_t* src, int width, uint8_t* dst) {
  const int n = width / 16 * 16;
  for (int x = 0; x < n; x += 16) {
    const uint8x8x4_t v = vld4_u8(src + 2 * x);  // Y0, Cb, Y1, Cr of 8 pixel pairs
    SixteenPixels(v.val[0], v.val[2], v.val[1], v.val[3], dst + 3 * x);
  }
  return n;
}

int Nv12RowToBgrNeon(const uint8_t* y, const uint8_t* uv, int width, uint8_t* dst) {
  const int n = width / 16 * 16;
  for (int x = 0; x < n; x += 16) {
    const uint8x8x2_t yy = vld2_u8(y + x);  // even and odd pixels
    const uint8x8x2_t c = vld2_u8(uv + x);  // Cb, Cr
    SixteenPixels(yy.val[0], yy.val[1], c.val[0], c.val[1], dst + 3 * x);
  }
  return n;
}

}  // namespace sfrt::v4l2::detail
