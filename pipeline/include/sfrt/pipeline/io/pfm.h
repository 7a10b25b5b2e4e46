// Portable FloatMap (.pfm) images, as used by the Scene Flow datasets for disparity and flow.
//
// Layout: three text lines, then raw float32 pixels.
//   line 1: "PF" (3 channels, interleaved) or "Pf" (1 channel)
//   line 2: "<width> <height>"
//   line 3: scale; its sign gives the byte order (negative: little-endian, positive: big-endian)
// Rows are stored bottom-to-top. Readers here accept any whitespace between and around the
// header fields (the Scene Flow files end lines with a space: "Pf \n960 540 \n-1.0\n"); the scale
// line must end with '\n', after which the pixel data starts.
// In memory, images are top-to-bottom, height x width x channels (HWC), float32.
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::io {

struct PfmImage {
  int height = 0;
  int width = 0;
  int channels = 0;         // 1 or 3
  std::vector<float> data;  // height * width * channels, rows top to bottom
};

// Reads a 1- or 3-channel PFM of either byte order. Errors name the file and the header field.
Result<PfmImage> ReadPfm(const std::string& path);

// Parses PFM bytes held in memory; `label` names them in error messages.
Result<PfmImage> ParsePfm(std::string_view bytes, const std::string& label);

// Serialises an image (rows top to bottom, HWC, 1 or 3 channels) as little-endian PFM:
// "PF\n<w> <h>\n-1.0\n" (or "Pf" for one channel), rows written bottom to top.
Result<std::vector<uint8_t>> SerializePfm(std::span<const float> data, int height, int width,
                                          int channels);

// SerializePfm, then writes `path` atomically (temporary file + rename).
Status WritePfm(const std::string& path, std::span<const float> data, int height, int width,
                int channels = 3);

}  // namespace sfrt::io
