// The AMX convolution, int8 (kernels/int8_job.h, tdpbusd) and bf16 (kernels/bf16_job.h,
// tdpbf16ps), written once over a tile-operation vocabulary `T`: the hardware's
// (kernels/avx512/conv2d_avx512amx.cc: ldtilecfg, tileloadd, tdpbusd/tdpbf16ps, tilestored) and a
// scalar emulation (src/amx_emulation.cc), so that the blocking and packing are tested on every
// CPU. The int8 path is bit for bit equal to ref::Conv2dInt8Rows (exact int32 sums, int8_job.h's
// epilogue); the bf16 path equals ref::Conv2dBf16Rows up to the order of the float32 sums.
//
// T provides Configure(const AmxTileConfig&), Release(), and, for tile numbers known at compile
// time, Zero<t>(), Load<t>(base, stride), Store<t>(base, stride), DpBusd<c, a, b>() (for each row m
// of c and 32-bit column n, c[m][n] += sum over k and i < 4 of the unsigned byte a[m][4k+i] times
// the signed byte b[k][4n+i]) and DpBf16ps<c, a, b>() (c[m][n] += sum over k and i < 2 of the bf16
// a[m][2k+i] times the bf16 b[k][2n+i], in float32); and Finish<kQuantized>(sums, init, epilogue,
// out, out_step), the epilogue of one stored 16 x 64 tile (AmxFinishScalar's arithmetic).
//
// Blocking, on the packed layouts of the AVX-512 kernels (nr 64: weights [block][tap][group][64]
// [one 32-bit group: 4 int8 or 2 bf16]): one output-channel block of 64 is four C tiles (tmm0-3)
// of 16 pixels x 16 32-bit channels. For each tap and each chunk of up to 16 groups, the A tile
// (tmm4; tmm6 for a last, shorter chunk) holds 16 output pixels' inputs (rows a fixed number of
// bytes apart in the input: one tileloadd), and the B tile (tmm5; tmm7) one C tile's 16 channels
// of the chunk's groups: rows of 64 bytes at a stride of 256 in the packed weights, so the
// AVX-512 layouts serve AMX unchanged; only the C tiles (and B tiles) of channels the block has
// are used. The C tiles start from zero; the int8 epilogue adds -in_zero_point times the sum of
// the taps' tap_sums.
//
// Plain convolutions: 16 consecutive output pixels of a row, their inputs sw pixels apart, one
// tap after the other. The fused upsample -> 3x3 convolution (a.upsampled, with phase kernels):
// per column phase, 16 of every second output pixel, whose inputs are consecutive pixels of the
// low-resolution map, over the phase's 2x2 kernel (4 taps; dot_driver_inl.h's DotPhaseRow). The
// tiles take every pixel of a row whose window lies inside the map (the row's last tile may
// overlap the one before it), on rows whose window lies inside the map, where the row has at
// least 16 such pixels (per phase); every other pixel goes to `fallback` with a column range
// (Args::col_begin/col_end), and whole calls go to it where the tiles would do little: fewer
// than 16 groups of input channels, a fused upsample without phase kernels, calls that ask for a
// column range themselves.
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

// One chunk's products: A (16 pixels' inputs) with the first NT B tiles of the block's 64
// channels (rows of 64 bytes, 256 apart in the packed weights), NT being the C tiles that hold
// valid channels. Quantized: tdpbusd; bf16: tdpbf16ps.
template <typename T, bool kQuantized, int NT, int A, int B>
inline void AmxChunk(const void* x, ptrdiff_t x_stride, const uint8_t* w) {
  T::template Load<A>(x, x_stride);
  auto dot = [&](auto c) {
    constexpr int C = decltype(c)::value;
    if constexpr (C < NT) {
      T::template Load<B>(w + 64 * C, 256);
      if constexpr (kQuantized) {
        T::template DpBusd<C, A, B>();
      } else {
        T::template DpBf16ps<C, A, B>();
      }
    }
  };
  dot(std::integral_constant<int, 0>{});
  dot(std::integral_constant<int, 1>{});
  dot(std::integral_constant<int, 2>{});
  dot(std::integral_constant<int, 3>{});
}

