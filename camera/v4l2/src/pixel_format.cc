#include "sfrt/camera/v4l2/pixel_format.h"

#include <linux/videodev2.h>
#include <turbojpeg.h>

#include <algorithm>
#include <cstring>

namespace sfrt::v4l2 {

using camera::ErrorKind;
using camera::Status;

namespace {

bool IsJpeg(uint32_t fourcc) { return fourcc == V4L2_PIX_FMT_MJPEG || fourcc == V4L2_PIX_FMT_JPEG; }

}  // namespace

std::string FourccToString(uint32_t fourcc) {
  std::string s(4, '?');
  for (int i = 0; i < 4; ++i) {
    char c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
    if (c >= 0x20 && c < 0x7f) s[i] = c;
  }
  return s;
}

bool IsSupportedFourcc(uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_YUYV:
    case V4L2_PIX_FMT_MJPEG:
    case V4L2_PIX_FMT_JPEG:
    case V4L2_PIX_FMT_GREY:
    case V4L2_PIX_FMT_NV12:
    case V4L2_PIX_FMT_BGR24:
    case V4L2_PIX_FMT_RGB24:
      return true;
    default:
      return false;
  }
}

int MinBytesPerLine(uint32_t fourcc, int width) {
  switch (fourcc) {
    case V4L2_PIX_FMT_YUYV:
      return 2 * width;
    case V4L2_PIX_FMT_GREY:
    case V4L2_PIX_FMT_NV12:
      return width;
    case V4L2_PIX_FMT_BGR24:
    case V4L2_PIX_FMT_RGB24:
      return 3 * width;
    default:
      return 0;
  }
}

size_t RequiredBytes(uint32_t fourcc, int width, int height, int bytesperline) {
  if (width <= 0 || height <= 0) return 0;
  const size_t row = static_cast<size_t>(MinBytesPerLine(fourcc, width));
  if (row == 0) return 0;
  const size_t stride = static_cast<size_t>(bytesperline);
  if (fourcc == V4L2_PIX_FMT_NV12) {
    // Y plane of `height` rows, then (height+1)/2 rows of interleaved CbCr, same stride.
    const size_t uv_rows = static_cast<size_t>(height + 1) / 2;
    return stride * static_cast<size_t>(height) + stride * (uv_rows - 1) + 2 * ((width + 1) / 2);
  }
  return stride * static_cast<size_t>(height - 1) + row;
}

PixelConverter::PixelConverter() = default;

PixelConverter::~PixelConverter() { ResetJpeg(); }

// A decompressor that failed (bad header, stopped mid-scan) reads the next header as 0x0
// (libjpeg-turbo 2.1), so each failure starts the next frame with a fresh one.
void PixelConverter::ResetJpeg() {
  if (jpeg_ != nullptr) tjDestroy(static_cast<tjhandle>(jpeg_));
  jpeg_ = nullptr;
}

