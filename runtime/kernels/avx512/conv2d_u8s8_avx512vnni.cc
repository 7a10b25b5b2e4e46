// AVX-512 VNNI int8 convolution kernels (compiled with -mavx512f -mavx512bw -mavx512vl -mavx512dq
// -mavx512vnni -ffp-contract=off only in this translation unit; runtime/CMakeLists.txt), bit for
// bit equal to ref::Conv2dInt8Rows: the arithmetic is kernels/int8_job.h's. The loops are
// kernels/simd/dot_driver_inl.h's; this file has the vocabulary V, the tiles and the few-output
// kernel.
//
// Blocks of 64 output channels (PackInt8Conv with nr 64). Register tiles: MR output pixels x NV
// vectors of 16 int32 channels: 6x4 (24 accumulators, 4 weight vectors, one broadcast), 8x3, 8x2
// and 8x1. Per tap and group of 4 input channels, each pixel's 4 bytes are broadcast and vpdpbusd
// adds their products with the weight vectors (u8 x s8, exact int32). The zero point:
// sum (x - z) * w = sum x * w - z * sum w, so the accumulators start from -z * the tap_sums.
#include <immintrin.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "kernels/avx512/dot_epilogue_avx512_inl.h"
#include "kernels/avx512/few_out_avx512_inl.h"
#include "kernels/int8_job.h"
#include "kernels/simd/dot_driver_inl.h"
#include "src/cpu_features.h"

namespace sfrt::avx512 {
namespace {

// Four input channels of one pixel in every 32-bit lane.
inline __m512i Broadcast4(const uint8_t* p) {
  int32_t v;
  std::memcpy(&v, p, sizeof(v));
  return _mm512_set1_epi32(v);
}

// The int8 vocabulary of kernels/simd/dot_driver_inl.h.
struct V {
  using Conv = PackedInt8Conv;
  using Acc = __m512i;
  static constexpr int kLanes = 16;
  static constexpr int kNr = 64;  // output channels per block
  static Acc Zero() { return _mm512_setzero_si512(); }
  static Acc Load(const int32_t* p) { return _mm512_loadu_si512(p); }
  static Acc Add(Acc a, Acc b) { return _mm512_add_epi32(a, b); }
  static Acc MulScalar(Acc a, int32_t c) { return _mm512_mullo_epi32(a, _mm512_set1_epi32(c)); }
  static int32_t ZeroPointCoefficient(int zero_point) { return -zero_point; }

  // The sums of MR pixels x NV vectors (dot_driver_inl.h). Its own function: inlined into the
  // epilogue's, GCC 12 spills and copies the accumulators inside the loop.
  template <int MR, int NV>
  [[gnu::noinline]] static void Accumulate(const uint8_t* const* xs, const int8_t* const* ws,
                                           int taps, int groups, const Acc* init, Acc* sums) {
    Acc acc[MR][NV];
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) acc[m][v] = init[v];
    }
    for (int t = 0; t < taps; ++t) {
      const uint8_t* x[MR];
#pragma GCC unroll 16
      for (int m = 0; m < MR; ++m) x[m] = xs[t * MR + m];
      const int8_t* w = ws[t];
      for (int g = 0; g < groups; ++g) {
        Acc wv[NV];
#pragma GCC unroll 4
        for (int v = 0; v < NV; ++v) wv[v] = _mm512_loadu_si512(w + v * 4 * kLanes);
        w += 4 * kNr;
#pragma GCC unroll 16
        for (int m = 0; m < MR; ++m) {
          const Acc b = Broadcast4(x[m] + 4 * g);
#pragma GCC unroll 4
          for (int v = 0; v < NV; ++v) acc[m][v] = _mm512_dpbusd_epi32(acc[m][v], b, wv[v]);
        }
      }
    }
#pragma GCC unroll 16
    for (int m = 0; m < MR; ++m) {
#pragma GCC unroll 4
      for (int v = 0; v < NV; ++v) sums[m * NV + v] = acc[m][v];
    }
  }

  // Lane-wise Int8Dequantize / Int8Quantize of one pixel's NV vectors into `out` (the pixel's
  // first channel of the block: float or uint8).
  template <int NV>
  static void Finish(const Acc* acc, const simd::DotEpilogue& e, void* out) {
    FinishU8s8<NV>(acc, e, out);
  }
};

