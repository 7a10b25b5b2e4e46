// cv::imread that reports failure only by an empty result. OpenCV 4.6 throws (cv::Exception,
// or std::bad_alloc for a huge declared size) instead of returning an empty Mat on some damaged
// headers, e.g. a PBM claiming a height over CV_IO_MAX_IMAGE_HEIGHT (found by fuzz_image), and
// one crafted frame must not end a run. Header-only so sfrt_tools_io needs no OpenCV.
#pragma once

#include <exception>
#include <opencv2/imgcodecs.hpp>
#include <string>

namespace sfrt::io {

inline cv::Mat ReadImageOrEmpty(const std::string& path, int flags = cv::IMREAD_COLOR) {
  try {
    return cv::imread(path, flags);
  } catch (const std::exception&) {
    return cv::Mat();
  }
}

}  // namespace sfrt::io
