// NEON (aarch64 Advanced SIMD) convolution kernels. Tiles (pixels x output channels), the
// accumulators using most of the 32 vector registers: 6x16 (24 accumulators) for layers with
// more than 8 output channels, 8x8 for 5..8 and 8x4 for at most 4.
#include <arm_neon.h>

#include "kernels/simd/kernel_tables_inl.h"

namespace sfrt::neon {
namespace {

struct V {
  using Reg = float32x4_t;
  static constexpr int kLanes = 4;
  static constexpr int kRegs = 32;
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

}  // namespace

const IsaConvKernels& ConvKernels() {
  static const IsaConvKernels kernels = {
      {
          simd::ConvVariant<V, 8, 1>("conv2d_f32__neon_8x4", "upconv2x_conv3x3_f32__neon_8x4"),
          simd::ConvVariant<V, 8, 2>("conv2d_f32__neon_8x8", "upconv2x_conv3x3_f32__neon_8x8"),
          simd::ConvVariant<V, 6, 4>("conv2d_f32__neon_6x16", "upconv2x_conv3x3_f32__neon_6x16"),
      },
      3,
      simd::FewOutConvRows<V, 6, 0>,
      "conv2d_fewout_f32__neon_6xc",
  };
  return kernels;
}

const WinogradKernels& WinogradUpKernels() {
  static const WinogradKernels kernels =
      simd::WinogradUpConvKernels<V, 6, 4>("upconv2x_conv3x3_winograd_f2x2_2x2__neon_6x16");
  return kernels;
}

const WinogradKernels& WinogradF2Kernels() {
  static const WinogradKernels kernels =
      simd::WinogradConvKernels<V, 2, 6, 4>("conv2d_winograd_f2x2_3x3__neon_6x16");
  return kernels;
}

const WinogradKernels& WinogradF4Kernels() {
  static const WinogradKernels kernels =
      simd::WinogradConvKernels<V, 4, 6, 4>("conv2d_winograd_f4x4_3x3__neon_6x16");
  return kernels;
}

}  // namespace sfrt::neon
