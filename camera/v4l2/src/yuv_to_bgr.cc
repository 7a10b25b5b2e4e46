#include "sfrt/camera/v4l2/yuv_to_bgr.h"

#include <algorithm>
#include <cstddef>
#include <cstring>

#include "yuv_rows.h"

namespace sfrt::v4l2 {
namespace {

uint8_t Clamp8(int v) { return static_cast<uint8_t>(std::clamp(v, 0, 255)); }

// BT.601 limited range, 8-bit fixed point. The chroma terms of a pixel (with the rounding
// constant) are computed once per chroma sample and shared by the pixels that use it.
struct Chroma {
  int b, g, r;
};

inline Chroma ChromaTerms(int cb, int cr) {
  const int d = cb - 128;
  const int e = cr - 128;
  return {516 * d + 128, -100 * d - 208 * e + 128, 409 * e + 128};
}

inline void ChromaToBgrPixel(int y, const Chroma& k, uint8_t* bgr) {
  const int c = 298 * (y - 16);
  bgr[0] = Clamp8((c + k.b) >> 8);
  bgr[1] = Clamp8((c + k.g) >> 8);
  bgr[2] = Clamp8((c + k.r) >> 8);
}

// The row kernels of the fastest path, or null for the scalar loop alone.
struct RowKernels {
  int (*yuyv)(const uint8_t*, int, uint8_t*) = nullptr;
  int (*nv12)(const uint8_t*, const uint8_t*, int, uint8_t*) = nullptr;
  const char* name = "scalar";
};

RowKernels DetectRowKernels() {
  RowKernels k;
#if defined(__x86_64__)
  if (__builtin_cpu_supports("avx2")) {  // libgcc also checks that the OS saves the AVX state
    k = {detail::YuyvRowToBgrAvx2, detail::Nv12RowToBgrAvx2, "avx2"};
  }
#elif defined(__aarch64__)
  k = {detail::YuyvRowToBgrNeon, detail::Nv12RowToBgrNeon, "neon"};  // NEON is baseline
#endif
  return k;
}

const RowKernels& Fastest() {
  static const RowKernels kernels = DetectRowKernels();
  return kernels;
}

}  // namespace

const char* RawConvertPathName() { return Fastest().name; }

void YuvToBgrPixel(int y, int cb, int cr, uint8_t* bgr) {
  ChromaToBgrPixel(y, ChromaTerms(cb, cr), bgr);
}

void YuyvToBgr(const uint8_t* src, int src_stride, int width, int height, uint8_t* dst,
               int dst_stride, RawConvertPath path) {
  const auto row_kernel = path == RawConvertPath::kFastest ? Fastest().yuyv : nullptr;
  for (int row = 0; row < height; ++row) {
    const uint8_t* s = src + static_cast<size_t>(row) * src_stride;
    uint8_t* d = dst + static_cast<size_t>(row) * dst_stride;
    int x = row_kernel != nullptr ? row_kernel(s, width, d) : 0;  // even: whole chroma pairs
    s += 2 * x;
    d += 3 * x;
    // Each 4-byte group Y0 Cb Y1 Cr holds two pixels sharing one chroma sample.
    for (; x + 1 < width; x += 2, s += 4, d += 6) {
      const Chroma k = ChromaTerms(s[1], s[3]);
      ChromaToBgrPixel(s[0], k, d);
      ChromaToBgrPixel(s[2], k, d + 3);
    }
    if (x < width) ChromaToBgrPixel(s[0], ChromaTerms(s[1], s[3]), d);  // odd width: last pixel
  }
}

void Nv12ToBgr(const uint8_t* y_plane, int y_stride, const uint8_t* uv_plane, int uv_stride,
               int width, int height, uint8_t* dst, int dst_stride, RawConvertPath path) {
  const auto row_kernel = path == RawConvertPath::kFastest ? Fastest().nv12 : nullptr;
  for (int row = 0; row < height; ++row) {
    const uint8_t* ys = y_plane + static_cast<size_t>(row) * y_stride;
    // One Cb Cr pair covers a 2x2 block of luma samples.
    const uint8_t* uvs = uv_plane + static_cast<size_t>(row / 2) * uv_stride;
    uint8_t* d = dst + static_cast<size_t>(row) * dst_stride;
    int x = row_kernel != nullptr ? row_kernel(ys, uvs, width, d) : 0;
    for (; x < width; x += 2) {
      const uint8_t* uv = uvs + x;
      const Chroma k = ChromaTerms(uv[0], uv[1]);
      ChromaToBgrPixel(ys[x], k, d + 3 * x);
      if (x + 1 < width) ChromaToBgrPixel(ys[x + 1], k, d + 3 * x + 3);
    }
  }
}

void GreyToBgr(const uint8_t* src, int src_stride, int width, int height, uint8_t* dst,
               int dst_stride) {
  for (int row = 0; row < height; ++row) {
    const uint8_t* s = src + static_cast<size_t>(row) * src_stride;
    uint8_t* d = dst + static_cast<size_t>(row) * dst_stride;
    for (int x = 0; x < width; ++x) d[3 * x] = d[3 * x + 1] = d[3 * x + 2] = s[x];
  }
}

void Bgr24ToBgr(const uint8_t* src, int src_stride, int width, int height, uint8_t* dst,
                int dst_stride) {
  for (int row = 0; row < height; ++row) {
    std::memcpy(dst + static_cast<size_t>(row) * dst_stride,
                src + static_cast<size_t>(row) * src_stride, static_cast<size_t>(width) * 3);
  }
}

void Rgb24ToBgr(const uint8_t* src, int src_stride, int width, int height, uint8_t* dst,
                int dst_stride) {
  for (int row = 0; row < height; ++row) {
    const uint8_t* s = src + static_cast<size_t>(row) * src_stride;
    uint8_t* d = dst + static_cast<size_t>(row) * dst_stride;
    for (int x = 0; x < width; ++x) {
      d[3 * x] = s[3 * x + 2];
      d[3 * x + 1] = s[3 * x + 1];
      d[3 * x + 2] = s[3 * x];
    }
  }
}

}  // namespace sfrt::v4l2
