// AMX peak loops: 6 independent C tiles (of palette 1's 8) accumulating tdpbusd (int8: 16 x 16
// int32 lanes, 64 u8 x s8 pairs each, 16384 multiply-accumulates per instruction) or tdpbf16ps
// (bf16: 16 x 16 fp32 lanes, 32 pairs each, 8192 per instruction) of one A and one B tile loaded
// once, so that the loop measures the tile multiplier alone. Each call configures the tiles on
// its own thread and releases them; the process's XTILEDATA permission comes from
// cpu_extensions.cc's check, which runs before these loops are called.
#include <immintrin.h>

#include <cstdint>

#include "profiling/peak_fma_kernels.h"

namespace sfrt::profiling::internal {
namespace {

constexpr int kChains = 6;

struct alignas(64) TileConfig {
  uint8_t palette = 1;
  uint8_t start_row = 0;
  uint8_t reserved[14] = {};
  uint16_t colsb[16] = {};
  uint8_t rows[16] = {};
};

void Configure() {
  TileConfig c;
  for (int t = 0; t < 8; ++t) {
    c.rows[t] = 16;
    c.colsb[t] = 64;
  }
  _tile_loadconfig(&c);
}

// The XOR of every 32-bit value of the C tiles, so that no chain can be dropped.
float Collect() {
  alignas(64) int32_t rows[16][16];
  int32_t total = 0;
  auto fold = [&] {
    for (const auto& row : rows) {
      for (int32_t v : row) total ^= v;
    }
  };
  _tile_stored(0, rows, 64);
  fold();
  _tile_stored(1, rows, 64);
  fold();
  _tile_stored(2, rows, 64);
  fold();
  _tile_stored(3, rows, 64);
  fold();
  _tile_stored(4, rows, 64);
  fold();
  _tile_stored(5, rows, 64);
  fold();
  _tile_release();
  return static_cast<float>(total);
}

void LoadOperands(uint8_t a_byte, uint8_t b_byte) {
  alignas(64) uint8_t a[16][64], b[16][64];
  for (int r = 0; r < 16; ++r) {
    for (int k = 0; k < 64; ++k) {
      a[r][k] = a_byte;
      b[r][k] = b_byte;
    }
  }
  _tile_loadd(6, a, 64);
  _tile_loadd(7, b, 64);
  _tile_zero(0);
  _tile_zero(1);
  _tile_zero(2);
  _tile_zero(3);
  _tile_zero(4);
  _tile_zero(5);
}

// tdpbusd (int8: u8 3 times s8 -2; the int32 sums wrap, never trap) or tdpbf16ps (bf16 zeros:
// the sums stay finite however long the loop runs) into the 6 C tiles.
template <bool kInt8>
float Run(int64_t iterations) {
  Configure();
  if constexpr (kInt8) {
    LoadOperands(3, 0xFE);
  } else {
    LoadOperands(0, 0);
  }
  // The tile numbers are literals: GCC's tile intrinsics paste them into the instruction.
  for (int64_t i = 0; i < iterations; ++i) {
    if constexpr (kInt8) {
      _tile_dpbusd(0, 6, 7);
      _tile_dpbusd(1, 6, 7);
      _tile_dpbusd(2, 6, 7);
      _tile_dpbusd(3, 6, 7);
      _tile_dpbusd(4, 6, 7);
      _tile_dpbusd(5, 6, 7);
    } else {
      _tile_dpbf16ps(0, 6, 7);
      _tile_dpbf16ps(1, 6, 7);
      _tile_dpbf16ps(2, 6, 7);
      _tile_dpbf16ps(3, 6, 7);
      _tile_dpbf16ps(4, 6, 7);
      _tile_dpbf16ps(5, 6, 7);
    }
  }
  return Collect();
}

}  // namespace

const PeakKernel* PeakKernelAmxInt8() {
  static const PeakKernel kernel = {"amx_int8: 6 C tiles x 16384 u8s8 MACs, tdpbusd",
                                    2 * kChains * 16384, Run<true>};
  return &kernel;
}

const PeakKernel* PeakKernelAmxBf16() {
  static const PeakKernel kernel = {"amx_bf16: 6 C tiles x 8192 bf16 MACs, tdpbf16ps",
                                    2 * kChains * 8192, Run<false>};
  return &kernel;
}

}  // namespace sfrt::profiling::internal
