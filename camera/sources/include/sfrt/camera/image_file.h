// Reading one image file safely: the size an image declares is checked before any decoder
// allocates for it.
//
// cv::imread allocates the decoded image from the header's width and height (up to 2^30 pixels)
// before it reads the pixel data, so a 25-byte damaged file can cost gigabytes (fuzz_image: a PBM
// header claiming 42242x20206). ReadImageFile reads the header itself first: PNG (IHDR), JPEG
// (the first SOFn marker), PNM (P1-P6), BMP, WebP (VP8, VP8L, VP8X) and TIFF (the first IFD's
// ImageWidth and ImageLength); any other content is refused, whatever the file's name. An image
// over kMaxImagePixels, or a raw PNM or uncompressed BMP whose pixel data the file cannot hold, is
// refused before decoding.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <string_view>

#include "sfrt/camera/status.h"

namespace sfrt::camera {

// The largest image any reader here decodes: 8192 x 8192 (a 192 MiB BGR frame).
inline constexpr int64_t kMaxImagePixels = int64_t{1} << 26;

struct ImageHeader {
  std::string format;  // "PNG", "JPEG", "PNM", "BMP", "WebP", "TIFF"
  int64_t width = 0;
  int64_t height = 0;
  int channels = 0;  // samples per pixel the file stores (grey 1, colour 3, ...); 0: not read
  int bits = 0;      // bits per sample; 0: not read (WebP, TIFF)
};

// The format and size `bytes` (the start of a file, at least its first 64 KiB or all of it)
// declare, from the header alone. `file_size` is the whole file's size. Errors say what is wrong
// ("is not an image this reader decodes (...)", "declares 42242x20206 pixels, ...").
Result<ImageHeader> PeekImageHeader(std::string_view bytes, uint64_t file_size);

// Checks the header as above, then decodes with cv::imread(path, flags). "" when it decoded,
// otherwise the reason, e.g. "missing", "could not be decoded as an image (...)". *out is empty
// unless it decoded. `decoded`, when given, is incremented when the file reaches the decoder.
std::string ReadImageFile(const std::string& path, int flags, cv::Mat* out,
                          uint64_t* decoded = nullptr);
// The header of the file at `path` alone (nothing is decoded).
Result<ImageHeader> ReadImageHeader(const std::string& path);
// How an image differs from the 8-bit colour every reader here delivers (grey is copied to three
// channels, 16 bits scaled to 8): "grayscale", "16-bit", "grayscale, 16-bit" or "".
std::string NotEightBitColour(const ImageHeader& header);

}  // namespace sfrt::camera
