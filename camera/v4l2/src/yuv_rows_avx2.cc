// YUYV and NV12 rows to BGR8 with AVX2, 16 pixels a step, bit for bit the scalar fixed-point
// formula (yuv_to_bgr.h): the products are summed in 32-bit lanes by vpmaddwd, shifted
// arithmetically and clamped to 0..255 by the saturating packs.
#include <immintrin.h>

#include <array>

#include "yuv_rows.h"

namespace sfrt::v4l2::detail {
namespace {

// vpshufb masks that scatter 16 bytes of one channel (0 B, 1 G, 2 R) into output block `block`
// (0..2) of the 48 interleaved bytes B0 G0 R0 B1 ...; 0x80 writes a zero.
constexpr std::array<uint8_t, 16> InterleaveMask(int channel, int block) {
  std::array<uint8_t, 16> m{};
  for (int j = 0; j < 16; ++j) {
    const int byte = 16 * block + j;
    m[j] = byte % 3 == channel ? static_cast<uint8_t>(byte / 3) : 0x80;
  }
  return m;
}

template <int Channel, int Block>
__m128i Scatter(__m128i v) {
  static constexpr std::array<uint8_t, 16> kMask = InterleaveMask(Channel, Block);
  return _mm_shuffle_epi8(v, _mm_loadu_si128(reinterpret_cast<const __m128i*>(kMask.data())));
}

// B, G or R of 16 pixels from their pairs (Y-16, Cb-128) and (Cr-128, 1), as 16 int16 lanes
// in pixel order. lo/hi are the unpacked halves (pixels 0-3, 8-11 and 4-7, 12-15).
inline __m256i Channel(__m256i yd_lo, __m256i yd_hi, __m256i e1_lo, __m256i e1_hi, __m256i k_yd,
                       __m256i k_e1) {
  const __m256i lo = _mm256_srai_epi32(
      _mm256_add_epi32(_mm256_madd_epi16(yd_lo, k_yd), _mm256_madd_epi16(e1_lo, k_e1)), 8);
  const __m256i hi = _mm256_srai_epi32(
      _mm256_add_epi32(_mm256_madd_epi16(yd_hi, k_yd), _mm256_madd_epi16(e1_hi, k_e1)), 8);
  return _mm256_packs_epi32(lo, hi);  // back to pixel order within each 128-bit lane
}

// Pairs of 16-bit coefficients for vpmaddwd: (a, b) in every 32-bit lane.
inline __m256i Pair(int a, int b) {
  return _mm256_set1_epi32(
      static_cast<int>((static_cast<uint32_t>(b) << 16) | (static_cast<uint32_t>(a) & 0xffff)));
}

// 16 pixels: Y, and the Cb and Cr of each pixel (each chroma sample repeated for the pixels
// that share it), as unsigned values in 16-bit lanes; 48 bytes of BGR to `dst`.
inline void SixteenPixels(__m256i y, __m256i cb, __m256i cr, uint8_t* dst) {
  const __m256i yv = _mm256_sub_epi16(y, _mm256_set1_epi16(16));
  const __m256i d = _mm256_sub_epi16(cb, _mm256_set1_epi16(128));
  const __m256i e = _mm256_sub_epi16(cr, _mm256_set1_epi16(128));
  const __m256i one = _mm256_set1_epi16(1);
  const __m256i yd_lo = _mm256_unpacklo_epi16(yv, d), yd_hi = _mm256_unpackhi_epi16(yv, d);
  const __m256i e1_lo = _mm256_unpacklo_epi16(e, one), e1_hi = _mm256_unpackhi_epi16(e, one);
  // 298 (Y-16) + {516, -100, 0} (Cb-128) + {0, -208, 409} (Cr-128) + 128.
  const __m256i b = Channel(yd_lo, yd_hi, e1_lo, e1_hi, Pair(298, 516), Pair(0, 128));
  const __m256i g = Channel(yd_lo, yd_hi, e1_lo, e1_hi, Pair(298, -100), Pair(-208, 128));
  const __m256i r = Channel(yd_lo, yd_hi, e1_lo, e1_hi, Pair(298, 0), Pair(409, 128));
  // Saturate to bytes: [B0-7 G0-7 | B8-15 G8-15], then B0-15 in the low half, G0-15 high.
  const __m256i bg = _mm256_permute4x64_epi64(_mm256_packus_epi16(b, g), 0xD8);
  const __m256i rr = _mm256_permute4x64_epi64(_mm256_packus_epi16(r, r), 0xD8);
  const __m128i bb = _mm256_castsi256_si128(bg);
  const __m128i gg = _mm256_extracti128_si256(bg, 1);
  const __m128i r16 = _mm256_castsi256_si128(rr);
  const __m128i out0 =
      _mm_or_si128(_mm_or_si128(Scatter<0, 0>(bb), Scatter<1, 0>(gg)), Scatter<2, 0>(r16));
  const __m128i out1 =
      _mm_or_si128(_mm_or_si128(Scatter<0, 1>(bb), Scatter<1, 1>(gg)), Scatter<2, 1>(r16));
  const __m128i out2 =
      _mm_or_si128(_mm_or_si128(Scatter<0, 2>(bb), Scatter<1, 2>(gg)), Scatter<2, 2>(r16));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(dst), out0);
  _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + 16), out1);
  _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + 32), out2);
}

// From 16-bit lanes C0 C1 C0' C1' ... (Cb, Cr interleaved, one pair per two pixels, within
// each 128-bit lane): Cb or Cr repeated for both pixels of its pair.
inline __m256i RepeatChroma(__m256i cbcr, int which) {
  const __m256i cb = _mm256_setr_epi8(0, 1, 0, 1, 4, 5, 4, 5, 8, 9, 8, 9, 12, 13, 12, 13, 0, 1, 0,
                                      1, 4, 5, 4, 5, 8, 9, 8, 9, 12, 13, 12, 13);
  const __m256i two = _mm256_set1_epi8(2);
  return _mm256_shuffle_epi8(cbcr, which == 0 ? cb : _mm256_add_epi8(cb, two));
}

}  // namespace

int YuyvRowToBgrAvx2(const uint8_t* src, int width, uint8_t* dst) {
  const int n = width / 16 * 16;
  const __m256i low_byte = _mm256_set1_epi16(0x00ff);
  for (int x = 0; x < n; x += 16) {
    // Y0 Cb Y1 Cr ...: each 128-bit lane holds 8 pixels with their 4 chroma pairs.
    const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(src + 2 * x));
    const __m256i y = _mm256_and_si256(v, low_byte);
    const __m256i cbcr = _mm256_srli_epi16(v, 8);
    SixteenPixels(y, RepeatChroma(cbcr, 0), RepeatChroma(cbcr, 1), dst + 3 * x);
  }
  return n;
}

int Nv12RowToBgrAvx2(const uint8_t* y, const uint8_t* uv, int width, uint8_t* dst) {
  const int n = width / 16 * 16;
  for (int x = 0; x < n; x += 16) {
    const __m256i yy =
        _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(y + x)));
    // 8 Cb Cr pairs for these 16 pixels: pairs 0-3 in the low lane (pixels 0-7), 4-7 high.
    const __m256i cbcr =
        _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(uv + x)));
    SixteenPixels(yy, RepeatChroma(cbcr, 0), RepeatChroma(cbcr, 1), dst + 3 * x);
  }
  return n;
}

}  // namespace sfrt::v4l2::detail
