// NEON (aarch64 Advanced SIMD) convolution kernels. Tiles (pixels x output channels), the
// accumulators using most of the 32 vector registers: 6x16 (24 accumulators) for layers with
// more than 8 output channels, 8x8 for 5..8 and 8x4 for at most 4.
#include <arm_neon.h>

#include "kernels/simd/conv_driver_inl.h"
#include "kernels/simd/conv_few_out_inl.h"
#include "kernels/simd/winograd_driver_inl.h"

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
  static Reg Add(Reg a, Reg b) { return vaddq_f32(a, b); }
  static Reg Sub(Reg a, Reg b) { return vsubq_f32(a, b); }
  static Reg Set(float x) { return vdupq_n_f32(x); }
  static float ReduceAdd(Reg v) { return vaddvq_f32(v); }
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

void FewOut6(const ConvArgs& a, int r0, int r1, int b0, int b1) {
  simd::FewOutConvRows<V, 6>(a, r0, r1, b0, b1);
}
void WinogradUpIn(const WinogradArgs& a, int b, int e) {
  simd::WinogradInput<V, WinogradPhaseTransform>(a, b, e);
}
void WinogradUpOut(const WinogradArgs& a, int b, int e) { simd::WinogradUpOutput<V>(a, b, e); }
void WinogradIn2(const WinogradArgs& a, int b, int e) {
  simd::WinogradInput<V, WinogradTransform<2>>(a, b, e);
}
void WinogradOut2(const WinogradArgs& a, int b, int e) {
  simd::WinogradOutput<V, WinogradTransform<2>>(a, b, e);
}
void WinogradIn4(const WinogradArgs& a, int b, int e) {
  simd::WinogradInput<V, WinogradTransform<4>>(a, b, e);
}
void WinogradOut4(const WinogradArgs& a, int b, int e) {
  simd::WinogradOutput<V, WinogradTransform<4>>(a, b, e);
}
void WinogradProduct6x16(const WinogradArgs& a, int b, int e) {
  simd::WinogradProduct<V, 6, 4>(a, b, e);
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
      FewOut6,
      "conv2d_fewout_f32__neon_6xc",
  };
  return kernels;
}

const WinogradKernels& WinogradUpKernels() {
  static const WinogradKernels kernels = {2,
                                          16,
                                          WinogradUpIn,
                                          WinogradProduct6x16,
                                          WinogradUpOut,
                                          "upconv2x_conv3x3_winograd_f2x2_2x2__neon_6x16"};
  return kernels;
}

const WinogradKernels& WinogradF2Kernels() {
  static const WinogradKernels kernels = {
      2, 16, WinogradIn2, WinogradProduct6x16, WinogradOut2, "conv2d_winograd_f2x2_3x3__neon_6x16"};
  return kernels;
}

const WinogradKernels& WinogradF4Kernels() {
  static const WinogradKernels kernels = {
      4, 16, WinogradIn4, WinogradProduct6x16, WinogradOut4, "conv2d_winograd_f4x4_3x3__neon_6x16"};
  return kernels;
}

}  // namespace sfrt::neon