// The scalar epilogue of a 16-pixel x 64-channel tile, sums[c][m][n] being pixel m's channel
// 16c + n (int32, or the bits of a float32 for bf16; the C tiles holding e.valid channels):
// int8, init[o] (the zero-point correction) added, then int8_job.h's Int8Dequantize and
// Int8Quantize; bf16, bf16_job.h's Bf16Epilogue and FloatToBf16. Pixel m goes to
// out + m * out_step. The emulated tiles' Finish; the hardware's is the same arithmetic in zmm
// registers.
template <bool kQuantized>
inline void AmxFinishScalar(const int32_t* sums, const int32_t* init, const DotEpilogue& e,
                            void* out, ptrdiff_t out_step) {
  for (int m = 0; m < kAmxPixels; ++m) {
    char* pixel = static_cast<char*>(out) + m * out_step;
    for (int o = 0; o < e.valid; ++o) {
      const int32_t sum = sums[(o / 16) * kAmxPixels * 16 + m * 16 + o % 16];
      float y;
      if constexpr (kQuantized) {
        y = Int8Dequantize(sum + init[o], e.multiplier[o], e.bias[o], e.act, e.slope);
      } else {
        float acc;
        std::memcpy(&acc, &sum, sizeof(acc));
        y = Bf16Epilogue(acc, e.bias[o], e.act, e.slope);
      }
      if (e.out_float) {
        reinterpret_cast<float*>(pixel)[o] = y;
      } else if constexpr (kQuantized) {
        reinterpret_cast<uint8_t*>(pixel)[o] = Int8Quantize(y, e.inv_scale, e.zero_point);
      } else {
        reinterpret_cast<uint16_t*>(pixel)[o] = FloatToBf16(y);
      }
    }
  }
}

// What every tile of one call shares.
template <typename Conv>
struct AmxJob {
  using Traits = DotTraits<Conv>;
  const typename Traits::Args* a = nullptr;
  int full = 0;    // groups per chunk (tiles 4 and 5)
  int chunks = 0;  // chunks of `full` groups, then the tail (tiles 6 and 7)
  int tail = 0;
  ptrdiff_t tap_bytes = 0;  // packed weights of one tap of one block
  ptrdiff_t out_pixel = 0;  // bytes between output pixels

  void* Out(int oy, int ox, int blk) const {
    if (a->conv->out_float) return a->out_f32.pixel(oy, ox) + blk * 64;
    return Traits::LowOut(*a).pixel(oy, ox) + blk * 64;
  }
};

// 16 output pixels x the e.valid channels of one block (NT C tiles) over `taps` taps: xs[t] the
// first pixel's input at tap t (the others x_stride bytes apart), ws[t] the tap's packed weights;
// the C tiles start from zero (a tilezero: loading a start would cost a tile load each), and
// T's epilogue adds init (int8's zero-point correction) and writes out + m * out_step.
template <typename T, typename Conv, int NT>
inline void AmxTile(const AmxJob<Conv>& j, const uint8_t* const* xs, ptrdiff_t x_stride,
                    const uint8_t* const* ws, int taps, const int32_t* init, const DotEpilogue& e,
                    void* out, ptrdiff_t out_step) {
  constexpr bool kQuantized = DotTraits<Conv>::kQuantized;
  alignas(64) int32_t sums[4 * kAmxPixels * 16];
  auto each_c = [&](auto op) {
    op(std::integral_constant<int, 0>{});
    if constexpr (NT > 1) op(std::integral_constant<int, 1>{});
    if constexpr (NT > 2) op(std::integral_constant<int, 2>{});
    if constexpr (NT > 3) op(std::integral_constant<int, 3>{});
  };
  each_c([](auto c) { T::template Zero<decltype(c)::value>(); });
  for (int t = 0; t < taps; ++t) {
    const uint8_t* x = xs[t];
    const uint8_t* w = ws[t];
    for (int c = 0; c < j.chunks; ++c) {
      AmxChunk<T, kQuantized, NT, 4, 5>(x + 4 * j.full * c, x_stride,
                                        w + static_cast<ptrdiff_t>(j.full) * c * 256);
    }
    if (j.tail > 0) {
      AmxChunk<T, kQuantized, NT, 6, 7>(x + 4 * j.full * j.chunks, x_stride,
                                        w + static_cast<ptrdiff_t>(j.full) * j.chunks * 256);
    }
  }
  each_c([&](auto c) {
    constexpr int C = decltype(c)::value;
    T::template Store<C>(sums + C * kAmxPixels * 16, 64);
  });
  T::template Finish<kQuantized>(sums, init, e, out, out_step);
}

// AmxTile for the block's number of C tiles with valid channels, nt in [1, 4].
template <typename T, typename Conv>
inline void AmxTileFor(int nt, const AmxJob<Conv>& j, const uint8_t* const* xs, ptrdiff_t x_stride,
                       const uint8_t* const* ws, int taps, const int32_t* init,
                       const DotEpilogue& e, void* out, ptrdiff_t out_step) {
  switch (nt) {
    case 1:
      return AmxTile<T, Conv, 1>(j, xs, x_stride, ws, taps, init, e, out, out_step);
    case 2:
      return AmxTile<T, Conv, 2>(j, xs, x_stride, ws, taps, init, e, out, out_step);
    case 3:
      return AmxTile<T, Conv, 3>(j, xs, x_stride, ws, taps, init, e, out, out_step);
    default:
      return AmxTile<T, Conv, 4>(j, xs, x_stride, ws, taps, init, e, out, out_step);
  }
}

