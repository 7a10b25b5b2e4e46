// AVX-512 convolution kernels (compiled with -mavx512f -mavx512bw -mavx512vl -mavx512dq only
// in this translation unit; runtime/CMakeLists.txt). Tiles: 8 pixels x 32 channels (wide) and
// 8 pixels x 16 channels (narrow, for layers with at most 16 output channels).
#include <immintrin.h>

#include "kernels/simd/conv_driver_inl.h"

namespace sfrt::avx512 {
namespace {

struct V {
  using Reg = __m512;
  static constexpr int kLanes = 16;
  static Reg Load(const float* p) { return _mm512_loadu_ps(p); }
  static Reg Broadcast(const float* p) { return _mm512_set1_ps(*p); }
  static Reg Fma(Reg a, Reg b, Reg acc) { return _mm512_fmadd_ps(a, b, acc); }
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

void Conv8x32(const ConvArgs& a, int b, int e) { simd::ConvRows<V, 8, 2>(a, b, e); }
void Conv8x16(const ConvArgs& a, int b, int e) { simd::ConvRows<V, 8, 1>(a, b, e); }
void UpConv8x32(const ConvArgs& a, int b, int e) { simd::UpConvRows<V, 8, 2>(a, b, e); }
void UpConv8x16(const ConvArgs& a, int b, int e) { simd::UpConvRows<V, 8, 1>(a, b, e); }

}  // namespace

const IsaConvKernels& ConvKernels() {
  static const IsaConvKernels kernels = {
      {16, Conv8x16, UpConv8x16, "conv2d_f32__avx512_8x16", "upconv2x_conv3x3_f32__avx512_8x16"},
      {32, Conv8x32, UpConv8x32, "conv2d_f32__avx512_8x32", "upconv2x_conv3x3_f32__avx512_8x32"},
  };
  return kernels;
}

}  // namespace sfrt::avx512
