// NEON (aarch64 Advanced SIMD) convolution kernels. Tiles (pixels x output channels), the
// accumulators using most of the 32 vector registers: 6x16 (24 accumulators) for layers with
// more than 8 output channels, 8x8 for 5..8 and 8x4 for at most 4.
#include <arm_neon.h>

#include "kernels/simd/conv_driver_inl.h"

namespace sfrt::neon {
namespace {

struct V {
  using Reg = float32x4_t;
  static constexpr int kLanes = 4;
  static Reg Load(const float* p) { return vld1q_f32(p); }
  static Reg LoadPartial(const float* p, int n) {
    float tmp[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    for (int i = 0; i < n; ++i) tmp[i] = p[i];
    return vld1q_f32(tmp);
  }
  static Reg Broadcast(const float* p) { return vld1q_dup_f32(p); }
  static Reg Fma(Reg a, Reg b, Reg acc) { return vfmaq_f32(acc, a, b); }
  static void Store(float* p, Reg v) { vst1q_f32(p, v); }
  static void StorePartial(float* p, Reg v, int n) {
    float tmp[4];
    vst1q_f32(tmp, v);
    for (int i = 0; i < n; ++i) p[i] = tmp[i];
  }
  // v > 0 ? v : v * slope, as the reference (NaN stays NaN).
  static Reg Leaky(Reg v, float slope) {
    const uint32x4_t positive = vcgtq_f32(v, vdupq_n_f32(0.0f));
    return vbslq_f32(positive, v, vmulq_n_f32(v, slope));
  }
  static Reg Relu(Reg v) {
    const uint32x4_t positive = vcgtq_f32(v, vdupq_n_f32(0.0f));
    return vbslq_f32(positive, v, vdupq_n_f32(0.0f));
  }
};

void Conv6x16(const ConvArgs& a, int r0, int r1, int b0, int b1) {
  simd::ConvRows<V, 6, 4>(a, r0, r1, b0, b1);
}
void Conv8x8(const ConvArgs& a, int r0, int r1, int b0, int b1) {
  simd::ConvRows<V, 8, 2>(a, r0, r1, b0, b1);
}
void Conv8x4(const ConvArgs& a, int r0, int r1, int b0, int b1) {
  simd::ConvRows<V, 8, 1>(a, r0, r1, b0, b1);
}
void UpConv6x16(const ConvArgs& a, int r0, int r1, int b0, int b1) {
  simd::UpConvRows<V, 6, 4>(a, r0, r1, b0, b1);
}
void UpConv8x8(const ConvArgs& a, int r0, int r1, int b0, int b1) {
  simd::UpConvRows<V, 8, 2>(a, r0, r1, b0, b1);
}
void UpConv8x4(const ConvArgs& a, int r0, int r1, int b0, int b1) {
  simd::UpConvRows<V, 8, 1>(a, r0, r1, b0, b1);
}

}  // namespace

const IsaConvKernels& ConvKernels() {
  static const IsaConvKernels kernels = {
      {
          {4, Conv8x4, UpConv8x4, "conv2d_f32__neon_8x4", "upconv2x_conv3x3_f32__neon_8x4"},
          {8, Conv8x8, UpConv8x8, "conv2d_f32__neon_8x8", "upconv2x_conv3x3_f32__neon_8x8"},
          {16, Conv6x16, UpConv6x16, "conv2d_f32__neon_6x16", "upconv2x_conv3x3_f32__neon_6x16"},
      },
      3,
  };
  return kernels;
}

}  // namespace sfrt::neon
