#include "sfrt/pipeline/message_io.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace sfrt::pipeline {
namespace {

std::string RawToBgr(const ImageMessage& im, cv::Mat* out) {
  struct Kind {
    const char* encoding;
    int type;
    int code;  // cv::cvtColor code, or -1 for a copy
  };
  static const Kind kKinds[] = {{"bgr8", CV_8UC3, -1},
                                {"rgb8", CV_8UC3, cv::COLOR_RGB2BGR},
                                {"bgra8", CV_8UC4, cv::COLOR_BGRA2BGR},
                                {"rgba8", CV_8UC4, cv::COLOR_RGBA2BGR},
                                {"mono8", CV_8UC1, cv::COLOR_GRAY2BGR}};
  const Kind* kind = nullptr;
  for (const Kind& k : kKinds) {
    if (im.encoding == k.encoding) kind = &k;
  }
  if (kind == nullptr) {
    return "encoding '" + im.encoding +
           "' is not one this reader converts (bgr8, rgb8, bgra8, rgba8, mono8)";
  }
  const size_t row = static_cast<size_t>(im.width) * CV_ELEM_SIZE(kind->type);
  if (im.width == 0 || im.height == 0 || im.step < row ||
      im.size < static_cast<size_t>(im.step) * im.height) {
    return "a " + im.encoding + " image of " + std::to_string(im.height) + "x" +
           std::to_string(im.width) + " (HxW) with step " + std::to_string(im.step) + " holds " +
           std::to_string(im.size) + " bytes, too few";
  }
  const cv::Mat src(static_cast<int>(im.height), static_cast<int>(im.width), kind->type,
                    const_cast<uint8_t*>(im.data), im.step);
  if (kind->code < 0) {
    src.copyTo(*out);
  } else {
    cv::cvtColor(src, *out, kind->code);
  }
  return "";
}

std::string CompressedToBgr(const ImageMessage& im, cv::Mat* out) {
  if (im.size == 0) return "an empty '" + im.encoding + "' image";
  const cv::Mat bytes(1, static_cast<int>(im.size), CV_8UC1, const_cast<uint8_t*>(im.data));
  cv::Mat decoded = cv::imdecode(bytes, cv::IMREAD_COLOR);
  if (decoded.empty()) return "a '" + im.encoding + "' image that could not be decoded";
  decoded.copyTo(*out);
  return "";
}

}  // namespace

std::string ImageMessageToBgr(const ImageMessage& image, cv::Mat* out) {
  return image.compressed ? CompressedToBgr(image, out) : RawToBgr(image, out);
}

}  // namespace sfrt::pipeline
