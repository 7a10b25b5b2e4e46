// AVX2 + FMA convolution kernels (compiled with -mavx2 -mfma only in this translation unit;
// runtime/CMakeLists.txt). Tiles: 6 pixels x 16 channels (wide; 12 accumulators + 2 weight
// vectors + 1 broadcast of the 16 YMM registers) and 6 pixels x 8 channels (narrow).
#include <immintrin.h>

#include "kernels/simd/kernel_tables_inl.h"

namespace sfrt::avx2 {
namespace {

struct V {
  using Reg = __m256;
  static constexpr int kLanes = 8;
  static constexpr int kRegs = 16;
  static Reg Load(const float* p) { return _mm256_loadu_ps(p); }
  static Reg LoadPartial(const float* p, int n) {
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    return _mm256_maskload_ps(p, _mm256_cmpgt_epi32(_mm256_set1_epi32(n), lane));
  }
  static Reg Broadcast(const float* p) { return _mm256_broadcast_ss(p); }
  static Reg Fma(Reg a, Reg b, Reg acc) { return _mm256_fmadd_ps(a, b, acc); }
  static Reg Add(Reg a, Reg b) { return _mm256_add_ps(a, b); }
  static Reg Sub(Reg a, Reg b) { return _mm256_sub_ps(a, b); }
  static Reg Set(float x) { return _mm256_set1_ps(x); }
  static float ReduceAdd(Reg v) {
    const __m128 s4 = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    const __m128 s2 = _mm_add_ps(s4, _mm_movehl_ps(s4, s4));
    return _mm_cvtss_f32(_mm_add_ss(s2, _mm_movehdup_ps(s2)));
  }
  static void Store(float* p, Reg v) { _mm256_storeu_ps(p, v); }
  static void StorePartial(float* p, Reg v, int n) {
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256i mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(n), lane);
    _mm256_maskstore_ps(p, mask, v);
  }
  // v > 0 ? v : v * slope, as the reference (NaN stays NaN).
  static Reg Leaky(Reg v, float slope) {
    const Reg positive = _mm256_cmp_ps(v, _mm256_setzero_ps(), _CMP_GT_OQ);
    return _mm256_blendv_ps(_mm256_mul_ps(v, _mm256_set1_ps(slope)), v, positive);
  }
  static Reg Relu(Reg v) {
    const Reg positive = _mm256_cmp_ps(v, _mm256_setzero_ps(), _CMP_GT_OQ);
    return _mm256_and_ps(v, positive);
  }
};

}  // namespace

const IsaConvKernels& ConvKernels() {
  static const IsaConvKernels kernels = {
      {
          simd::ConvVariant<V, 6, 1>("conv2d_f32__avx2_6x8", "upconv2x_conv3x3_f32__avx2_6x8"),
          simd::ConvVariant<V, 6, 2>("conv2d_f32__avx2_6x16", "upconv2x_conv3x3_f32__avx2_6x16"),
      },
      2,
      // The last window row prefetched 8 KiB ahead: 16.0 -> 12.5 ms at 540x960 on Zen 4
      // (tools/bench/README.md); the AVX-512 and NEON tiers were not measured faster with it.
      simd::FewOutConvRows<V, 4, 8192>,
      "conv2d_fewout_f32__avx2_4xc",
  };
  return kernels;
}

const WinogradKernels& WinogradUpKernels() {
  static const WinogradKernels kernels =
      simd::WinogradUpConvKernels<V, 6, 2>("upconv2x_conv3x3_winograd_f2x2_2x2__avx2_6x16");
  return kernels;
}

const WinogradKernels& WinogradF2Kernels() {
  static const WinogradKernels kernels =
      simd::WinogradConvKernels<V, 2, 6, 2>("conv2d_winograd_f2x2_3x3__avx2_6x16");
  return kernels;
}

const WinogradKernels& WinogradF4Kernels() {
  static const WinogradKernels kernels =
      simd::WinogradConvKernels<V, 4, 6, 2>("conv2d_winograd_f4x4_3x3__avx2_6x16");
  return kernels;
}

}  // namespace sfrt::avx2
