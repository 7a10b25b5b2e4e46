// The frames `sfrt export --calibration PATH` quantises with: the network input as float32, read
// from a .npy or made from a directory of stereo frames the way `sfrt run --replay` and
// `sfrt infer` make it.
#pragma once

#include <string>

#include "sfrt/exporter/quantize.h"
#include "sfrt/model.h"
#include "sfrt/status.h"

namespace sfrt::tools {

// A float32 .npy of shape (H, W, C) (one frame) or (N, H, W, C), C = `channels`, values as
// `sfrt infer --input-npy` takes them; the first `max_frames` frames. Errors name the file.
Result<exporter::CalibrationSet> ReadCalibrationNpy(const std::string& path, int channels,
                                                    int max_frames);

// The first `max_frames` (t, t+1) windows of consecutive stereo pairs in a directory that
// `sfrt run --replay` reads (Scene Flow, KITTI or <seq>/{left,right} layouts), each resized to
// height x width as `sfrt run` resizes and preprocessed as the model's InputDesc prescribes.
// `described` receives one line saying what was read. Errors name the directory.
Result<exporter::CalibrationSet> ReadCalibrationDirectory(const std::string& path,
                                                          const InputDesc& input, int height,
                                                          int width, int max_frames,
                                                          std::string* described);

}  // namespace sfrt::tools