Status PixelConverter::ToBgr(const RawFrame& raw, Frame* out) {
  const std::string name = FourccToString(raw.fourcc);
  if (raw.width <= 0 || raw.height <= 0) {
    return Status::Error(ErrorKind::kInvalidArgument,
                         name + " frame: size " + std::to_string(raw.width) + "x" +
                             std::to_string(raw.height) + " is not positive");
  }
  out->timestamp_ns = raw.timestamp_ns;
  out->sequence = raw.sequence;
  out->dequeue_ns = raw.dequeue_ns;
  const int w = raw.width;
  const int h = raw.height;
  const int dst_stride = 3 * w;

  if (IsJpeg(raw.fourcc)) {
    if (jpeg_ == nullptr) {
      jpeg_ = tjInitDecompress();
      if (jpeg_ == nullptr) {
        return Status::Error(ErrorKind::kSystem,
                             std::string("tjInitDecompress failed: ") + tjGetErrorStr2(nullptr));
      }
    }
    tjhandle tj = static_cast<tjhandle>(jpeg_);
    const std::string what = "MJPEG frame " + std::to_string(raw.sequence) + " (" +
                             std::to_string(raw.bytes.size()) + " bytes): ";
    int jw = 0, jh = 0, subsamp = 0, colorspace = 0;
    if (raw.bytes.empty() || tjDecompressHeader3(tj, raw.bytes.data(), raw.bytes.size(), &jw, &jh,
                                                 &subsamp, &colorspace) != 0) {
      Status s =
          Status::Error(ErrorKind::kFrameError, what + "bad JPEG header: " + tjGetErrorStr2(tj));
      ResetJpeg();
      return s;
    }
    if (jw != w || jh != h) {
      return Status::Error(ErrorKind::kFrameError, what + "JPEG size " + std::to_string(jw) + "x" +
                                                       std::to_string(jh) +
                                                       " differs from the negotiated " +
                                                       std::to_string(w) + "x" + std::to_string(h));
    }
    out->width = w;
    out->height = h;
    out->bgr.resize(static_cast<size_t>(w) * h * 3);
    // STOPONWARNING: a truncated stream ("premature end of data") is an error, not a grey tail.
    if (tjDecompress2(tj, raw.bytes.data(), raw.bytes.size(), out->bgr.data(), w, dst_stride, h,
                      TJPF_BGR, TJFLAG_STOPONWARNING) != 0) {
      Status s =
          Status::Error(ErrorKind::kFrameError, what + "decode failed: " + tjGetErrorStr2(tj));
      ResetJpeg();
      return s;
    }
    return Status::Ok();
  }

  if (!IsSupportedFourcc(raw.fourcc)) {
    return Status::Error(ErrorKind::kUnsupported, "pixel format " + name + " is not supported");
  }
  const int stride = raw.bytesperline;
  if (stride < MinBytesPerLine(raw.fourcc, w)) {
    return Status::Error(ErrorKind::kInvalidArgument,
                         name + " frame: bytesperline " + std::to_string(stride) +
                             " is below the minimum " +
                             std::to_string(MinBytesPerLine(raw.fourcc, w)));
  }
  const size_t need = RequiredBytes(raw.fourcc, w, h, stride);
  if (raw.bytes.size() < need) {
    return Status::Error(ErrorKind::kFrameError,
                         name + " frame " + std::to_string(raw.sequence) + ": bytesused " +
                             std::to_string(raw.bytes.size()) + " is short of the " +
                             std::to_string(need) + " bytes a " + std::to_string(w) + "x" +
                             std::to_string(h) + " frame needs");
  }
  out->width = w;
  out->height = h;
  out->bgr.resize(static_cast<size_t>(w) * h * 3);
  const uint8_t* src = raw.bytes.data();
  uint8_t* dst = out->bgr.data();
  switch (raw.fourcc) {
    case V4L2_PIX_FMT_YUYV:
      YuyvToBgr(src, stride, w, h, dst, dst_stride);
      break;
    case V4L2_PIX_FMT_NV12:
      Nv12ToBgr(src, stride, src + static_cast<size_t>(stride) * h, stride, w, h, dst, dst_stride);
      break;
    case V4L2_PIX_FMT_GREY:
      GreyToBgr(src, stride, w, h, dst, dst_stride);
      break;
    case V4L2_PIX_FMT_BGR24:
      Bgr24ToBgr(src, stride, w, h, dst, dst_stride);
      break;
    case V4L2_PIX_FMT_RGB24:
      Rgb24ToBgr(src, stride, w, h, dst, dst_stride);
      break;
    default:
      break;
  }
  return Status::Ok();
}

Status SplitSideBySide(const Frame& both, bool left_first, Frame* left, Frame* right) {
  if (both.width <= 0 || both.width % 2 != 0 ||
      both.bgr.size() != static_cast<size_t>(both.width) * both.height * 3) {
    return Status::Error(ErrorKind::kInvalidArgument,
                         "side-by-side frame: width " + std::to_string(both.width) +
                             " must be even and positive with width*height*3 bytes");
  }
  const int half = both.width / 2;
  Frame* first = left_first ? left : right;
  Frame* second = left_first ? right : left;
  for (Frame* f : {first, second}) {
    f->width = half;
    f->height = both.height;
    f->timestamp_ns = both.timestamp_ns;
    f->sequence = both.sequence;
    f->dequeue_ns = both.dequeue_ns;
    f->bgr.resize(static_cast<size_t>(half) * both.height * 3);
  }
  const size_t half_row = static_cast<size_t>(half) * 3;
  for (int row = 0; row < both.height; ++row) {
    const uint8_t* s = both.bgr.data() + static_cast<size_t>(row) * both.width * 3;
    std::memcpy(first->bgr.data() + row * half_row, s, half_row);
    std::memcpy(second->bgr.data() + row * half_row, s + half_row, half_row);
  }
  return Status::Ok();
}

}  // namespace sfrt::v4l2
