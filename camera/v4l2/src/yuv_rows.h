// Row kernels behind yuv_to_bgr.h's SIMD paths. Each converts the first (width / 16) * 16
// pixels of one row and returns how many it converted; the caller finishes the row with the
// scalar loop. Only the kernels of the machine's architecture are compiled.
#pragma once

#include <cstdint>

namespace sfrt::v4l2::detail {

#if defined(__x86_64__)
int YuyvRowToBgrAvx2(const uint8_t* src, int width, uint8_t* dst);
int Nv12RowToBgrAvx2(const uint8_t* y, const uint8_t* uv, int width, uint8_t* dst);
#endif
#if defined(__aarch64__)
int YuyvRowToBgrNeon(const uint8_t* src, int width, uint8_t* dst);
int Nv12RowToBgrNeon(const uint8_t* y, const uint8_t* uv, int width, uint8_t* dst);
#endif

}  // namespace sfrt::v4l2::detail