// The int8 precision of kernels/avx512/few_out_avx512_inl.h: u8 x s8 products by vpdpbusd,
// exact int32 sums, the zero point's correction, int8_job.h's epilogue.
struct FewOutU8s8 {
  using Conv = PackedInt8Conv;
  using Args = Int8ConvArgs;
  using Elem = uint8_t;
  using Weight = int8_t;
  using Acc = __m512i;
  using In = __m512i;
  static constexpr int kPerLoad = 64;
  static int OutWidth(const Args& a) {
    return a.conv->out_float ? a.out_f32.width : a.out_u8.width;
  }
  static Acc Zero() { return _mm512_setzero_si512(); }
  static In LoadX(const uint8_t* x, int left) {
    const __mmask64 m = left >= 64 ? ~__mmask64{0} : (__mmask64{1} << left) - 1;
    return _mm512_maskz_loadu_epi8(m, x);
  }
  static In LoadW(const int8_t* w) { return _mm512_loadu_si512(w); }
  static Acc Dot(Acc acc, In x, In w) { return _mm512_dpbusd_epi32(acc, x, w); }
  template <int K>
  static Acc SumEachVector(const Acc* v) {
    return SumEachVectorBits<K>(v, [](__m512i x, __m512i y) { return _mm512_add_epi32(x, y); });
  }

  // One pixel: the zero-point correction of the taps inside, the scalar epilogue.
  static void FinishPixel(const Args& a, int oy, int ox, const Acc* acc, const InsideTaps& in) {
    const Conv& p = *a.conv;
    for (int o = 0; o < p.out_channels; ++o) {
      int32_t zsum = 0;
      for (int ky = in.ky0; ky < in.ky1; ++ky) {
        for (int kx = in.kx0; kx < in.kx1; ++kx) {
          zsum += p.tap_sums[(ky * p.kernel_w + kx) * p.nr + o];
        }
      }
      alignas(64) int32_t lanes[V::kLanes];
      _mm512_store_si512(lanes, acc[o]);
      int32_t sum = -p.in_zero_point * zsum;
      for (int l = 0; l < V::kLanes; ++l) sum += lanes[l];
      const float y = Int8Dequantize(sum, p.multiplier[o], p.bias[o], p.activation, p.leaky_slope);
      if (p.out_float) {
        a.out_f32.pixel(oy, ox)[o] = y;
      } else {
        a.out_u8.pixel(oy, ox)[o] = Int8Quantize(y, p.out_inv_scale, p.out_zero_point);
      }
    }
  }

  // A tile's values: value i is channel i % CO.
  struct Values {
    alignas(64) float multiplier[kFewOutValues] = {};
    alignas(64) float bias[kFewOutValues] = {};
    alignas(64) int32_t zero_fix[kFewOutValues] = {};  // -z * the sum of every tap's tap_sums
    simd::DotEpilogue e{};
  };
  static void Prepare(const Conv& p, Values& q) {
    const int taps = p.kernel_h * p.kernel_w;
    for (int i = 0; i < kFewOutValues; ++i) {
      const int o = i % p.out_channels;
      q.multiplier[i] = p.multiplier[o];
      q.bias[i] = p.bias[o];
      int32_t zsum = 0;
      for (int t = 0; t < taps; ++t) zsum += p.tap_sums[t * p.nr + o];
      q.zero_fix[i] = -p.in_zero_point * zsum;
    }
    q.e = {q.multiplier, q.bias,          p.activation,     p.leaky_slope,
           p.out_float,  p.out_inv_scale, p.out_zero_point, kFewOutValues};
  }
  template <int CO>
  static void FinishValues(const Args& a, int oy, int ox, int chunk, int count, Acc sums,
                           const Values& q) {
    const __m512i fixed = _mm512_add_epi32(sums, _mm512_load_si512(q.zero_fix + 16 * chunk));
    const __m512 y = DequantizeLanes(fixed, q.e, chunk);
    if (a.conv->out_float) {
      StoreValues<CO>(a.out_f32.pixel(oy, ox), a.out_f32.channels, chunk, count,
                      [y](float* d, __mmask16 m) { _mm512_mask_storeu_ps(d, m, y); });
      return;
    }
    const __m512i bytes = QuantizeLanes(y, q.e);
    StoreValues<CO>(
        a.out_u8.pixel(oy, ox), a.out_u8.stride(), chunk, count,
        [bytes](uint8_t* d, __mmask16 m) { _mm512_mask_cvtepi32_storeu_epi8(d, m, bytes); });
  }
};

