// The AMX convolution, int8 (kernels/int8_job.h, tdpbusd) and bf16 (kernels/bf16_job.h,
// tdpbf16ps), written once over a tile-operation vocabulary `T`: the hardware's
// (kernels/avx512/conv2d_avx512amx.cc: ldtilecfg, tileloadd, tdpbusd/tdpbf16ps, tilestored) and a
// scalar emulation (src/amx_emulation.cc), so that the blocking and packing are tested on every
// CPU. The int8 path is bit for bit equal to ref::Conv2dInt8Rows (exact int32 sums, int8_job.h's
// epilogue); the bf16 path equals ref::Conv2dBf16Rows up to the order of the float32 sums.
//
// T provides Configure(const AmxTileConfig&), Release(), and, for tile numbers known at compile
// time, Load<t>(base, stride), Store<t>(base, stride), DpBusd<c, a, b>() (for each row m of c and
// 32-bit column n, c[m][n] += sum over k and i < 4 of the unsigned byte a[m][4k+i] times the
// signed byte b[k][4n+i]) and DpBf16ps<c, a, b>() (c[m][n] += sum over k and i < 2 of the bf16
// a[m][2k+i] times the bf16 b[k][2n+i], in float32).
//
// Blocking, on the packed layouts of the AVX-512 kernels (nr 64: weights [block][tap][group][64]
// [one 32-bit group: 4 int8 or 2 bf16]): one output-channel block of 64 is four C tiles (tmm0-3)
// of 16 pixels x 16 32-bit channels. For each tap and each chunk of up to 16 groups, the A tile
// (tmm4; tmm6 for a last, shorter chunk) holds 16 consecutive output pixels' inputs (rows
// sw * channels elements apart in the input: one tileloadd), and the B tile (tmm5; tmm7) one C
// tile's 16 channels of the chunk's groups: rows of 64 bytes at a stride of 256 in the packed
// weights, so the AVX-512 layouts serve AMX unchanged. The int8 C tiles start from
// -in_zero_point times the sum of every tap's tap_sums (a tileloadd with stride 0 repeats one
// row), the bf16 ones from zero. An output row's AMX pixels are the whole groups of 16 among the
// columns whose window lies inside the input, on rows whose window lies inside the input; every
// other pixel (the border, a row's last < 16 interior pixels) goes to `fallback` with a column
// range (Args::col_begin/col_end), as do whole convolutions with few outputs (int8 few_weights)
// and calls that ask for a column range themselves.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "kernels/bf16_job.h"
#include "kernels/int8_job.h"
#include "kernels/simd/conv_driver_inl.h"
#include "kernels/simd/dot_driver_inl.h"