// The first columns of the 16-pixel tiles that cover n >= 16 pixels: 0, 16, ..., and a last one
// at n - 16 that may overlap the one before it (those pixels are computed again, to the same
// bits: each pixel's sums do not depend on its place in the tile).
inline int AmxTileStart(int tile, int n) {
  const int start = tile * kAmxPixels;
  return start + kAmxPixels <= n ? start : n - kAmxPixels;
}
inline int AmxTileCount(int n) { return (n + kAmxPixels - 1) / kAmxPixels; }

// What the epilogue adds to a channel block's sums: int8, -z * the sum of the given taps' tap_sums
// (interior pixels read every tap); bf16, nothing (zeros, unread).
template <typename Conv>
inline void AmxInit(const Conv& p, const int32_t* tap_sums, int taps, int32_t* init) {
  if constexpr (DotTraits<Conv>::kQuantized) {
    for (int o = 0; o < 64; ++o) {
      int32_t s = 0;
      for (int t = 0; t < taps; ++t) s += tap_sums[t * 64 + o];
      init[o] = -p.in_zero_point * s;
    }
  } else {
    (void)p;
    (void)tap_sums;
    (void)taps;
    for (int o = 0; o < 64; ++o) init[o] = 0;
  }
}

// The block's epilogue fields: dot_driver_inl.h's BlockEpilogue for nr 64.
template <typename C>
struct AmxBlocks {
  using Conv = C;
  static constexpr int kNr = 64;
};

