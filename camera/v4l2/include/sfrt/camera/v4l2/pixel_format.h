// Pixel formats from V4L2 buffers to packed BGR8 (3 bytes per pixel, row stride 3*width, the
// layout OpenCV's CV_8UC3 and the model's BGR input use).
//
// Supported: YUYV (YUV 4:2:2 packed), MJPEG (decoded with libjpeg-turbo), GREY (Y8), NV12
// (Y plane then interleaved CbCr at half resolution), BGR24 and RGB24. Every raw converter
// honours the source row stride (V4L2 bytesperline), which drivers often pad.
//
// The raw formats are converted by yuv_to_bgr.h (BT.601 limited range for YUV, SIMD where the
// CPU has it).
//
// Thread-safety: the free functions are pure. A PixelConverter holds a libjpeg-turbo handle and
// must be used by one thread at a time.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "sfrt/camera/status.h"
#include "sfrt/camera/v4l2/yuv_to_bgr.h"  // the raw converters ToBgr uses

namespace sfrt::v4l2 {

// A frame of packed BGR8 pixels with its capture metadata.
struct Frame {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> bgr;  // width * height * 3 bytes, rows top to bottom
  int64_t timestamp_ns = 0;  // CLOCK_MONOTONIC at capture (the driver's buffer timestamp)
  uint32_t sequence = 0;     // the driver's frame counter (counts dropped frames too)
  int64_t dequeue_ns = 0;    // CLOCK_MONOTONIC when this process dequeued the buffer
};

// The bytes of one dequeued buffer, copied out of the driver's memory, with what is needed to
// interpret them.
struct RawFrame {
  uint32_t fourcc = 0;
  int width = 0;
  int height = 0;
  int bytesperline = 0;        // row stride of the (first) plane; 0 for MJPEG
  std::vector<uint8_t> bytes;  // bytes.size() == bytesused of the buffer
  int64_t timestamp_ns = 0;
  uint32_t sequence = 0;
  int64_t dequeue_ns = 0;  // CLOCK_MONOTONIC when the buffer was dequeued (VIDIOC_DQBUF)
};

// "YUYV", "MJPG", ... for a V4L2 fourcc (non-printable bytes shown as '?').
std::string FourccToString(uint32_t fourcc);
// True for the formats this module converts.
bool IsSupportedFourcc(uint32_t fourcc);
// Smallest valid bytesperline for a raw format at this width (0 for compressed formats).
int MinBytesPerLine(uint32_t fourcc, int width);
// Bytes a complete raw frame needs with this stride (0 for compressed formats).
size_t RequiredBytes(uint32_t fourcc, int width, int height, int bytesperline);

// Converts any supported RawFrame to a Frame, reusing out->bgr's storage (no allocation once it
// has reached the frame size). A truncated raw buffer or an undecodable JPEG gives a kFrameError
// Status for that frame; the converter stays usable.
class PixelConverter {
 public:
  PixelConverter();
  ~PixelConverter();
  PixelConverter(const PixelConverter&) = delete;
  PixelConverter& operator=(const PixelConverter&) = delete;

  camera::Status ToBgr(const RawFrame& raw, Frame* out);

 private:
  void ResetJpeg();
  void* jpeg_ = nullptr;  // tjhandle, created on first MJPEG frame
};

// Splits a side-by-side frame (both eyes in one image, each width/2 wide) into two frames.
// left_first: the left eye is the left half (the usual layout); false swaps the halves.
// Timestamp and sequence are copied to both. Width must be even.
camera::Status SplitSideBySide(const Frame& both, bool left_first, Frame* left, Frame* right);

}  // namespace sfrt::v4l2
