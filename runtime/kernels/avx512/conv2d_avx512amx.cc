// AMX convolution kernels, int8 (tdpbusd) and bf16 (tdpbf16ps), compiled with -mamx-tile
// -mamx-int8 -mamx-bf16 and the AVX-512 flags only in this translation unit
// (runtime/CMakeLists.txt): kernels/simd/amx_driver_inl.h over the hardware's tile instructions.
// The int8 kernels are bit for bit equal to ref::Conv2dInt8Rows. What the tiles leave (border
// columns, few input channels, the few-output convolution) runs on the AVX-512 VNNI (int8) and
// AVX512_BF16 (bf16) kernels, which every AMX CPU has; the epilogues are theirs
// (kernels/avx512/dot_epilogue_avx512_inl.h). Chosen only where HostCpuFeatures().amx_int8 /
// amx_bf16 (src/cpu_features.cc: CPUID, XCR0, the palette of CPUID leaf 0x1D and Linux's tile
// data permission).
#include <immintrin.h>

#include <cstddef>
#include <cstdint>

#include "kernels/avx512/dot_epilogue_avx512_inl.h"
#include "kernels/bf16_job.h"
#include "kernels/int8_job.h"
#include "kernels/simd/amx_driver_inl.h"
#include "src/cpu_features.h"

namespace sfrt::avx512 {
namespace {

// GCC's tile intrinsics are macros that paste the tile number into the instruction's text, so
// the number must be a literal: each template below names its tiles one by one.
#define SFRT_TILE_CASE(n, stmt) \
  if constexpr (T == n) {       \
    stmt;                       \
  }
// Every (C, A, B) of simd::AmxDpOperands: the 1 x 4 blocking's C tiles 0-3 with A/B 4/5 and 6/7,
// the 2 x 2 blocking's C 2 * i + j with A 4 + i and B 6 + j.
#define SFRT_DP_CASE(op, c, a, b)             \
  if constexpr (C == c && A == a && B == b) { \
    op(c, a, b);                              \
  }
#define SFRT_DP_CASES(op)   \
  SFRT_DP_CASE(op, 0, 4, 5) \
  SFRT_DP_CASE(op, 1, 4, 5) \
  SFRT_DP_CASE(op, 2, 4, 5) \
  SFRT_DP_CASE(op, 3, 4, 5) \
  SFRT_DP_CASE(op, 0, 6, 7) \
  SFRT_DP_CASE(op, 1, 6, 7) \
  SFRT_DP_CASE(op, 2, 6, 7) \
  SFRT_DP_CASE(op, 3, 6, 7) \
  SFRT_DP_CASE(op, 0, 4, 6) \
  SFRT_DP_CASE(op, 1, 4, 7) \
  SFRT_DP_CASE(op, 2, 5, 6) \
  SFRT_DP_CASE(op, 3, 5, 7)
struct HardwareTiles {
  static void Configure(const simd::AmxTileConfig& c) { _tile_loadconfig(&c); }
  static void Release() { _tile_release(); }
  template <int T>
  static void Zero() {
    static_assert(T >= 0 && T < 4, "the kernels zero the C tiles 0-3");
    SFRT_TILE_CASE(0, _tile_zero(0))
    SFRT_TILE_CASE(1, _tile_zero(1))
    SFRT_TILE_CASE(2, _tile_zero(2))
    SFRT_TILE_CASE(3, _tile_zero(3))
  }
  template <int T>
  static void Load(const void* base, ptrdiff_t stride) {
    static_assert(T >= 0 && T < 8, "palette 1 has tiles 0-7");
    SFRT_TILE_CASE(0, _tile_loadd(0, base, stride))
    SFRT_TILE_CASE(1, _tile_loadd(1, base, stride))
    SFRT_TILE_CASE(2, _tile_loadd(2, base, stride))
    SFRT_TILE_CASE(3, _tile_loadd(3, base, stride))
    SFRT_TILE_CASE(4, _tile_loadd(4, base, stride))
    SFRT_TILE_CASE(5, _tile_loadd(5, base, stride))
    SFRT_TILE_CASE(6, _tile_loadd(6, base, stride))
    SFRT_TILE_CASE(7, _tile_loadd(7, base, stride))
  }
  template <int T>
  static void Store(void* base, ptrdiff_t stride) {
    static_assert(T >= 0 && T < 4, "the kernels store the C tiles 0-3");
    SFRT_TILE_CASE(0, _tile_stored(0, base, stride))
    SFRT_TILE_CASE(1, _tile_stored(1, base, stride))
    SFRT_TILE_CASE(2, _tile_stored(2, base, stride))
    SFRT_TILE_CASE(3, _tile_stored(3, base, stride))
  }
  template <int C, int A, int B>
  static void DpBusd() {
    static_assert(simd::AmxDpOperands(C, A, B), "a tile triple the kernels do not use");
    SFRT_DP_CASES(_tile_dpbusd)
  }
  template <int C, int A, int B>
  static void DpBf16ps() {
    static_assert(simd::AmxDpOperands(C, A, B), "a tile triple the kernels do not use");
    SFRT_DP_CASES(_tile_dpbf16ps)
  }
  // The epilogue of one stored tile (int8: plus init, the zero-point correction), pixel by pixel
  // on the VNNI and AVX512_BF16 kernels' code, over the vectors that hold valid channels.
  template <bool kQuantized>
  static void Finish(const int32_t* sums, const int32_t* init, const simd::DotEpilogue& e,
                     void* out, ptrdiff_t out_step) {
    switch ((e.valid + 15) / 16) {
      case 1:
        return FinishVectors<kQuantized, 1>(sums, init, e, out, out_step);
      case 2:
        return FinishVectors<kQuantized, 2>(sums, init, e, out, out_step);
      case 3:
        return FinishVectors<kQuantized, 3>(sums, init, e, out, out_step);
      default:
        return FinishVectors<kQuantized, 4>(sums, init, e, out, out_step);
    }
  }
  template <bool kQuantized, int NV>
  static void FinishVectors(const int32_t* sums, const int32_t* init, const simd::DotEpilogue& e,
                            void* out, ptrdiff_t out_step) {
    constexpr int kTile = simd::kAmxPixels * 16;  // 32-bit values per C tile
    for (int m = 0; m < simd::kAmxPixels; ++m) {
      void* pixel = static_cast<char*>(out) + m * out_step;
      const int32_t* row = sums + m * 16;
      if constexpr (kQuantized) {
        __m512i acc[NV];
#pragma GCC unroll 4
        for (int v = 0; v < NV; ++v) {
          acc[v] = _mm512_add_epi32(_mm512_load_si512(row + v * kTile),
                                    _mm512_load_si512(init + v * 16));
        }
        FinishU8s8<NV>(acc, e, pixel);
      } else {
        __m512 acc[NV];
#pragma GCC unroll 4
        for (int v = 0; v < NV; ++v) {
          acc[v] = _mm512_load_ps(reinterpret_cast<const float*>(row + v * kTile));
        }
        FinishBf16<NV>(acc, e, pixel);
      }
    }
  }
};
#undef SFRT_TILE_CASE
#undef SFRT_DP_CASE
#undef SFRT_DP_CASES

// What the tiles leave goes to the AVX-512 VNNI / AVX512_BF16 kernels of the same kind.
Int8ConvRowsFn g_vnni_conv = nullptr;
Int8ConvRowsFn g_vnni_upconv = nullptr;
Bf16ConvRowsFn g_bf16_conv = nullptr;
Bf16ConvRowsFn g_bf16_upconv = nullptr;

void ConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  simd::AmxConvRows<HardwareTiles, PackedInt8Conv>(a, row_begin, row_end, blk_begin, blk_end,
                                                   a.upsampled ? g_vnni_upconv : g_vnni_conv);
}

void Bf16ConvRows(const Bf16ConvArgs& a, int row_begin, int row_end, int blk_begin, int blk_end) {
  simd::AmxConvRows<HardwareTiles, PackedBf16Conv>(a, row_begin, row_end, blk_begin, blk_end,
                                                   a.upsampled ? g_bf16_upconv : g_bf16_conv);
}

void TileFinish(bool quantized, const int32_t* sums, const int32_t* init,
                const simd::DotEpilogue& e, void* out, ptrdiff_t out_step) {
  if (quantized) {
    HardwareTiles::Finish<true>(sums, init, e, out, out_step);
  } else {
    HardwareTiles::Finish<false>(sums, init, e, out, out_step);
  }
}

}  // namespace

