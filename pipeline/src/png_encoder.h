// The visualisation's PNG encoder, built for a picture a frame (issue #38: the default outputs at
// most 4 ms a frame at 96x128). Each row gets PNG's "Up" filter (the pictures are smooth down the
// columns) and the whole image is compressed in one call by libdeflate at level 1, which is
// faster than zlib's streaming deflate and makes a smaller file: a 236x384 flow picture in about
// 1.2 ms against 1.8 ms for libpng with zlib level 1 and run-length matching
// (tools/bench/README.md). The PNG container (signature, IHDR, one IDAT, IEND, each chunk with its
// CRC-32) is written here, as the PNG specification lays it out. Lossless: any PNG decoder reads
// back the exact pixels (tests/pipeline/png_encoder_test.cc decodes with OpenCV's libpng
// reader).
//
// One encoder per writing thread: it keeps the compressor and the filtered rows between frames,
// so a run of same-sized pictures allocates nothing after the first.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "sfrt/status.h"

struct libdeflate_compressor;

namespace sfrt::pipeline {

class PngEncoder {
 public:
  PngEncoder();
  ~PngEncoder();
  PngEncoder(const PngEncoder&) = delete;
  PngEncoder& operator=(const PngEncoder&) = delete;

  // Encodes an 8-bit 3-channel BGR image (rows may be padded) as an 8-bit RGB PNG into *out,
  // which is cleared and refilled (a caller that keeps it reuses its capacity). Errors say why.
  Status Encode(const cv::Mat& bgr, std::vector<uint8_t>* out);

 private:
  struct FreeCompressor {
    void operator()(libdeflate_compressor* c) const;
  };
  std::unique_ptr<libdeflate_compressor, FreeCompressor> compressor_;
  std::vector<uint8_t> filtered_;    // each row: the filter byte, then the filtered RGB bytes
  std::vector<uint8_t> compressed_;  // the zlib stream that the IDAT chunk holds
};

}  // namespace sfrt::pipeline