static_assert(kInt8FewOutChannels <= kFewOutMaxChannels);

// The tiles' pixels for 1, 2, 3 and 4 valid vectors: 8x1, 8x2, 8x3, 6x4.
void TileRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  simd::DotConvRows<V, 8, 8, 8, 6>(a, row_begin, row_end, blk_begin, blk_end);
}

// Narrow convolutions (PackedInt8Conv::narrow: at most 4 inputs, so one group of 4 bytes per
// pixel, and at most 4 outputs): a tile would use 4 of its 64 lanes, so these are vectorised
// over 16 output pixels instead: per tap and output channel, one vpdpbusd of the 16 pixels' 4
// bytes (one load where they are adjacent, else a gather) with the channel's 4 weights
// broadcast. Where a row's windows lie inside the input, 16 pixels at a time; the rest through
// the tiles on column ranges.
struct NarrowPlan {
  int32_t weights[kMaxInt8Taps][4] = {};  // [tap][output]: its 4 int8 weights
  int32_t init[4] = {};                   // -z * the sum of every tap's tap_sums
  alignas(64) float multiplier[4][16] = {};
  alignas(64) float bias[4][16] = {};
  simd::DotEpilogue e[4] = {};
};

void PrepareNarrow(const PackedInt8Conv& p, NarrowPlan& plan) {
  const int taps = p.kernel_h * p.kernel_w;
  for (int o = 0; o < p.out_channels; ++o) {
    int32_t zsum = 0;
    for (int t = 0; t < taps; ++t) {
      // weights[block 0][tap][group 0][nr][4]
      std::memcpy(&plan.weights[t][o], p.weights + (static_cast<size_t>(t) * p.nr + o) * 4, 4);
      zsum += p.tap_sums[t * p.nr + o];
    }
    plan.init[o] = -p.in_zero_point * zsum;
    for (int l = 0; l < 16; ++l) {
      plan.multiplier[o][l] = p.multiplier[o];
      plan.bias[o][l] = p.bias[o];
    }
    plan.e[o] = {plan.multiplier[o], plan.bias[o],    p.activation,     p.leaky_slope,
                 p.out_float,        p.out_inv_scale, p.out_zero_point, 16};
  }
}

// Pixels ox .. ox + 15 of row oy, every tap inside the input; CO output channels.
template <int CO>
void NarrowBlock(const Int8ConvArgs& a, int oy, int ox, const NarrowPlan& plan, __m512i offsets) {
  const PackedInt8Conv& p = *a.conv;
  const bool adjacent = p.stride_w == 1 && a.in.stride() == 4;
  const int iy0 = oy * p.stride_h - a.pads.top;
  const int ix0 = ox * p.stride_w - a.pads.left;
  __m512i acc[CO];
#pragma GCC unroll 4
  for (int o = 0; o < CO; ++o) acc[o] = _mm512_set1_epi32(plan.init[o]);
  for (int ky = 0; ky < p.kernel_h; ++ky) {
    for (int kx = 0; kx < p.kernel_w; ++kx) {
      const uint8_t* x = a.in.pixel(iy0 + ky, ix0 + kx);
      const __m512i xv =
          adjacent ? _mm512_loadu_si512(x)
                   : _mm512_mask_i32gather_epi32(_mm512_setzero_si512(), kAll, offsets, x, 1);
      const int32_t* w = plan.weights[ky * p.kernel_w + kx];
#pragma GCC unroll 4
      for (int o = 0; o < CO; ++o)
        acc[o] = _mm512_dpbusd_epi32(acc[o], xv, _mm512_set1_epi32(w[o]));
    }
  }
  alignas(64) float y[CO][16];
  alignas(64) int32_t q[CO][16];
#pragma GCC unroll 4
  for (int o = 0; o < CO; ++o) {
    const __m512 v = DequantizeLanes(acc[o], plan.e[o], 0);
    if (p.out_float) {
      _mm512_store_ps(y[o], v);
    } else {
      _mm512_store_si512(q[o], QuantizeLanes(v, plan.e[o]));
    }
  }
  for (int j = 0; j < 16; ++j) {
    if (p.out_float) {
      float* out = a.out_f32.pixel(oy, ox + j);
      for (int o = 0; o < CO; ++o) out[o] = y[o][j];
    } else {
      uint8_t* out = a.out_u8.pixel(oy, ox + j);
      for (int o = 0; o < CO; ++o) out[o] = static_cast<uint8_t>(q[o][j]);
    }
  }
}