const IsaInt8Kernels* Int8KernelsAmx() {
  static const IsaInt8Kernels* kernels = []() -> const IsaInt8Kernels* {
    const IsaInt8Kernels* vnni = Int8Kernels();
    if (vnni == nullptr || vnni->nr != 64 || !HostCpuFeatures().amx_int8) return nullptr;
    g_vnni_conv = vnni->conv;
    g_vnni_upconv = vnni->upconv;
    // Narrow convolutions (one group of input channels) go to the VNNI kernels whole, and
    // there to their narrow kernel.
    static const IsaInt8Kernels table = {64,
                                         ConvRows,
                                         ConvRows,
                                         "conv2d_u8s8__avx512amx_16x64",
                                         "upconv2d_u8s8__avx512amx_16x64",
                                         "",
                                         vnni->narrow_name};
    return &table;
  }();
  return kernels;
}

AmxTileFinishFn AmxTileFinish() {
  const CpuFeatures& f = HostCpuFeatures();
  return f.avx512 && f.avx512_vnni && f.avx512_bf16 ? TileFinish : nullptr;
}

const IsaBf16Kernels* Bf16KernelsAmx() {
  static const IsaBf16Kernels* kernels = []() -> const IsaBf16Kernels* {
    const IsaBf16Kernels* avx = Bf16Kernels();
    if (avx == nullptr || avx->nr != 64 || !HostCpuFeatures().amx_bf16) return nullptr;
    g_bf16_conv = avx->conv;
    g_bf16_upconv = avx->upconv;
    static const IsaBf16Kernels table = {64, Bf16ConvRows, Bf16ConvRows,
                                         "conv2d_bf16__avx512amx_16x64",
                                         "upconv2d_bf16__avx512amx_16x64"};
    return &table;
  }();
  return kernels;
}

}  // namespace sfrt::avx512
