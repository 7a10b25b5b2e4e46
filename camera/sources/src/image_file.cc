#include "sfrt/camera/image_file.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <opencv2/imgcodecs.hpp>

namespace sfrt::camera {
namespace {

// Reads `size` bytes at `offset` of the file; fewer (or none) past its end.
using ReadAt = std::function<std::string(uint64_t offset, size_t size)>;

uint64_t Be(std::string_view b, size_t at, int n) {
  uint64_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | static_cast<uint8_t>(b[at + i]);
  return v;
}

uint64_t Le(std::string_view b, size_t at, int n) {
  uint64_t v = 0;
  for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<uint8_t>(b[at + i]);
  return v;
}

std::string Dims(int64_t w, int64_t h) { return std::to_string(w) + "x" + std::to_string(h); }

// The refusal of an image of w x h pixels (both > 0) over kMaxImagePixels, or "".
std::string OverLimit(const std::string& format, int64_t w, int64_t h) {
  if (w <= kMaxImagePixels / h) return "";
  return "is a " + format + " declaring " + Dims(w, h) + " pixels, more than the " +
         std::to_string(kMaxImagePixels >> 20) + " Mpx (8192x8192) an image may have";
}

Result<ImageHeader> Png(std::string_view b) {
  if (b.size() < 24 || b.substr(12, 4) != "IHDR") {
    return Status::Error("is a PNG without its IHDR header");
  }
  ImageHeader h{"PNG", static_cast<int64_t>(Be(b, 16, 4)), static_cast<int64_t>(Be(b, 20, 4))};
  if (b.size() >= 26) {
    h.bits = static_cast<uint8_t>(b[24]);
    static constexpr int kChannels[7] = {1, 0, 3, 3, 2, 0, 4};  // by colour type (palette: 3)
    const uint8_t type = static_cast<uint8_t>(b[25]);
    h.channels = type < 7 ? kChannels[type] : 0;
  }
  return h;
}

// The first start-of-frame marker (SOF0-3, 5-7, 9-11, 13-15) before the scan.
Result<ImageHeader> Jpeg(std::string_view b) {
  size_t at = 2;
  while (at + 4 <= b.size()) {
    if (static_cast<uint8_t>(b[at]) != 0xFF)
      return Status::Error("is a JPEG with a damaged marker");
    const uint8_t m = static_cast<uint8_t>(b[at + 1]);
    if (m == 0xFF) {  // fill byte
      ++at;
      continue;
    }
    if (m == 0x01 || (m >= 0xD0 && m <= 0xD8)) {  // markers without a length
      at += 2;
      continue;
    }
    const size_t length = Be(b, at + 2, 2);
    const bool sof = m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC;
    if (sof) {
      if (length < 7 || at + 9 > b.size())
        return Status::Error("is a JPEG with a short frame header");
      ImageHeader h{"JPEG", static_cast<int64_t>(Be(b, at + 7, 2)),
                    static_cast<int64_t>(Be(b, at + 5, 2))};
      h.bits = static_cast<uint8_t>(b[at + 4]);
      if (at + 10 <= b.size()) h.channels = static_cast<uint8_t>(b[at + 9]);
      return h;
    }
    if (m == 0xDA || m == 0xD9 || length < 2) break;  // scan or end before any frame header
    at += 2 + length;
  }
  return Status::Error("is a JPEG without a frame header in its first " + std::to_string(b.size()) +
                       " bytes");
}

// P1-P6: magic, width, height and (but for bitmaps) the maximum value, separated by whitespace
// and comments; the pixel data follows one whitespace byte.
Result<ImageHeader> Pnm(std::string_view b, uint64_t file_size) {
  const char kind = b[1];
  const bool bitmap = kind == '1' || kind == '4';
  int64_t v[3] = {0, 0, 1};
  size_t at = 2;
  for (int k = 0; k < (bitmap ? 2 : 3); ++k) {
    while (at < b.size() && (std::isspace(static_cast<unsigned char>(b[at])) || b[at] == '#')) {
      if (b[at] == '#') {
        while (at < b.size() && b[at] != '\n') ++at;
      } else {
        ++at;
      }
    }
    if (at >= b.size() || !std::isdigit(static_cast<unsigned char>(b[at]))) {
      return Status::Error("is a PNM (P" + std::string(1, kind) + ") with a damaged header");
    }
    int64_t n = 0;
    while (at < b.size() && std::isdigit(static_cast<unsigned char>(b[at]))) {
      n = std::min<int64_t>(n * 10 + (b[at++] - '0'), int64_t{1} << 40);
    }
    v[k] = n;
  }
  const int64_t w = v[0], h = v[1];
  if (w > 0 && h > 0) {
    if (std::string over = OverLimit("PNM", w, h); !over.empty()) return Status::Error(over);
    // Raw: the pixel data's exact size. ASCII: at least one character per sample.
    const int64_t channels = kind == '3' || kind == '6' ? 3 : 1;
    const int64_t bytes_per_sample = v[2] > 255 ? 2 : 1;
    const int64_t need = kind == '4'   ? (w + 7) / 8 * h
                         : kind >= '5' ? w * h * channels * bytes_per_sample
                                       : w * h * channels;
    const int64_t room = static_cast<int64_t>(file_size) - static_cast<int64_t>(at) - 1;
    if (need > room) {
      return Status::Error("is a PNM (P" + std::string(1, kind) + ") declaring " + Dims(w, h) +
                           " pixels, " + std::to_string(need) +
                           " bytes of pixel data, in a file of " + std::to_string(file_size) +
                           " bytes");
    }
  }
  ImageHeader header{"PNM", w, h};
  header.channels = kind == '3' || kind == '6' ? 3 : 1;
  header.bits = bitmap ? 1 : v[2] > 255 ? 16 : 8;
  return header;
}

Result<ImageHeader> Bmp(std::string_view b, uint64_t file_size) {
  if (b.size() < 26) return Status::Error("is a BMP with a short header");
  const uint64_t dib = Le(b, 14, 4);
  int64_t w = 0, h = 0;
  uint64_t bpp = 0, compression = 0;
  if (dib == 12) {
    w = static_cast<int64_t>(Le(b, 18, 2));
    h = static_cast<int64_t>(Le(b, 20, 2));
    bpp = b.size() >= 26 ? Le(b, 24, 2) : 0;
  } else if (dib >= 40 && b.size() >= 34) {
    w = static_cast<int32_t>(Le(b, 18, 4));
    h = static_cast<int32_t>(Le(b, 22, 4));
    bpp = Le(b, 28, 2);
    compression = Le(b, 30, 4);
  } else {
    return Status::Error("is a BMP with an unknown header of " + std::to_string(dib) + " bytes");
  }
  h = h < 0 ? -h : h;
  if (w < 0) return Status::Error("is a BMP with a negative width");
  if (bpp > 64) return Status::Error("is a BMP of " + std::to_string(bpp) + " bits per pixel");
  if (w > 0 && h > 0) {
    if (std::string over = OverLimit("BMP", w, h); !over.empty()) return Status::Error(over);
  }
  if (compression == 0 && bpp > 0 && w > 0 && h > 0) {
    const int64_t row = (static_cast<int64_t>(bpp) * w + 31) / 32 * 4;
    if (row * h > static_cast<int64_t>(file_size)) {
      return Status::Error("is a BMP declaring " + Dims(w, h) + " pixels, " +
                           std::to_string(row * h) + " bytes of pixel data, in a file of " +
                           std::to_string(file_size) + " bytes");
    }
  }
  ImageHeader header{"BMP", w, h};
  header.channels = bpp == 32 ? 4 : bpp >= 16 ? 3 : bpp > 0 ? 3 : 0;  // palettes hold colours
  header.bits = 8;
  return header;
}

Result<ImageHeader> Webp(std::string_view b) {
  if (b.size() >= 30 && b.substr(12, 4) == "VP8 ") {
    return ImageHeader{"WebP", static_cast<int64_t>(Le(b, 26, 2) & 0x3FFF),
                       static_cast<int64_t>(Le(b, 28, 2) & 0x3FFF)};
  }
  if (b.size() >= 25 && b.substr(12, 4) == "VP8L") {
    const uint64_t bits = Le(b, 21, 4);
    return ImageHeader{"WebP", static_cast<int64_t>((bits & 0x3FFF) + 1),
                       static_cast<int64_t>(((bits >> 14) & 0x3FFF) + 1)};
  }
  if (b.size() >= 30 && b.substr(12, 4) == "VP8X") {
    return ImageHeader{"WebP", static_cast<int64_t>(Le(b, 24, 3) + 1),
                       static_cast<int64_t>(Le(b, 27, 3) + 1)};
  }
  return Status::Error("is a WebP (RIFF) file without a VP8, VP8L or VP8X image");
}

// The first image file directory's ImageWidth (256) and ImageLength (257) tags.
Result<ImageHeader> Tiff(std::string_view b, const ReadAt& read) {
  const bool little = b[0] == 'I';
  auto get = [little](std::string_view s, size_t at, int n) {
    return little ? Le(s, at, n) : Be(s, at, n);
  };
  const uint64_t ifd = get(b, 4, 4);
  const std::string count_bytes = read(ifd, 2);
  if (count_bytes.size() < 2)
    return Status::Error("is a TIFF whose first directory is past its end");
  const uint64_t count = get(count_bytes, 0, 2);
  const std::string entries = read(ifd + 2, static_cast<size_t>(count) * 12);
  if (entries.size() < count * 12) return Status::Error("is a TIFF with a truncated directory");
  int64_t dims[2] = {-1, -1};
  for (uint64_t i = 0; i < count; ++i) {
    const size_t e = static_cast<size_t>(i) * 12;
    const uint64_t tag = get(entries, e, 2), type = get(entries, e + 2, 2);
    if (tag != 256 && tag != 257) continue;
    const uint64_t value = type == 3 ? get(entries, e + 8, 2) : get(entries, e + 8, 4);
    dims[tag - 256] = static_cast<int64_t>(value);
  }
  if (dims[0] < 0 || dims[1] < 0)
    return Status::Error("is a TIFF without its image width and length");
  return ImageHeader{"TIFF", dims[0], dims[1]};
}

Result<ImageHeader> Peek(std::string_view b, uint64_t file_size, const ReadAt& read) {
  Result<ImageHeader> h =
      Status::Error("is not an image this reader decodes (PNG, JPEG, PNM P1-P6, BMP, WebP, TIFF)");
  if (b.size() >= 8 && b.substr(0, 8) == "\x89PNG\r\n\x1a\n") {
    h = Png(b);
  } else if (b.size() >= 3 && b.substr(0, 2) == "\xFF\xD8") {
    h = Jpeg(b);
  } else if (b.size() >= 3 && b[0] == 'P' && b[1] >= '1' && b[1] <= '6') {
    h = Pnm(b, file_size);
  } else if (b.size() >= 2 && b.substr(0, 2) == "BM") {
    h = Bmp(b, file_size);
  } else if (b.size() >= 16 && b.substr(0, 4) == "RIFF" && b.substr(8, 4) == "WEBP") {
    h = Webp(b);
  } else if (b.size() >= 8 && (b.substr(0, 4) == std::string_view("II*\0", 4) ||
                               b.substr(0, 4) == std::string_view("MM\0*", 4))) {
    h = Tiff(b, read);
  }
  if (!h.ok()) return h;
  if (h->width <= 0 || h->height <= 0) {
    return Status::Error("is a " + h->format + " declaring " + Dims(h->width, h->height) +
                         " pixels");
  }
  if (std::string over = OverLimit(h->format, h->width, h->height); !over.empty()) {
    return Status::Error(over);
  }
  return h;
}

constexpr size_t kHeadBytes = size_t{1} << 16;
constexpr const char* kCannotRead = "cannot be read";

// Reads from `in` at an offset, at most 16 x kHeadBytes at a time (a TIFF directory).
ReadAt FileReader(std::ifstream& in) {
  return [&in](uint64_t offset, size_t n) {
    in.clear();
    in.seekg(static_cast<std::streamoff>(offset));
    std::string s(std::min<size_t>(n, kHeadBytes * 16), '\0');
    in.read(s.data(), static_cast<std::streamsize>(s.size()));
    s.resize(static_cast<size_t>(std::max<std::streamsize>(in.gcount(), 0)));
    return s;
  };
}

}  // namespace

Result<ImageHeader> PeekImageHeader(std::string_view bytes, uint64_t file_size) {
  const ReadAt read = [bytes](uint64_t offset, size_t size) {
    if (offset >= bytes.size()) return std::string();
    return std::string(bytes.substr(static_cast<size_t>(offset), size));
  };
  return Peek(bytes.substr(0, kHeadBytes), file_size, read);
}

std::string NotEightBitColour(const ImageHeader& h) {
  std::string what = h.channels == 1 || h.channels == 2 ? "grayscale" : "";
  if (h.bits == 16) what += what.empty() ? "16-bit" : ", 16-bit";
  return what;
}

Result<ImageHeader> ReadImageHeader(const std::string& path) {
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  if (ec || !in) return Status::Error(kCannotRead);
  const ReadAt read = FileReader(in);
  return Peek(read(0, kHeadBytes), size, read);
}

std::string ReadImageFile(const std::string& path, int flags, cv::Mat* out, uint64_t* decoded) {
  namespace fs = std::filesystem;
  out->release();
  std::error_code ec;
  if (!fs::exists(path, ec)) return "missing";
  if (!fs::is_regular_file(path, ec)) return "not a regular file";
  Result<ImageHeader> header = ReadImageHeader(path);
  if (!header.ok()) {
    return header.message() == kCannotRead ? header.message()
                                           : "could not be decoded: it " + header.message();
  }
  if (decoded != nullptr) ++*decoded;
  try {
    *out = cv::imread(path, flags);
  } catch (const cv::Exception& e) {
    // imread throws, not fails, on some damaged headers (a PBM claiming a height over
    // CV_IO_MAX_IMAGE_HEIGHT: found by fuzz_image).
    out->release();
    return "could not be decoded as an image (" + e.err + ")";
  } catch (const std::exception& e) {  // std::bad_alloc for a huge declared size
    out->release();
    return std::string("could not be decoded as an image (") + e.what() + ")";
  }
  if (out->empty()) return "could not be decoded as an image (corrupt or unsupported)";
  return "";
}

}  // namespace sfrt::camera
