// NEON quantisation of float32 rows to uint8 (base Armv8 NEON, -ffp-contract=off), the same bytes
// as Int8Quantize: one multiply, the clamp to [-512, 512] written as Int8Quantize's compares (a
// NaN becomes -512), conversion rounding half to even (fcvtns), the zero point added and a
// clamp to 0..255.
#include <arm_neon.h>

#include <cstdint>

#include "kernels/int8_job.h"

namespace sfrt::neon {
namespace {

inline int32x4_t Quantize4(float32x4_t x, float32x4_t inv, int32x4_t zp) {
  const float32x4_t lo = vdupq_n_f32(-512.0f), hi = vdupq_n_f32(512.0f);
  float32x4_t t = vmulq_f32(x, inv);
  t = vbslq_f32(vcgtq_f32(t, lo), t, lo);
  t = vbslq_f32(vcltq_f32(t, hi), t, hi);
  int32x4_t q = vaddq_s32(vcvtnq_s32_f32(t), zp);
  q = vmaxq_s32(q, vdupq_n_s32(0));
  return vminq_s32(q, vdupq_n_s32(255));
}

}  // namespace

void QuantizeRows(const ConstTensorView& in, float inv_scale, int zero_point, const ByteView& out,
                  int row_begin, int row_end) {
  const float32x4_t inv = vdupq_n_f32(inv_scale);
  const int32x4_t zp = vdupq_n_s32(zero_point);
  const ptrdiff_t n = static_cast<ptrdiff_t>(in.width) * in.channels;  // a row is dense
  for (int y = row_begin; y < row_end; ++y) {
    const float* src = in.pixel(y, 0);
    uint8_t* dst = out.pixel(y, 0);
    ptrdiff_t i = 0;
    for (; i + 16 <= n; i += 16) {
      const int32x4_t q0 = Quantize4(vld1q_f32(src + i), inv, zp);
      const int32x4_t q1 = Quantize4(vld1q_f32(src + i + 4), inv, zp);
      const int32x4_t q2 = Quantize4(vld1q_f32(src + i + 8), inv, zp);
      const int32x4_t q3 = Quantize4(vld1q_f32(src + i + 12), inv, zp);
      const uint16x8_t lo = vcombine_u16(vqmovun_s32(q0), vqmovun_s32(q1));
      const uint16x8_t hi = vcombine_u16(vqmovun_s32(q2), vqmovun_s32(q3));
      vst1q_u8(dst + i, vcombine_u8(vqmovn_u16(lo), vqmovn_u16(hi)));
    }
    for (; i < n; ++i) dst[i] = Int8Quantize(src[i], inv_scale, zero_point);
  }
}

}  // namespace sfrt::neon