// Rows [row_begin, row_end) of blocks [blk_begin, blk_end) of an int8 or bf16 convolution
// (Conv: PackedInt8Conv or PackedBf16Conv) packed with nr 64, plain or (a.upsampled) the fused
// upsample's through its phase kernels; `fallback` (same arguments) computes what the tiles do
// not: rows whose window leaves the input, the border columns, rows with fewer than 16 interior
// pixels (per column phase when upsampled), and the layers the tiles leave whole.
template <typename T, typename Conv>
void AmxConvRows(const typename DotTraits<Conv>::Args& a, int row_begin, int row_end, int blk_begin,
                 int blk_end,
                 void (*fallback)(const typename DotTraits<Conv>::Args&, int, int, int, int)) {
  using Traits = DotTraits<Conv>;
  using Elem = typename Traits::Elem;
  const Conv& p = *a.conv;
  const int out_w = p.out_float ? a.out_f32.width : Traits::LowOut(a).width;
  const int groups = Traits::Groups(p);
  // Calls for a column range go to the fallback whole, as do the layers the tiles leave: few
  // input channels (under 16 groups a tile product does less than a quarter of its work, and
  // the epilogue per tile outweighs it), the upsample without phase kernels. Few output
  // channels are fine: only the C tiles with valid channels are computed.
  bool tiles = p.nr == 64 && groups >= 16 && p.kernel_h * p.kernel_w <= kMaxInt8Taps &&
               a.col_begin <= 0 && a.col_end >= out_w;
  if (a.upsampled) {
    tiles = tiles && p.phase_weights != nullptr && p.kernel_h == 3 && p.kernel_w == 3 &&
            p.stride_h == 1 && p.stride_w == 1;
  }
  if (!tiles) {
    fallback(a, row_begin, row_end, blk_begin, blk_end);
    return;
  }
  AmxJob<Conv> j;
  j.a = &a;
  j.full = groups < kAmxRows ? groups : kAmxRows;
  j.chunks = groups / j.full;
  j.tail = groups - j.chunks * j.full;
  j.tap_bytes = static_cast<ptrdiff_t>(groups) * 4 * 64;
  j.out_pixel = p.out_float ? static_cast<ptrdiff_t>(a.out_f32.channels) * sizeof(float)
                            : Traits::LowOut(a).stride() * static_cast<ptrdiff_t>(sizeof(Elem));
  const ptrdiff_t in_pixel = a.in.stride() * static_cast<ptrdiff_t>(sizeof(Elem));
  // The map the convolution reads (C when upsampled) and its interior columns.
  const int src_h = a.upsampled ? a.c_height : a.in.height;
  const int src_w = a.upsampled ? a.c_width : a.in.width;
  const ColumnRange inside = InsideColumns(out_w, src_w, p.kernel_w, p.stride_w, a.pads.left);
  const int interior = inside.hi > inside.lo ? inside.hi - inside.lo : 0;
  // Upsampled: each column phase has about half the interior; both need 16.
  const bool wide = a.upsampled ? interior >= 2 * kAmxPixels + 1 : interior >= kAmxPixels;
  const int taps = a.upsampled ? 4 : p.kernel_h * p.kernel_w;
  const uint8_t* weights =
      reinterpret_cast<const uint8_t*>(a.upsampled ? p.phase_weights : p.weights);
  const ptrdiff_t phase_bytes = static_cast<ptrdiff_t>(p.blocks) * 4 * j.tap_bytes;

  T::Configure(AmxConfigFor(groups));
  alignas(64) int32_t init[64];
  alignas(64) int32_t phase_init[4][64];
  const uint8_t* xs[kMaxInt8Taps];
  const uint8_t* ws[kMaxInt8Taps];
  for (int blk = blk_begin; blk < blk_end; ++blk) {
    const DotEpilogue e = BlockEpilogue<AmxBlocks<Conv>>(p, blk);
    const int nt = (e.valid + 15) / 16;
    DotEpilogue phase_e[4] = {e, e, e, e};
    if (a.upsampled) {
      for (int ph = 0; ph < 4; ++ph) {
        const int32_t* sums = nullptr;
        if constexpr (Traits::kQuantized) {
          sums = p.phase_tap_sums + (static_cast<ptrdiff_t>(ph) * p.blocks + blk) * 4 * 64;
          phase_e[ph].multiplier = p.phase_multiplier + (ph * p.blocks + blk) * 64;
        }
        AmxInit(p, sums, 4, phase_init[ph]);
      }
    } else {
      const int32_t* sums = nullptr;
      if constexpr (Traits::kQuantized) {
        sums = p.tap_sums + static_cast<ptrdiff_t>(blk) * taps * 64;
      }
      AmxInit(p, sums, taps, init);
    }
    for (int oy = row_begin; oy < row_end; ++oy) {
      const int iy0 = oy * (a.upsampled ? 1 : p.stride_h) - a.pads.top;
      const bool rows_inside = iy0 >= 0 && iy0 + p.kernel_h <= src_h;
      typename Traits::Args rest = a;
      if (!rows_inside || !wide) {
        fallback(rest, oy, oy + 1, blk, blk + 1);
        continue;
      }
      if (inside.lo > 0) {
        rest.col_begin = 0;
        rest.col_end = inside.lo;
        fallback(rest, oy, oy + 1, blk, blk + 1);
      }
      if (inside.hi < out_w) {
        rest.col_begin = inside.hi;
        rest.col_end = out_w;
        fallback(rest, oy, oy + 1, blk, blk + 1);
      }
      if (!a.upsampled) {
        const uint8_t* wblk = weights + static_cast<ptrdiff_t>(blk) * taps * j.tap_bytes;
        for (int t = 0; t < taps; ++t) ws[t] = wblk + t * j.tap_bytes;
        const ptrdiff_t x_stride = static_cast<ptrdiff_t>(p.stride_w) * in_pixel;
        for (int i = 0; i < AmxTileCount(interior); ++i) {
          const int ox0 = inside.lo + AmxTileStart(i, interior);
          const int ix0 = ox0 * p.stride_w - a.pads.left;
          for (int ky = 0; ky < p.kernel_h; ++ky) {
            for (int kx = 0; kx < p.kernel_w; ++kx) {
              xs[ky * p.kernel_w + kx] =
                  reinterpret_cast<const uint8_t*>(a.in.pixel(iy0 + ky, ix0 + kx));
            }
          }
          AmxTileFor<T>(nt, j, xs, x_stride, ws, taps, init, e, j.Out(oy, ox0, blk), j.out_pixel);
        }
        continue;
      }
      // The fused upsample: per column phase, every second interior pixel from the phase's 2x2
      // kernel over consecutive low-resolution pixels (dot_driver_inl.h's DotPhaseRow).
      const int ay = iy0 + a.crop_top;
      const int by = ay >> 1;
      for (int px = 0; px < 2; ++px) {
        const int first = inside.lo + ((inside.lo - a.pads.left + a.crop_left + px) & 1);
        const int n = (inside.hi - first + 1) / 2;  // this phase's interior pixels
        const int ph = (ay & 1) * 2 + px;
        const uint8_t* pw =
            weights + ph * phase_bytes + static_cast<ptrdiff_t>(blk) * 4 * j.tap_bytes;
        for (int t = 0; t < 4; ++t) ws[t] = pw + t * j.tap_bytes;
        for (int i = 0; i < AmxTileCount(n); ++i) {
          const int ox0 = first + 2 * AmxTileStart(i, n);
          const int bx = (ox0 - a.pads.left + a.crop_left) >> 1;
          for (int t = 0; t < 4; ++t) {
            xs[t] = reinterpret_cast<const uint8_t*>(a.in.pixel(by + t / 2, bx + t % 2));
          }
          AmxTileFor<T>(nt, j, xs, in_pixel, ws, 4, phase_init[ph], phase_e[ph],
                        j.Out(oy, ox0, blk), 2 * j.out_pixel);
        }
      }
    }
  }
  T::Release();
}

}  // namespace sfrt::simd
