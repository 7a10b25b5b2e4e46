// A scalar emulation of the AMX tile registers, tdpbusd and tdpbf16ps for
// kernels/simd/amx_driver_inl.h, so that the AMX kernels' blocking and packing run (and are tested
// against the reference kernels) on every CPU. Each thread has its own eight tiles, as each has its
// own tile state on the hardware. Not fast: a test vehicle, never chosen by a session.
#include <atomic>
#include <cstdint>
#include <cstring>

#include "kernels/bf16_job.h"
#include "kernels/int8_job.h"
#include "kernels/ref/conv2d_bf16_ref.h"
#include "kernels/ref/conv2d_int8_ref.h"
#include "kernels/simd/amx_driver_inl.h"

namespace sfrt::amx {
namespace {

std::atomic<long> g_violations{0};

struct EmulatedTiles {
  struct State {
    bool configured = false;
    uint8_t rows[8] = {};
    uint16_t colsb[8] = {};
    alignas(64) uint8_t data[8][simd::kAmxRows][simd::kAmxRowBytes] = {};
  };
  static State& S() {
    static thread_local State state;
    return state;
  }
  static void Violation() { g_violations.fetch_add(1, std::memory_order_relaxed); }

  // LDTILECFG: palette 1 allows 8 tiles of at most 16 rows x 64 bytes; tiles are zeroed.
  static void Configure(const simd::AmxTileConfig& c) {
    State& s = S();
    if (c.palette != 1 || c.start_row != 0) Violation();
    for (int t = 0; t < 16; ++t) {
      if (t >= 8) {
        if (c.rows[t] != 0 || c.colsb[t] != 0) Violation();
        continue;
      }
      if (c.rows[t] > simd::kAmxRows || c.colsb[t] > simd::kAmxRowBytes ||
          (c.rows[t] == 0) != (c.colsb[t] == 0)) {
        Violation();
      }
      s.rows[t] = c.rows[t];
      s.colsb[t] = c.colsb[t];
    }
    std::memset(s.data, 0, sizeof(s.data));
    s.configured = true;
  }
  static void Release() { S().configured = false; }

  // TILEZERO.
  template <int T>
  static void Zero() {
    State& s = S();
    if (!s.configured || s.rows[T] == 0) Violation();
    std::memset(s.data[T], 0, sizeof(s.data[T]));
  }
  template <int T>
  static void Load(const void* base, ptrdiff_t stride) {
    State& s = S();
    if (!s.configured || s.rows[T] == 0) Violation();
    for (int r = 0; r < s.rows[T]; ++r) {
      std::memcpy(s.data[T][r], static_cast<const uint8_t*>(base) + r * stride, s.colsb[T]);
    }
  }
  template <int T>
  static void Store(void* base, ptrdiff_t stride) {
    State& s = S();
    if (!s.configured || s.rows[T] == 0) Violation();
    for (int r = 0; r < s.rows[T]; ++r) {
      std::memcpy(static_cast<uint8_t*>(base) + r * stride, s.data[T][r], s.colsb[T]);
    }
  }
  // The shapes of tdpbusd / tdpbf16ps c, a, b must agree as the instructions require (#UD
  // otherwise).
  template <int C, int A, int B>
  static bool ShapesAgree() {
    State& s = S();
    if (!s.configured || s.rows[A] != s.rows[C] || s.rows[B] != s.colsb[A] / 4 ||
        s.colsb[B] != s.colsb[C] || s.colsb[C] % 4 != 0 || s.colsb[A] % 4 != 0) {
      Violation();
      return false;
    }
    return true;
  }
  template <int C, int A, int B>
  static void DpBusd() {
    if (!ShapesAgree<C, A, B>()) return;
    State& s = S();
    const int m_rows = s.rows[C], n_cols = s.colsb[C] / 4, k_groups = s.colsb[A] / 4;
    for (int m = 0; m < m_rows; ++m) {
      for (int n = 0; n < n_cols; ++n) {
        int32_t acc;
        std::memcpy(&acc, &s.data[C][m][4 * n], sizeof(acc));
        for (int k = 0; k < k_groups; ++k) {
          for (int i = 0; i < 4; ++i) {
            acc += static_cast<int32_t>(s.data[A][m][4 * k + i]) *
                   static_cast<int32_t>(static_cast<int8_t>(s.data[B][k][4 * n + i]));
          }
        }
        std::memcpy(&s.data[C][m][4 * n], &acc, sizeof(acc));
      }
    }
  }
  // Each product of two bf16 values is exact in float32; the two of a pair are added to the
  // accumulator one after the other (the hardware rounds a pair its own way: bf16 kernels are
  // compared within float32 rounding of the sums).
  template <int C, int A, int B>
  static void DpBf16ps() {
    if (!ShapesAgree<C, A, B>()) return;
    State& s = S();
    const int m_rows = s.rows[C], n_cols = s.colsb[C] / 4, k_groups = s.colsb[A] / 4;
    auto bf16 = [](const uint8_t* p) {
      uint16_t h;
      std::memcpy(&h, p, sizeof(h));
      return Bf16ToFloat(h);
    };
    for (int m = 0; m < m_rows; ++m) {
      for (int n = 0; n < n_cols; ++n) {
        float acc;
        std::memcpy(&acc, &s.data[C][m][4 * n], sizeof(acc));
        for (int k = 0; k < k_groups; ++k) {
          for (int i = 0; i < 2; ++i) {
            acc += bf16(&s.data[A][m][4 * k + 2 * i]) * bf16(&s.data[B][k][4 * n + 2 * i]);
          }
        }
        std::memcpy(&s.data[C][m][4 * n], &acc, sizeof(acc));
      }
    }
  }
  template <bool kQuantized>
  static void Finish(const int32_t* sums, const int32_t* init, const simd::DotEpilogue& e,
                     void* out, ptrdiff_t out_step) {
    simd::AmxFinishScalar<kQuantized>(sums, init, e, out, out_step);
  }
};

void EmulatedConvRows(const Int8ConvArgs& a, int row_begin, int row_end, int blk_begin,
                      int blk_end) {
  simd::AmxConvRows<EmulatedTiles, PackedInt8Conv>(a, row_begin, row_end, blk_begin, blk_end,
                                                   ref::Conv2dInt8Rows);
}

void EmulatedBf16ConvRows(const Bf16ConvArgs& a, int row_begin, int row_end, int blk_begin,
                          int blk_end) {
  simd::AmxConvRows<EmulatedTiles, PackedBf16Conv>(a, row_begin, row_end, blk_begin, blk_end,
                                                   ref::Conv2dBf16Rows);
}

}  // namespace

const IsaInt8Kernels* Int8KernelsEmulated() {
  // nr 64: the VNNI packing, which the AMX kernels read; what the tiles leave: the reference.
  // One function serves both entries: Int8ConvArgs::upsampled tells them apart.
  static constexpr IsaInt8Kernels kKernels = {64, EmulatedConvRows, EmulatedConvRows,
                                              "conv2d_u8s8__amx_emulated_16x64",
                                              "upconv2d_u8s8__amx_emulated_16x64"};
  return &kKernels;
}

const IsaBf16Kernels* Bf16KernelsEmulated() {
  static constexpr IsaBf16Kernels kKernels = {64, EmulatedBf16ConvRows, EmulatedBf16ConvRows,
                                              "conv2d_bf16__amx_emulated_16x64",
                                              "upconv2d_bf16__amx_emulated_16x64"};
  return &kKernels;
}

long EmulatedTileViolations() { return g_violations.load(std::memory_order_relaxed); }

}  // namespace sfrt::amx
