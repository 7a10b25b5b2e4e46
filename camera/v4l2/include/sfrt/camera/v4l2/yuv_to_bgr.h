// Raw camera pixels to packed BGR8 (3 bytes per pixel, the layout of OpenCV's CV_8UC3 and the
// model's BGR input). Pure functions of their arguments: no allocation, no state, any thread.
//
// YUV is BT.601 limited range ("studio swing", Y 16..235, Cb/Cr 16..240), what UVC cameras send:
//   R = 1.164 (Y-16) + 1.596 (Cr-128)
//   G = 1.164 (Y-16) - 0.392 (Cb-128) - 0.813 (Cr-128)
//   B = 1.164 (Y-16) + 2.017 (Cb-128)
// computed in 8-bit fixed point (coefficients x256, rounded, clamped to 0..255), within 1 of the
// real-valued formula. Every path gives the same bytes as YuvToBgrPixel: the SIMD ones (AVX2 on
// x86-64 where the CPU has it, chosen at run time; NEON on aarch64) do the same integer
// arithmetic 16 pixels at a time, and the tests compare them with the scalar loop for every
// (Y, Cb, Cr).
#pragma once

#include <cstdint>

namespace sfrt::v4l2 {

// kFastest: the widest SIMD this CPU runs (RawConvertPathName() says which); kScalar: one pixel
// at a time, the oracle of the tests.
enum class RawConvertPath { kFastest, kScalar };
// "avx2", "neon" or "scalar": what kFastest runs on this CPU.
const char* RawConvertPathName();

// One pixel of BT.601 limited-range YCbCr to B, G, R.
void YuvToBgrPixel(int y, int cb, int cr, uint8_t* bgr);

// Raw converters. `dst` receives width*height*3 bytes with row stride dst_stride; every one
// honours the source row stride (V4L2 bytesperline), which drivers often pad.
//   YUYV: 4:2:2 packed, Y0 Cb Y1 Cr per two pixels.
//   NV12: a Y plane, then interleaved Cb Cr at half resolution in both directions.
void YuyvToBgr(const uint8_t* src, int src_stride, int width, int height, uint8_t* dst,
               int dst_stride, RawConvertPath path = RawConvertPath::kFastest);
void Nv12ToBgr(const uint8_t* y_plane, int y_stride, const uint8_t* uv_plane, int uv_stride,
               int width, int height, uint8_t* dst, int dst_stride,
               RawConvertPath path = RawConvertPath::kFastest);
void GreyToBgr(const uint8_t* src, int src_stride, int width, int height, uint8_t* dst,
               int dst_stride);
void Bgr24ToBgr(const uint8_t* src, int src_stride, int width, int height, uint8_t* dst,
                int dst_stride);
void Rgb24ToBgr(const uint8_t* src, int src_stride, int width, int height, uint8_t* dst,
                int dst_stride);

}  // namespace sfrt::v4l2
