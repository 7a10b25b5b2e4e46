// The AMX convolution, int8 (kernels/int8_job.h, tdpbusd) and bf16 (kernels/bf16_job.h,
// tdpbf16ps), written once over a tile-operation vocabulary `T`: the hardware's
// (kernels/avx512/conv2d_avx512amx.cc: ldtilecfg, tileloadd, tdpbusd/tdpbf16ps, tilestored) and a
// scalar emulation (src/amx_emulation.cc), so that the blocking and packing are tested on every
// CPU. The two are built with different flags, so nothing here may give them one shared function
// (the linker keeps one copy of it, maybe the AVX-512 one): everything is a template on T (each
// file's own tile type, in an anonymous namespace) or static, and the structs are trivial
// (tests/runtime/check_kernel_linkage.py). The int8 path is bit for bit equal to
// ref::Conv2dInt8Rows (exact int32 sums, int8_job.h's epilogue); the bf16 path equals
// ref::Conv2dBf16Rows up to the order of the float32 sums.
//
// T provides Configure(const AmxTileConfig&), Release(), and, for tile numbers known at compile
// time, Zero<t>(), Load<t>(base, stride), Store<t>(base, stride), DpBusd<c, a, b>() (for each row m
// of c and 32-bit column n, c[m][n] += sum over k and i < 4 of the unsigned byte a[m][4k+i] times
// the signed byte b[k][4n+i]) and DpBf16ps<c, a, b>() (c[m][n] += sum over k and i < 2 of the bf16
// a[m][2k+i] times the bf16 b[k][2n+i], in float32); and Finish<kQuantized>(sums, init, epilogue,
// out, out_step), the epilogue of one stored 16 x 64 tile (AmxFinishScalar's arithmetic).
//
// Blocking, on the packed layouts of the AVX-512 kernels (nr 64: weights [block][tap][group][64]
// [one 32-bit group: 4 int8 or 2 bf16]). An A tile holds 16 output pixels' inputs for one tap and
// one chunk of up to 16 groups (rows a fixed number of bytes apart in the input: one tileloadd); a
// B tile 16 output channels of the chunk's groups (rows of 64 bytes at a stride of 256 in the
// packed weights, so the AVX-512 layouts serve AMX unchanged); a C tile 16 pixels x 16 32-bit
// channels, summed over every tap and chunk before it is stored.
// - 2 x 2 (AmxPairs: input channels a multiple of 64, which every large layer of SceneEDNet is):
//   two pixel tiles (A: tmm4, tmm5) times two channel tiles (B: tmm6, tmm7) into four C tiles
//   (tmm0-3), a block of 64 channels in two halves of 32. Each tile loaded serves two products,
//   and each weight tile loaded from L2 serves 32 pixels, where the 1 x 4 blocking's serves 16.
// - 1 x 4 otherwise: one pixel tile (tmm4; tmm6 for a last, shorter chunk) times the block's four
//   channel tiles, loaded one after the other into tmm5 (tmm7), into C tiles tmm0-3.
// Only the C tiles (and B tiles) of channels the block has are used. The C tiles start from zero;
// the int8 epilogue adds -in_zero_point times the sum of the taps' tap_sums.
//
// Plain convolutions: a pixel tile is 16 consecutive output pixels of a row, their inputs sw
// pixels apart (the 2 x 2 blocking takes a row's tiles two by two). The fused upsample -> 3x3
// convolution (a.upsampled, with phase kernels): per column phase, a tile is 16 of every second
// output pixel, whose inputs are consecutive pixels of the low-resolution map, over the phase's
// 2x2 kernel (4 taps; dot_driver_inl.h's DotPhaseRow). The tiles take every pixel of a row whose
// window lies inside the map (the row's last tile may overlap the one before it), on rows whose
// window lies inside the map, where the row has at least 16 such pixels (per phase); every other
// pixel goes to `fallback` with a column range (Args::col_begin/col_end), and whole calls go to
// it where the tiles would do little: fewer than 16 groups of input channels, a fused upsample
// without phase kernels, calls that ask for a column range themselves.
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
  uint8_t palette;
  uint8_t start_row;
  uint8_t reserved[14];
  uint16_t colsb[16];  // bytes per row of tile i
  uint8_t rows[16];
};
static_assert(sizeof(AmxTileConfig) == 64, "LDTILECFG reads 64 bytes");

