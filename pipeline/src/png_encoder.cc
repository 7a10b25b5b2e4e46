#include "png_encoder.h"

#include <libdeflate.h>

#include <array>
#include <cstring>
#include <limits>
#include <string>

namespace sfrt::pipeline {
namespace {

constexpr int kLevel = 1;                   // libdeflate's fastest level that still compresses
constexpr uint8_t kFilterNone = 0;          // PNG filter type of the first row (no row above)
constexpr uint8_t kFilterUp = 2;            // PNG filter type: minus the byte above
constexpr uint32_t kMaxChunk = 0x7fffffff;  // PNG: a chunk's length is at most 2^31 - 1

void PutBigEndian32(uint32_t v, std::vector<uint8_t>* out) {
  out->push_back(static_cast<uint8_t>(v >> 24));
  out->push_back(static_cast<uint8_t>(v >> 16));
  out->push_back(static_cast<uint8_t>(v >> 8));
  out->push_back(static_cast<uint8_t>(v));
}

// A chunk: length, type, data, then the CRC-32 of the type and the data.
void PutChunk(const char (&type)[5], const uint8_t* data, uint32_t size,
              std::vector<uint8_t>* out) {
  PutBigEndian32(size, out);
  const size_t type_at = out->size();
  out->insert(out->end(), type, type + 4);
  if (size > 0) out->insert(out->end(), data, data + size);
  PutBigEndian32(libdeflate_crc32(0, out->data() + type_at, 4 + size_t{size}), out);
}

// Row r of `bgr` as PNG stores it: the filter byte, then R, G, B per pixel, each minus the byte
// above it (Up) except on the first row. Unsigned bytes wrap, as the filter's arithmetic is mod
// 256.
void FilterRow(const cv::Mat& bgr, int r, uint8_t* dst) {
  const uint8_t* s = bgr.ptr<uint8_t>(r);
  const size_t bytes = static_cast<size_t>(bgr.cols) * 3;
  uint8_t* d = dst + 1;
  if (r == 0) {
    dst[0] = kFilterNone;
    for (size_t x = 0; x < bytes; x += 3) {
      d[x] = s[x + 2];
      d[x + 1] = s[x + 1];
      d[x + 2] = s[x];
    }
    return;
  }
  dst[0] = kFilterUp;
  const uint8_t* p = bgr.ptr<uint8_t>(r - 1);
  for (size_t x = 0; x < bytes; x += 3) {
    d[x] = static_cast<uint8_t>(s[x + 2] - p[x + 2]);
    d[x + 1] = static_cast<uint8_t>(s[x + 1] - p[x + 1]);
    d[x + 2] = static_cast<uint8_t>(s[x] - p[x]);
  }
}

}  // namespace

void PngEncoder::FreeCompressor::operator()(libdeflate_compressor* c) const {
  libdeflate_free_compressor(c);
}

PngEncoder::PngEncoder() : compressor_(libdeflate_alloc_compressor(kLevel)) {}

PngEncoder::~PngEncoder() = default;

Status PngEncoder::Encode(const cv::Mat& bgr, std::vector<uint8_t>* out) {
  if (bgr.type() != CV_8UC3 || bgr.empty()) {
    return Status::Error("the PNG encoder takes a non-empty 8-bit 3-channel image");
  }
  if (compressor_ == nullptr) return Status::Error("libdeflate: cannot allocate a compressor");
  const size_t row_bytes = 1 + static_cast<size_t>(bgr.cols) * 3;
  filtered_.resize(row_bytes * static_cast<size_t>(bgr.rows));
  for (int r = 0; r < bgr.rows; ++r) FilterRow(bgr, r, filtered_.data() + row_bytes * r);

  compressed_.resize(libdeflate_zlib_compress_bound(compressor_.get(), filtered_.size()));
  const size_t size =
      libdeflate_zlib_compress(compressor_.get(), filtered_.data(), filtered_.size(),
                               compressed_.data(), compressed_.size());
  if (size == 0 || size > kMaxChunk) {  // 0: the bound did not hold, which libdeflate rules out
    return Status::Error("cannot compress a " + std::to_string(bgr.cols) + "x" +
                         std::to_string(bgr.rows) + " picture into one PNG chunk");
  }

  static constexpr std::array<uint8_t, 8> kSignature = {0x89, 'P',  'N',  'G',
                                                        '\r', '\n', 0x1a, '\n'};
  std::array<uint8_t, 13> ihdr{};
  const auto put32 = [&ihdr](size_t at, uint32_t v) {
    for (int i = 0; i < 4; ++i) ihdr[at + i] = static_cast<uint8_t>(v >> (24 - 8 * i));
  };
  put32(0, static_cast<uint32_t>(bgr.cols));
  put32(4, static_cast<uint32_t>(bgr.rows));
  ihdr[8] = 8;   // bit depth
  ihdr[9] = 2;   // colour type: RGB
  ihdr[10] = 0;  // compression: deflate
  ihdr[11] = 0;  // filter method: adaptive, per-row filter byte
  ihdr[12] = 0;  // no interlace

  out->clear();
  out->reserve(kSignature.size() + 3 * 12 + ihdr.size() + size);
  out->insert(out->end(), kSignature.begin(), kSignature.end());
  PutChunk("IHDR", ihdr.data(), static_cast<uint32_t>(ihdr.size()), out);
  PutChunk("IDAT", compressed_.data(), static_cast<uint32_t>(size), out);
  PutChunk("IEND", nullptr, 0, out);
  return Status::Ok();
}

}  // namespace sfrt::pipeline
