// Stereo calibration readers: ROS camera_info YAML pairs, Kalibr camchain YAML, OpenCV FileStorage.
//
// All readers produce one StereoCalibration in OpenCV's stereoCalibrate convention. Units of T
// are whatever the file uses (metres for ROS and Kalibr); the rectified baseline comes out in the
// same unit.
//
// Accepted keys (case-sensitive):
//  * ROS camera_info (camera_calibration_parsers YAML), one file per camera:
//      image_width, image_height, camera_matrix{rows:3,cols:3,data[9]},
//      distortion_model (plumb_bob | rational_polynomial | none; empty = none),
//      distortion_coefficients{data[n]}, rectification_matrix{rows:3,cols:3,data[9]},
//      projection_matrix{rows:3,cols:4,data[12]}.
//    The pair's geometry comes from the rectified frames ROS stores: with R1, R2 the
//    rectification matrices and P2's Tx = P2[0][3], Ty = P2[1][3], the right camera sees
//    x2 = R2^T (R1 x1 + (Tx/fx', Ty/fy', 0)), i.e. R = R2^T R1, T = R2^T (Tx/fx', Ty/fy', 0).
//    The left file's projection_matrix must have Tx = 0 and the right file's Tx must be non-zero.
//  * Kalibr camchain: cam0 and cam1 with camera_model (pinhole), intrinsics [fu, fv, pu, pv],
//    distortion_model (radtan | none), distortion_coeffs [k1, k2, p1, p2], resolution [w, h], and
//    cam1.T_cn_cnm1 (4x4, maps cam0 coordinates to cam1: R = its 3x3 block, T = its last column).
//    equidistant / fov / omni models are rejected by name.
//  * OpenCV FileStorage YAML (what cv::FileStorage writes to a .yml/.yaml name, "%YAML:1.0"
//    header included; one file or two, e.g. the stereo_calib sample's intrinsics.yml +
//    extrinsics.yml): K1 or M1 (3x3), D1 (1xN or Nx1, N in {4,5,8,12,14}), K2 or M2, D2, R (3x3
//    matrix, or a 3-vector Rodrigues rotation), T (3-vector); optional image size as image_size /
//    imageSize ([w, h]) or image_width + image_height. A key present in both files is an error.
//    Matrices are opencv-matrix mappings (rows, cols, dt with one channel, data), at most 64x64.
//    The files are parsed with yaml-cpp, never handed to cv::FileStorage (whose parsers crash on
//    damaged files); OpenCV's XML flavour is refused with a hint to save it as YAML.
// Every calibration file is at most 1 MiB (kMaxCalibrationFileBytes in calibration.cc).
//
// Errors: one line naming the file, the key and the offending value, e.g.
//   "right.yaml: key 'projection_matrix' data has 9 values, expected 12".
// Thread-safety: the functions are reentrant; they share no state.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "sfrt/camera/status.h"

namespace sfrt::camera {

struct StereoCalibration {
  cv::Size
      image_size;  // raw image size both cameras were calibrated at; 0x0 when the file lacks it
  cv::Matx33d K1 = cv::Matx33d::eye();  // left intrinsics
  cv::Mat D1;                           // left distortion, 1xN CV_64F (OpenCV order), may be empty
  cv::Matx33d K2 = cv::Matx33d::eye();  // right intrinsics
  cv::Mat D2;
  // Right camera from left camera: x_right = R * x_left + T.
  cv::Matx33d R = cv::Matx33d::eye();
  cv::Vec3d T = {0, 0, 0};
  std::string source;  // the file(s) it came from, for messages
};

Result<StereoCalibration> ReadRosCameraInfoPair(const std::string& left_yaml,
                                                const std::string& right_yaml);
Result<StereoCalibration> ReadKalibrCamchain(const std::string& path);
// paths: one or two FileStorage files whose keys are merged.
Result<StereoCalibration> ReadOpenCvCalibration(const std::vector<std::string>& paths);

// Picks the reader from the content: two files whose top level has camera_matrix -> ROS pair;
// a top level with cam0 and cam1 -> Kalibr; otherwise OpenCV FileStorage.
Result<StereoCalibration> ReadStereoCalibration(const std::vector<std::string>& paths);

}  // namespace sfrt::camera
