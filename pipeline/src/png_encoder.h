// The visualisation's PNG encoder: libpng with the settings that make a flow picture cheap to
// write (issue #38: the default outputs at most 4 ms a frame at 96x128). The "Up" filter on every
// row (the pictures are smooth down the columns) and zlib level 1 with run-length matching encode
// a 236x384 canvas in about 1.9 ms against 3.4 ms for OpenCV's encoder at level 1 (which tries
// every filter per row), for a file about 20% larger. Lossless either way: any PNG decoder reads
// back the exact pixels (tests/tools/pipeline/visualize_test.cc compares with OpenCV's decoder).
//
// `out` is cleared and refilled; a caller that keeps it reuses its capacity.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::pipeline {

// Encodes an 8-bit 3-channel BGR image (rows may be padded) as PNG into *out. Errors say why.
Status EncodePng(const cv::Mat& bgr, std::vector<uint8_t>* out);

}  // namespace sfrt::pipeline
