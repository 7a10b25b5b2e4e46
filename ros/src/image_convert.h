// An image message's pixels as the pipeline's BGR8, shared by the bag source and the node's topic
// source. Not installed.
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "message_io.h"

namespace sfrt::ros::detail {

// Raw sensor_msgs/Image in bgr8, rgb8, bgra8, rgba8 or mono8, or a CompressedImage (JPEG, PNG:
// anything OpenCV decodes), as BGR8 into *out (its memory reused when the size matches).
// Returns "" when done, else why not, naming the encoding ("encoding 'yuv422' is not one ...").
std::string ImageToBgr(const ImageView& image, cv::Mat* out);

}  // namespace sfrt::ros::detail