// Columns [x_begin, x_end) of row oy through the tiles.
void NarrowByTiles(const Int8ConvArgs& a, int oy, int x_begin, int x_end) {
  if (x_begin >= x_end) return;
  Int8ConvArgs part = a;
  part.col_begin = x_begin;
  part.col_end = x_end;
  TileRows(part, oy, oy + 1, 0, 1);
}

template <int CO>
void NarrowRowsOf(const Int8ConvArgs& a, int row_begin, int row_end) {
  const PackedInt8Conv& p = *a.conv;
  const int out_w = p.out_float ? a.out_f32.width : a.out_u8.width;
  const int x_begin = simd::MaxOf(0, a.col_begin), x_end = simd::MinOf(out_w, a.col_end);
  const simd::ColumnRange inside =
      simd::InsideColumns(out_w, a.in.width, p.kernel_w, p.stride_w, a.pads.left);
  const int start = simd::MinOf(simd::MaxOf(x_begin, inside.lo), x_end);
  const int block_end = simd::MinOf(inside.hi, x_end);
  NarrowPlan plan;
  PrepareNarrow(p, plan);
  const __m512i offsets =
      _mm512_mullo_epi32(_mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15),
                         _mm512_set1_epi32(static_cast<int32_t>(p.stride_w * a.in.stride())));
  for (int oy = row_begin; oy < row_end; ++oy) {
    const int iy0 = oy * p.stride_h - a.pads.top;
    if (iy0 < 0 || iy0 + p.kernel_h > a.in.height) {
      NarrowByTiles(a, oy, x_begin, x_end);
      continue;
    }
    NarrowByTiles(a, oy, x_begin, start);
    int ox = start;
    for (; ox + 16 <= block_end; ox += 16) NarrowBlock<CO>(a, oy, ox, plan, offsets);
    NarrowByTiles(a, oy, ox, x_end);
  }
}

void NarrowRows(const Int8ConvArgs& a, int row_begin, int row_end) {
  switch (a.conv->out_channels) {
    case 1:
      NarrowRowsOf<1>(a, row_begin, row_end);
      break;
    case 2:
      NarrowRowsOf<2>(a, row_begin, row_end);
      break;
    case 3:
      NarrowRowsOf<3>(a, row_begin, row_end);
      break;
    default:
      NarrowRowsOf<4>(a, row_begin, row_end);
      break;
  }
}

void ConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  const PackedInt8Conv& p = *a.conv;
  if (p.few_weights != nullptr || p.narrow) {
    if (blk_begin > 0 || blk_end <= 0) return;  // one block
    if (p.few_weights != nullptr) {
      FewOutRows<FewOutU8s8>(a, row_begin, row_end);
    } else {
      NarrowRows(a, row_begin, row_end);
    }
    return;
  }
  TileRows(a, row_begin, row_end, blk_begin, blk_end);
}

}  // namespace

const IsaInt8Kernels* Int8Kernels() {
  static constexpr IsaInt8Kernels kKernels = {V::kNr,
                                              ConvRows,
                                              simd::DotUpConvRows<V, 8, 8, 8, 6>,
                                              "conv2d_u8s8__avx512vnni_6x64",
                                              "upconv2d_u8s8__avx512vnni_6x64",
                                              "conv2d_fewout_u8s8__avx512vnni_8x3",
                                              "conv2d_narrow_u8s8__avx512vnni_16x4"};
  const CpuFeatures& f = HostCpuFeatures();
  return f.avx512 && f.avx512_vnni ? &kKernels : nullptr;
}

}  // namespace sfrt::avx512
