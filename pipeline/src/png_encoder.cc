#include "png_encoder.h"

#include <png.h>
#include <zlib.h>

#include <csetjmp>
#include <string>

namespace sfrt::pipeline {
namespace {

struct Sink {
  std::vector<uint8_t>* out;
};

void Append(png_structp png, png_bytep data, png_size_t size) {
  auto* sink = static_cast<Sink*>(png_get_io_ptr(png));
  sink->out->insert(sink->out->end(), data, data + size);
}

void Flush(png_structp) {}

// libpng reports errors by longjmp after calling this; the message is kept for the Status.
void OnError(png_structp png, png_const_charp message) {
  auto* text = static_cast<std::string*>(png_get_error_ptr(png));
  *text = message;
  png_longjmp(png, 1);
}

void OnWarning(png_structp, png_const_charp) {}

}  // namespace

Status EncodePng(const cv::Mat& bgr, std::vector<uint8_t>* out) {
  if (bgr.type() != CV_8UC3 || bgr.empty()) {
    return Status::Error("the PNG encoder takes a non-empty 8-bit 3-channel image");
  }
  out->clear();
  std::string error;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, OnError, OnWarning);
  if (png == nullptr) return Status::Error("libpng: cannot create a write structure");
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    return Status::Error("libpng: cannot create an info structure");
  }
  Sink sink{out};
  // Nothing below holds a C++ object with a destructor that a longjmp would skip.
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return Status::Error("libpng: " + error);
  }
  png_set_write_fn(png, &sink, Append, Flush);
  png_set_IHDR(png, info, static_cast<png_uint_32>(bgr.cols), static_cast<png_uint_32>(bgr.rows), 8,
               PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
  png_set_compression_level(png, 1);
  png_set_compression_strategy(png, Z_RLE);
  png_set_bgr(png);  // the rows are BGR as OpenCV holds them
  png_write_info(png, info);
  for (int r = 0; r < bgr.rows; ++r) {
    png_write_row(png, const_cast<png_bytep>(bgr.ptr<uint8_t>(r)));
  }
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return Status::Ok();
}

}  // namespace sfrt::pipeline