namespace sfrt::simd {

// LDTILECFG's 64-byte operand (palette 1).
struct alignas(64) AmxTileConfig {
  uint8_t palette = 1;
  uint8_t start_row = 0;
  uint8_t reserved[14] = {};
  uint16_t colsb[16] = {};  // bytes per row of tile i
  uint8_t rows[16] = {};
};
static_assert(sizeof(AmxTileConfig) == 64, "LDTILECFG reads 64 bytes");

inline constexpr int kAmxRows = 16;      // palette 1: rows per tile
inline constexpr int kAmxRowBytes = 64;  // palette 1: bytes per row
inline constexpr int kAmxPixels = 16;    // output pixels per C tile (its rows)

// The tile shapes for `groups` groups of 4 input channels: C tiles 0-3 of 16 x 64 bytes; A (4)
// and B (5) for full chunks of min(16, groups) groups; A (6) and B (7) for a last chunk of
// groups % 16 when groups > 16 and that is not 0.
inline AmxTileConfig AmxConfigFor(int groups) {
  AmxTileConfig c;
  for (int t = 0; t < 4; ++t) {
    c.rows[t] = kAmxPixels;
    c.colsb[t] = kAmxRowBytes;
  }
  const int full = groups < kAmxRows ? groups : kAmxRows;
  c.rows[4] = kAmxPixels;
  c.colsb[4] = static_cast<uint16_t>(4 * full);
  c.rows[5] = static_cast<uint8_t>(full);
  c.colsb[5] = kAmxRowBytes;
  const int tail = groups > kAmxRows ? groups % kAmxRows : 0;
  if (tail > 0) {
    c.rows[6] = kAmxPixels;
    c.colsb[6] = static_cast<uint16_t>(4 * tail);
    c.rows[7] = static_cast<uint8_t>(tail);
    c.colsb[7] = kAmxRowBytes;
  }
  return c;
}

// One chunk's four products: A (16 pixels' inputs) with the four B tiles of the block's
// 64 channels (rows of 64 bytes, 256 apart in the packed weights). Quantized: tdpbusd; bf16:
// tdpbf16ps.
template <typename T, bool kQuantized, int A, int B>
inline void AmxChunk(const void* x, ptrdiff_t x_stride, const uint8_t* w) {
  T::template Load<A>(x, x_stride);
  auto dot = [](auto c) {
    constexpr int C = decltype(c)::value;
    if constexpr (kQuantized) {
      T::template DpBusd<C, A, B>();
    } else {
      T::template DpBf16ps<C, A, B>();
    }
  };
  T::template Load<B>(w, 256);
  dot(std::integral_constant<int, 0>{});
  T::template Load<B>(w + 64, 256);
  dot(std::integral_constant<int, 1>{});
  T::template Load<B>(w + 128, 256);
  dot(std::integral_constant<int, 2>{});
  T::template Load<B>(w + 192, 256);
  dot(std::integral_constant<int, 3>{});
}

// Rows [row_begin, row_end) of blocks [blk_begin, blk_end) of a plain int8 or bf16 convolution
// (Conv: PackedInt8Conv or PackedBf16Conv) packed with nr 64; `fallback` (same arguments)
// computes what the tiles do not.
template <typename T, typename Conv>
void AmxConvRows(const typename DotTraits<Conv>::Args& a, int row_begin, int row_end, int blk_begin,
                 int blk_end,
                 void (*fallback)(const typename DotTraits<Conv>::Args&, int, int, int, int)) {
  using Traits = DotTraits<Conv>;
  using Elem = typename Traits::Elem;
  constexpr bool kQuantized = Traits::kQuantized;
  const Conv& p = *a.conv;
  const int out_w = p.out_float ? a.out_f32.width : Traits::LowOut(a).width;
  // Calls for a column range (the kernels' contract) go to the fallback whole, as do the layers
  // the tiles leave.
  bool tiles = p.nr == 64 && !a.upsampled && a.col_begin <= 0 && a.col_end >= out_w;
  if constexpr (kQuantized) tiles = tiles && p.few_weights == nullptr;
  if (!tiles) {
    fallback(a, row_begin, row_end, blk_begin, blk_end);
    return;
  }
  const int taps = p.kernel_h * p.kernel_w;
  const int groups = Traits::Groups(p);
  const int full = groups < kAmxRows ? groups : kAmxRows;
  const int chunks = groups / full;  // chunks of `full` groups, then the tail (tiles 6 and 7)
  const int tail = groups - chunks * full;
  const ColumnRange inside = InsideColumns(out_w, a.in.width, p.kernel_w, p.stride_w, a.pads.left);
  const ptrdiff_t x_stride =
      static_cast<ptrdiff_t>(p.stride_w) * a.in.channels * static_cast<ptrdiff_t>(sizeof(Elem));
  const ptrdiff_t tap_bytes = static_cast<ptrdiff_t>(groups) * 4 * 64;
  const uint8_t* weights = reinterpret_cast<const uint8_t*>(p.weights);

  T::Configure(AmxConfigFor(groups));
  // The C tiles' start, 32-bit values: int8, -z * the sum of all taps' tap_sums (interior pixels
  // read every tap); bf16, 0.0f (whose bits are 0).
  alignas(64) int32_t init[64] = {};
  alignas(64) int32_t sums[4][kAmxPixels][16];
  for (int blk = blk_begin; blk < blk_end; ++blk) {
    if constexpr (kQuantized) {
      for (int o = 0; o < 64; ++o) {
        int32_t s = 0;
        for (int t = 0; t < taps; ++t) {
          s += p.tap_sums[(static_cast<ptrdiff_t>(blk) * taps + t) * 64 + o];
        }
        init[o] = -p.in_zero_point * s;
      }
    }
    const uint8_t* wblk = weights + static_cast<ptrdiff_t>(blk) * taps * tap_bytes;
    const int valid = MinOf(64, p.out_channels - blk * 64);
    for (int oy = row_begin; oy < row_end; ++oy) {
      const int iy0 = oy * p.stride_h - a.pads.top;
      const bool rows_inside = iy0 >= 0 && iy0 + p.kernel_h <= a.in.height;
      const int n16 =
          rows_inside && inside.hi > inside.lo ? (inside.hi - inside.lo) / kAmxPixels : 0;
      const int amx_lo = inside.lo, amx_hi = inside.lo + n16 * kAmxPixels;
      typename Traits::Args rest = a;
      if (n16 == 0) {
        fallback(rest, oy, oy + 1, blk, blk + 1);
        continue;
      }
      if (amx_lo > 0) {
        rest.col_begin = 0;
        rest.col_end = amx_lo;
        fallback(rest, oy, oy + 1, blk, blk + 1);
      }
      if (amx_hi < out_w) {
        rest.col_begin = amx_hi;
        rest.col_end = out_w;
        fallback(rest, oy, oy + 1, blk, blk + 1);
      }
      for (int ox0 = amx_lo; ox0 < amx_hi; ox0 += kAmxPixels) {
        T::template Load<0>(init, 0);
        T::template Load<1>(init + 16, 0);
        T::template Load<2>(init + 32, 0);
        T::template Load<3>(init + 48, 0);
        const int ix0 = ox0 * p.stride_w - a.pads.left;
        for (int ky = 0; ky < p.kernel_h; ++ky) {
          for (int kx = 0; kx < p.kernel_w; ++kx) {
            // The pixel's bytes: `full` groups of 4 bytes per chunk.
            const uint8_t* x = reinterpret_cast<const uint8_t*>(a.in.pixel(iy0 + ky, ix0 + kx));
            const uint8_t* w = wblk + (ky * p.kernel_w + kx) * tap_bytes;
            for (int c = 0; c < chunks; ++c) {
              AmxChunk<T, kQuantized, 4, 5>(x + 4 * full * c, x_stride,
                                            w + static_cast<ptrdiff_t>(full) * c * 256);
            }
            if (tail > 0) {
              AmxChunk<T, kQuantized, 6, 7>(x + 4 * full * chunks, x_stride,
                                            w + static_cast<ptrdiff_t>(full) * chunks * 256);
            }
          }
        }
        T::template Store<0>(sums[0], 64);
        T::template Store<1>(sums[1], 64);
        T::template Store<2>(sums[2], 64);
        T::template Store<3>(sums[3], 64);
        for (int m = 0; m < kAmxPixels; ++m) {
          for (int o = 0; o < valid; ++o) {
            const int c = blk * 64 + o;
            const int32_t sum = sums[o / 16][m][o % 16];
            float y;
            if constexpr (kQuantized) {
              y = Int8Dequantize(sum, p.multiplier[c], p.bias[c], p.activation, p.leaky_slope);
            } else {
              float acc;
              std::memcpy(&acc, &sum, sizeof(acc));
              y = Bf16Epilogue(acc, p.bias[c], p.activation, p.leaky_slope);
            }
            if (p.out_float) {
              a.out_f32.pixel(oy, ox0 + m)[c] = y;
            } else if constexpr (kQuantized) {
              a.out_u8.pixel(oy, ox0 + m)[c] = Int8Quantize(y, p.out_inv_scale, p.out_zero_point);
            } else {
              a.out_bf16.pixel(oy, ox0 + m)[c] = FloatToBf16(y);
            }
          }
        }
      }
    }
  }
  T::Release();
}

}  // namespace sfrt::simd
