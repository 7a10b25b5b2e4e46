// AVX-512 convolution kernels (compiled with -mavx512f -mavx512bw -mavx512vl -mavx512dq only
// in this translation unit; runtime/CMakeLists.txt). Tiles (pixels x output channels), the
// accumulators using most of the 32 ZMM registers: 6x64 (24 accumulators, 4 weight vectors, one
// broadcast: 10 loads per 24 FMAs) for layers with more than 32 output channels, 12x32 for
// 17..32, 8x16 for 9..16 and 12x8 (256-bit) for at most 8; the few-output layers on 256-bit
// vectors, 4 pixels a tile.
#include <immintrin.h>

#include "kernels/simd/kernel_tables_inl.h"

namespace sfrt::avx512 {
namespace {

struct V {
  using Reg = __m512;
  static constexpr int kLanes = 16;
  static constexpr int kRegs = 32;
  static Reg Load(const float* p) { return _mm512_loadu_ps(p); }
  static Reg LoadPartial(const float* p, int n) {
    return _mm512_maskz_loadu_ps(static_cast<__mmask16>((1u << n) - 1u), p);
  }
  static Reg Broadcast(const float* p) { return _mm512_set1_ps(*p); }
  static Reg Fma(Reg a, Reg b, Reg acc) { return _mm512_fmadd_ps(a, b, acc); }
  static Reg Add(Reg a, Reg b) { return _mm512_add_ps(a, b); }
  static Reg Sub(Reg a, Reg b) { return _mm512_sub_ps(a, b); }
  static Reg Set(float x) { return _mm512_set1_ps(x); }
  // Lane sum in 512-bit registers with the zero-masked shuffles (GCC 12's
  // _mm512_reduce_add_ps, casts and unmasked shuffles trip -Wmaybe-uninitialized).
  static float ReduceAdd(Reg v) {
    constexpr __mmask16 kAll = 0xFFFF;
    v = _mm512_add_ps(v, _mm512_maskz_shuffle_f32x4(kAll, v, v, 0x4E));
    v = _mm512_add_ps(v, _mm512_maskz_shuffle_f32x4(kAll, v, v, 0xB1));
    v = _mm512_add_ps(v, _mm512_maskz_permute_ps(kAll, v, 0x4E));
    v = _mm512_add_ps(v, _mm512_maskz_permute_ps(kAll, v, 0xB1));
    return _mm512_cvtss_f32(v);
  }
  static void Store(float* p, Reg v) { _mm512_storeu_ps(p, v); }
  static void StorePartial(float* p, Reg v, int n) {
    _mm512_mask_storeu_ps(p, static_cast<__mmask16>((1u << n) - 1u), v);
  }
  // v > 0 ? v : v * slope, as the reference (NaN stays NaN).
  static Reg Leaky(Reg v, float slope) {
    const __mmask16 positive = _mm512_cmp_ps_mask(v, _mm512_setzero_ps(), _CMP_GT_OQ);
    return _mm512_mask_blend_ps(positive, _mm512_mul_ps(v, _mm512_set1_ps(slope)), v);
  }
  static Reg Relu(Reg v) {
    const __mmask16 positive = _mm512_cmp_ps_mask(v, _mm512_setzero_ps(), _CMP_GT_OQ);
    return _mm512_mask_blend_ps(positive, _mm512_setzero_ps(), v);
  }
};

// 256-bit vectors (AVX-512VL keeps all 32 registers and masked loads/stores) for layers with
// at most 8 output channels, where a 16-lane tile would compute mostly padding, and for the
// few-output kernel (4 pixels a tile, as avx2's: the 16-lane one with 8 took 1.5x its time).
struct V8 {
  using Reg = __m256;
  static constexpr int kLanes = 8;
  static constexpr int kRegs = 32;  // AVX-512VL: ymm0-31
  static Reg Load(const float* p) { return _mm256_loadu_ps(p); }
  static Reg LoadPartial(const float* p, int n) {
    return _mm256_maskz_loadu_ps(static_cast<__mmask8>((1u << n) - 1u), p);
  }
  static Reg Broadcast(const float* p) { return _mm256_broadcast_ss(p); }
  static Reg Fma(Reg a, Reg b, Reg acc) { return _mm256_fmadd_ps(a, b, acc); }
  static Reg Set(float x) { return _mm256_set1_ps(x); }
  static float ReduceAdd(Reg v) {
    const __m128 s4 = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    const __m128 s2 = _mm_add_ps(s4, _mm_movehl_ps(s4, s4));
    return _mm_cvtss_f32(_mm_add_ss(s2, _mm_movehdup_ps(s2)));
  }
  static void Store(float* p, Reg v) { _mm256_storeu_ps(p, v); }
  static void StorePartial(float* p, Reg v, int n) {
    _mm256_mask_storeu_ps(p, static_cast<__mmask8>((1u << n) - 1u), v);
  }
  static Reg Leaky(Reg v, float slope) {
    const __mmask8 positive = _mm256_cmp_ps_mask(v, _mm256_setzero_ps(), _CMP_GT_OQ);
    return _mm256_mask_blend_ps(positive, _mm256_mul_ps(v, _mm256_set1_ps(slope)), v);
  }
  static Reg Relu(Reg v) {
    const __mmask8 positive = _mm256_cmp_ps_mask(v, _mm256_setzero_ps(), _CMP_GT_OQ);
    return _mm256_mask_blend_ps(positive, _mm256_setzero_ps(), v);
  }
};

}  // namespace

const IsaConvKernels& ConvKernels() {
  static const IsaConvKernels kernels = {
      {
          simd::ConvVariant<V8, 12, 1>("conv2d_f32__avx512_12x8",
                                       "upconv2x_conv3x3_f32__avx512_12x8"),
          simd::ConvVariant<V, 8, 1>("conv2d_f32__avx512_8x16",
                                     "upconv2x_conv3x3_f32__avx512_8x16"),
          simd::ConvVariant<V, 12, 2>("conv2d_f32__avx512_12x32",
                                      "upconv2x_conv3x3_f32__avx512_12x32"),
          simd::ConvVariant<V, 6, 4>("conv2d_f32__avx512_6x64",
                                     "upconv2x_conv3x3_f32__avx512_6x64"),
      },
      4,
      simd::FewOutConvRows<V8, 4, 8192>,
      "conv2d_fewout_f32__avx512_4xc",
  };
  return kernels;
}

const WinogradKernels& WinogradUpKernels() {
  static const WinogradKernels kernels =
      simd::WinogradUpConvKernels<V, 6, 4>("upconv2x_conv3x3_winograd_f2x2_2x2__avx512_6x64");
  return kernels;
}

const WinogradKernels& WinogradF2Kernels() {
  static const WinogradKernels kernels =
      simd::WinogradConvKernels<V, 2, 6, 4>("conv2d_winograd_f2x2_3x3__avx512_6x64");
  return kernels;
}

const WinogradKernels& WinogradF4Kernels() {
  static const WinogradKernels kernels =
      simd::WinogradConvKernels<V, 4, 6, 4>("conv2d_winograd_f4x4_3x3__avx512_6x64");
  return kernels;
}

}  // namespace sfrt::avx512