inline constexpr int kAmxRows = 16;      // palette 1: rows per tile
inline constexpr int kAmxRowBytes = 64;  // palette 1: bytes per row
inline constexpr int kAmxPixels = 16;    // output pixels per C tile (its rows)

// Whether a layer of `groups` groups of 4 input channels takes the 2 x 2 blocking (AmxPairBlock):
// whole chunks of 16 groups only, so that tiles 4-7 can all be 16 x 64 bytes.
static inline bool AmxPairs(int groups) { return groups >= kAmxRows && groups % kAmxRows == 0; }

// The tile shapes for `groups` groups of 4 input channels: C tiles 0-3 of 16 x 64 bytes. Under
// AmxPairs, A tiles 4 and 5 and B tiles 6 and 7, all 16 x 64 bytes (16 groups). Otherwise A (4)
// and B (5) for full chunks of min(16, groups) groups; A (6) and B (7) for a last chunk of
// groups % 16 when groups > 16 and that is not 0.
static inline AmxTileConfig AmxConfigFor(int groups) {
  AmxTileConfig c{};
  c.palette = 1;
  for (int t = 0; t < 4; ++t) {
    c.rows[t] = kAmxPixels;
    c.colsb[t] = kAmxRowBytes;
  }
  if (AmxPairs(groups)) {
    for (int t = 4; t < 8; ++t) {
      c.rows[t] = kAmxRows;
      c.colsb[t] = kAmxRowBytes;
    }
    return c;
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

// The (C, A, B) tile triples the kernels multiply: the 1 x 4 blocking's C tiles with A/B 4/5
// (full chunks) or 6/7 (the tail), and the 2 x 2 blocking's C tile 2 * i + j with A 4 + i and
// B 6 + j. The hardware's tile numbers must be literals, so T spells out each of these.
static constexpr bool AmxDpOperands(int c, int a, int b) {
  if (c < 0 || c > 3) return false;
  if ((a == 4 && b == 5) || (a == 6 && b == 7)) return true;
  return a == 4 + c / 2 && b == 6 + c % 2;
}

// c += a . b: tdpbusd (quantized) or tdpbf16ps.
template <typename T, bool kQuantized, int C, int A, int B>
inline void AmxDp() {
  static_assert(AmxDpOperands(C, A, B), "a tile triple the kernels do not use");
  if constexpr (kQuantized) {
    T::template DpBusd<C, A, B>();
  } else {
    T::template DpBf16ps<C, A, B>();
  }
}

// One chunk's products: A (16 pixels' inputs) with the first NT B tiles of the block's 64
// channels (rows of 64 bytes, 256 apart in the packed weights), NT being the C tiles that hold
// valid channels.
template <typename T, bool kQuantized, int NT, int A, int B>
inline void AmxChunk(const void* x, ptrdiff_t x_stride, const uint8_t* w) {
  T::template Load<A>(x, x_stride);
  auto dot = [&](auto c) {
    constexpr int C = decltype(c)::value;
    if constexpr (C < NT) {
      T::template Load<B>(w + 64 * C, 256);
      AmxDp<T, kQuantized, C, A, B>();
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
static inline void AmxFinishScalar(const int32_t* sums, const int32_t* init, const DotEpilogue& e,
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
  const typename Traits::Args* a;
  int full;    // groups per chunk (tiles 4 and 5)
  int chunks;  // chunks of `full` groups, then the tail (tiles 6 and 7)
  int tail;
  bool pairs;           // AmxPairs: the 2 x 2 blocking
  ptrdiff_t tap_bytes;  // packed weights of one tap of one block
  ptrdiff_t out_pixel;  // bytes between output pixels
};

// Output pixel (oy, ox)'s first channel of block blk.
template <typename Conv>
static void* AmxOut(const AmxJob<Conv>& j, int oy, int ox, int blk) {
  if (j.a->conv->out_float) return j.a->out_f32.pixel(oy, ox) + blk * 64;
  return DotTraits<Conv>::LowOut(*j.a).pixel(oy, ox) + blk * 64;
}

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
static inline int AmxTileStart(int tile, int n) {
  const int start = tile * kAmxPixels;
  return start + kAmxPixels <= n ? start : n - kAmxPixels;
}
static inline int AmxTileCount(int n) { return (n + kAmxPixels - 1) / kAmxPixels; }

// Up to two 16-pixel tiles that share their taps' weights: tile i's first pixel reads xs[i][t] at
// tap t (its other pixels x_stride bytes apart) and writes out[i] (its block's first channel;
// its other pixels out_step bytes apart). The taps go row by row of the kernel, taps_w a row.
struct AmxPixelTiles {
  int count;
  const uint8_t* xs[2][kMaxInt8Taps];  // set by AmxRowTiles' fill per tile
  void* out[2];
  ptrdiff_t x_stride;
  ptrdiff_t out_step;
  int taps;
  int taps_w;
};

// One chunk of the 2 x 2 blocking: MT pixel tiles (A tiles 4, 5) times NB channel tiles (B
// tiles 6, 7: rows of 64 bytes, 256 apart in the packed weights) into C tiles 2 * i + j. Each
// A and B tile loaded serves NB and MT products: four loads for four products, where the 1 x 4
// blocking loads five, four of them weights.
template <typename T, bool kQuantized, int MT, int NB>
inline void AmxPairChunk(const uint8_t* x0, const uint8_t* x1, ptrdiff_t x_stride,
                         const uint8_t* w) {
  T::template Load<4>(x0, x_stride);
  T::template Load<6>(w, 256);
  if constexpr (MT > 1) T::template Load<5>(x1, x_stride);
  if constexpr (NB > 1) T::template Load<7>(w + 64, 256);
  AmxDp<T, kQuantized, 0, 4, 6>();
  if constexpr (NB > 1) AmxDp<T, kQuantized, 1, 4, 7>();
  if constexpr (MT > 1) AmxDp<T, kQuantized, 2, 5, 6>();
  if constexpr (MT > 1 && NB > 1) AmxDp<T, kQuantized, 3, 5, 7>();
}

// The 2 x 2 blocking (AmxPairs: whole chunks of 16 groups): the MT (= tiles.count) pixel tiles
// times the block's channels [32 * half, 32 * half + 16 * NB) over the taps, ws[t] the tap's
// packed weights of the block; C tiles from zero, then T's epilogue of each pixel tile with init
// and e's channels of this half. The sums go by kernel row, chunk, then the row's taps, so that
// the taps of a row, whose pixels overlap but for one, read one chunk of the inputs from L1.
template <typename T, typename Conv, int MT, int NB>
inline void AmxPairBlock(const AmxJob<Conv>& j, const AmxPixelTiles& tiles,
                         const uint8_t* const* ws, int half, const int32_t* init,
                         const DotEpilogue& e) {
  constexpr bool kQuantized = DotTraits<Conv>::kQuantized;
  constexpr ptrdiff_t kChunkWeights = kAmxRows * 256;  // one chunk of 16 groups x 64 channels
  T::template Zero<0>();
  if constexpr (NB > 1) T::template Zero<1>();
  if constexpr (MT > 1) T::template Zero<2>();
  if constexpr (MT > 1 && NB > 1) T::template Zero<3>();
  const ptrdiff_t w_half = 128 * half;  // the half's first channel: 32 channels x 4 bytes
  for (int row = 0; row < tiles.taps; row += tiles.taps_w) {
    for (int c = 0; c < j.chunks; ++c) {
      const ptrdiff_t x_off = c * kAmxRowBytes;
      const ptrdiff_t w_off = c * kChunkWeights + w_half;
      for (int t = row; t < row + tiles.taps_w; ++t) {
        AmxPairChunk<T, kQuantized, MT, NB>(tiles.xs[0][t] + x_off,
                                            MT > 1 ? tiles.xs[1][t] + x_off : nullptr,
                                            tiles.x_stride, ws[t] + w_off);
      }
    }
  }
  constexpr int kTile = kAmxPixels * 16;  // 32-bit sums per C tile
  alignas(64) int32_t sums[2][2 * kTile];
  T::template Store<0>(sums[0], 64);
  if constexpr (NB > 1) T::template Store<1>(sums[0] + kTile, 64);
  if constexpr (MT > 1) T::template Store<2>(sums[1], 64);
  if constexpr (MT > 1 && NB > 1) T::template Store<3>(sums[1] + kTile, 64);
  DotEpilogue eh = e;
  eh.bias += 32 * half;
  if constexpr (kQuantized) eh.multiplier += 32 * half;
  eh.valid = e.valid - 32 * half < 32 ? e.valid - 32 * half : 32;
  const ptrdiff_t out_half =
      32 * half *
      static_cast<ptrdiff_t>(e.out_float ? sizeof(float) : sizeof(typename DotTraits<Conv>::Elem));
  for (int m = 0; m < MT; ++m) {
    T::template Finish<kQuantized>(sums[m], init + 32 * half, eh,
                                   static_cast<char*>(tiles.out[m]) + out_half, tiles.out_step);
  }
}

// The pixel tiles times the block's nt C tiles of valid channels (nt in [1, 4]): by halves of
// 32 channels under AmxPairs, else one 16-pixel tile at a time with the 1 x 4 blocking.
template <typename T, typename Conv>
inline void AmxBlockTiles(const AmxJob<Conv>& j, const AmxPixelTiles& tiles, int nt,
                          const uint8_t* const* ws, const int32_t* init, const DotEpilogue& e) {
  if (!j.pairs) {
    for (int m = 0; m < tiles.count; ++m) {
      AmxTileFor<T>(nt, j, tiles.xs[m], tiles.x_stride, ws, tiles.taps, init, e, tiles.out[m],
                    tiles.out_step);
    }
    return;
  }
  for (int half = 0; 2 * half < nt; ++half) {
    const bool two_b = nt - 2 * half >= 2;
    if (tiles.count == 2) {
      if (two_b) {
        AmxPairBlock<T, Conv, 2, 2>(j, tiles, ws, half, init, e);
      } else {
        AmxPairBlock<T, Conv, 2, 1>(j, tiles, ws, half, init, e);
      }
    } else if (two_b) {
      AmxPairBlock<T, Conv, 1, 2>(j, tiles, ws, half, init, e);
    } else {
      AmxPairBlock<T, Conv, 1, 1>(j, tiles, ws, half, init, e);
    }
  }
}

// What the epilogue adds to a channel block's sums: int8, -z * the sum of the given taps' tap_sums
// (interior pixels read every tap); bf16, nothing (zeros, unread).
template <typename Conv>
static inline void AmxInit(const Conv& p, const int32_t* tap_sums, int taps, int32_t* init) {
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

// What one call's rows share beyond AmxJob: the map the convolution reads (C when upsampled),
// its interior columns, and the weights the tiles read.
template <typename Conv>
struct AmxCall {
  using Traits = DotTraits<Conv>;
  using Fallback = void (*)(const typename Traits::Args&, int, int, int, int);
  AmxJob<Conv> j;
  Fallback fallback;
  int out_w;
  int src_h;
  ColumnRange inside;
  int interior;
  bool wide;  // a row has enough interior pixels for the tiles
  int taps;   // the plain kernel's, or the phases' 4
  const uint8_t* weights;
  ptrdiff_t phase_bytes;  // one phase's packed weights
  ptrdiff_t in_pixel;     // bytes between input pixels
};

// Whether the tiles take the call (else the fallback computes it whole): not for a column range,
// nor for few input channels (under 16 groups a tile product does less than a quarter of its
// work, and the epilogue per tile outweighs it), nor for an upsample without phase kernels. Few
// output channels are fine: only the C tiles with valid channels are computed.
template <typename Conv>
static bool AmxTakes(const typename DotTraits<Conv>::Args& a, int out_w) {
  const Conv& p = *a.conv;
  const bool tiles = p.nr == 64 && DotTraits<Conv>::Groups(p) >= kAmxRows &&
                     p.kernel_h * p.kernel_w <= kMaxInt8Taps && a.col_begin <= 0 &&
                     a.col_end >= out_w;
  if (!a.upsampled) return tiles;
  return tiles && p.phase_weights != nullptr && p.kernel_h == 3 && p.kernel_w == 3 &&
         p.stride_h == 1 && p.stride_w == 1;
}

template <typename Conv>
static AmxCall<Conv> AmxCallFor(const typename DotTraits<Conv>::Args& a, int out_w,
                                typename AmxCall<Conv>::Fallback fallback) {
  using Traits = DotTraits<Conv>;
  const Conv& p = *a.conv;
  const int groups = Traits::Groups(p);
  AmxCall<Conv> c{};
  c.fallback = fallback;
  c.out_w = out_w;
  c.j.a = &a;
  c.j.full = groups < kAmxRows ? groups : kAmxRows;
  c.j.chunks = groups / c.j.full;
  c.j.tail = groups - c.j.chunks * c.j.full;
  c.j.pairs = AmxPairs(groups) && !p.amx_1x4;
  c.j.tap_bytes = static_cast<ptrdiff_t>(groups) * 4 * 64;
  const ptrdiff_t elem = sizeof(typename Traits::Elem);
  c.j.out_pixel = p.out_float ? static_cast<ptrdiff_t>(a.out_f32.channels) * sizeof(float)
                              : Traits::LowOut(a).stride() * elem;
  c.in_pixel = a.in.stride() * elem;
  c.src_h = a.upsampled ? a.c_height : a.in.height;
  const int src_w = a.upsampled ? a.c_width : a.in.width;
  c.inside = InsideColumns(out_w, src_w, p.kernel_w, p.stride_w, a.pads.left);
  c.interior = c.inside.hi > c.inside.lo ? c.inside.hi - c.inside.lo : 0;
  // Upsampled: each column phase has about half the interior; both need 16.
  c.wide = a.upsampled ? c.interior >= 2 * kAmxPixels + 1 : c.interior >= kAmxPixels;
  c.taps = a.upsampled ? 4 : p.kernel_h * p.kernel_w;
  c.weights = reinterpret_cast<const uint8_t*>(a.upsampled ? p.phase_weights : p.weights);
  c.phase_bytes = static_cast<ptrdiff_t>(p.blocks) * 4 * c.j.tap_bytes;
  return c;
}

// One block's epilogue and zero-point terms: the plain kernel's (index 0), or each phase's.
struct AmxBlockTerms {
  DotEpilogue e[4];
  int nt;  // C tiles with valid channels
  alignas(64) int32_t init[4][64];
};

template <typename Conv>
static void AmxTermsFor(const AmxCall<Conv>& c, int blk, AmxBlockTerms* terms) {
  const Conv& p = *c.j.a->conv;
  const DotEpilogue e = BlockEpilogue<AmxBlocks<Conv>>(p, blk);
  terms->nt = (e.valid + 15) / 16;
  for (int ph = 0; ph < 4; ++ph) terms->e[ph] = e;
  if (!c.j.a->upsampled) {
    const int32_t* sums = nullptr;
    if constexpr (DotTraits<Conv>::kQuantized) {
      sums = p.tap_sums + static_cast<ptrdiff_t>(blk) * c.taps * 64;
    }
    AmxInit(p, sums, c.taps, terms->init[0]);
    return;
  }
  for (int ph = 0; ph < 4; ++ph) {
    const int32_t* sums = nullptr;
    if constexpr (DotTraits<Conv>::kQuantized) {
      sums = p.phase_tap_sums + (static_cast<ptrdiff_t>(ph) * p.blocks + blk) * 4 * 64;
      terms->e[ph].multiplier = p.phase_multiplier + (ph * p.blocks + blk) * 64;
    }
    AmxInit(p, sums, 4, terms->init[ph]);
  }
}

// The `count` 16-pixel tiles of one row and block, two at a time: fill(i, xs) sets tile i's
// inputs per tap and returns its output; `tiles` comes with its strides and taps.
template <typename T, typename Conv, typename Fill>
void AmxRowTiles(const AmxJob<Conv>& j, int count, AmxPixelTiles& tiles, const uint8_t* const* ws,
                 const int32_t* init, const DotEpilogue& e, int nt, Fill fill) {
  for (int i = 0; i < count; i += 2) {
    tiles.count = i + 1 < count ? 2 : 1;
    for (int m = 0; m < tiles.count; ++m) tiles.out[m] = fill(i + m, tiles.xs[m]);
    AmxBlockTiles<T>(j, tiles, nt, ws, init, e);
  }
}

// The interior pixels of plain output row oy (first input row iy0) of block blk.
template <typename T, typename Conv>
void AmxPlainRow(const AmxCall<Conv>& c, const AmxBlockTerms& terms, int blk, int oy, int iy0) {
  const auto& a = *c.j.a;
  const Conv& p = *a.conv;
  const uint8_t* ws[kMaxInt8Taps];
  const uint8_t* wblk = c.weights + static_cast<ptrdiff_t>(blk) * c.taps * c.j.tap_bytes;
  for (int t = 0; t < c.taps; ++t) ws[t] = wblk + t * c.j.tap_bytes;
  const ptrdiff_t x_stride = static_cast<ptrdiff_t>(p.stride_w) * c.in_pixel;
  auto fill = [&](int i, const uint8_t** xs) {
    const int ox0 = c.inside.lo + AmxTileStart(i, c.interior);
    const int ix0 = ox0 * p.stride_w - a.pads.left;
    for (int ky = 0; ky < p.kernel_h; ++ky) {
      for (int kx = 0; kx < p.kernel_w; ++kx) {
        xs[ky * p.kernel_w + kx] = reinterpret_cast<const uint8_t*>(a.in.pixel(iy0 + ky, ix0 + kx));
      }
    }
    return AmxOut(c.j, oy, ox0, blk);
  };
  AmxPixelTiles tiles;  // count, out and xs set per tile by AmxRowTiles (no zeroing per row)
  tiles.x_stride = x_stride;
  tiles.out_step = c.j.out_pixel;
  tiles.taps = c.taps;
  tiles.taps_w = p.kernel_w;
  AmxRowTiles<T>(c.j, AmxTileCount(c.interior), tiles, ws, terms.init[0], terms.e[0], terms.nt,
                 fill);
}

// The interior pixels of fused-upsample output row oy (first row iy0 of C) of block blk: per
// column phase, every second pixel from the phase's 2x2 kernel over consecutive low-resolution
// pixels (dot_driver_inl.h's DotPhaseRow).
template <typename T, typename Conv>
void AmxPhaseRow(const AmxCall<Conv>& c, const AmxBlockTerms& terms, int blk, int oy, int iy0) {
  const auto& a = *c.j.a;
  const int ay = iy0 + a.crop_top;
  const int by = ay >> 1;
  const uint8_t* ws[4];
  AmxPixelTiles tiles;  // count, out and xs set per tile by AmxRowTiles (no zeroing per row)
  tiles.x_stride = c.in_pixel;
  tiles.out_step = 2 * c.j.out_pixel;
  tiles.taps = 4;
  tiles.taps_w = 2;
  for (int px = 0; px < 2; ++px) {
    const int first = c.inside.lo + ((c.inside.lo - a.pads.left + a.crop_left + px) & 1);
    const int n = (c.inside.hi - first + 1) / 2;  // this phase's interior pixels
    const int ph = (ay & 1) * 2 + px;
    const uint8_t* pw =
        c.weights + ph * c.phase_bytes + static_cast<ptrdiff_t>(blk) * 4 * c.j.tap_bytes;
    for (int t = 0; t < 4; ++t) ws[t] = pw + t * c.j.tap_bytes;
    auto fill = [&](int i, const uint8_t** xs) {
      const int ox0 = first + 2 * AmxTileStart(i, n);
      const int bx = (ox0 - a.pads.left + a.crop_left) >> 1;
      for (int t = 0; t < 4; ++t) {
        xs[t] = reinterpret_cast<const uint8_t*>(a.in.pixel(by + t / 2, bx + t % 2));
      }
      return AmxOut(c.j, oy, ox0, blk);
    };
    AmxRowTiles<T>(c.j, AmxTileCount(n), tiles, ws, terms.init[ph], terms.e[ph], terms.nt, fill);
  }
}

// Output row oy of block blk: the tiles take its interior pixels where its window rows lie inside
// the map and it has enough of them; the fallback the rest.
template <typename T, typename Conv>
void AmxRow(const AmxCall<Conv>& c, const AmxBlockTerms& terms, int blk, int oy) {
  const auto& a = *c.j.a;
  const Conv& p = *a.conv;
  const int iy0 = oy * (a.upsampled ? 1 : p.stride_h) - a.pads.top;
  typename DotTraits<Conv>::Args rest = a;
  if (iy0 < 0 || iy0 + p.kernel_h > c.src_h || !c.wide) {
    c.fallback(rest, oy, oy + 1, blk, blk + 1);
    return;
  }
  if (c.inside.lo > 0) {
    rest.col_begin = 0;
    rest.col_end = c.inside.lo;
    c.fallback(rest, oy, oy + 1, blk, blk + 1);
  }
  if (c.inside.hi < c.out_w) {
    rest.col_begin = c.inside.hi;
    rest.col_end = c.out_w;
    c.fallback(rest, oy, oy + 1, blk, blk + 1);
  }
  if (a.upsampled) {
    AmxPhaseRow<T>(c, terms, blk, oy, iy0);
  } else {
    AmxPlainRow<T>(c, terms, blk, oy, iy0);
  }
}

// Rows [row_begin, row_end) of blocks [blk_begin, blk_end) of an int8 or bf16 convolution
// (Conv: PackedInt8Conv or PackedBf16Conv) packed with nr 64, plain or (a.upsampled) the fused
// upsample's through its phase kernels; `fallback` (same arguments) computes what the tiles do
// not: rows whose window leaves the input, the border columns, rows with fewer than 16 interior
// pixels (per column phase when upsampled), and the layers the tiles leave whole (AmxTakes).
template <typename T, typename Conv>
void AmxConvRows(const typename DotTraits<Conv>::Args& a, int row_begin, int row_end, int blk_begin,
                 int blk_end, typename AmxCall<Conv>::Fallback fallback) {
  using Traits = DotTraits<Conv>;
  const int out_w = a.conv->out_float ? a.out_f32.width : Traits::LowOut(a).width;
  if (!AmxTakes<Conv>(a, out_w)) {
    fallback(a, row_begin, row_end, blk_begin, blk_end);
    return;
  }
  const AmxCall<Conv> c = AmxCallFor<Conv>(a, out_w, fallback);
  T::Configure(AmxConfigFor(Traits::Groups(*a.conv)));
  AmxBlockTerms terms;
  for (int blk = blk_begin; blk < blk_end; ++blk) {
    AmxTermsFor(c, blk, &terms);
    for (int oy = row_begin; oy < row_end; ++oy) AmxRow<T>(c, terms, blk, oy);
  }
  T::Release();
}

}  // namespace sfrt::simd
