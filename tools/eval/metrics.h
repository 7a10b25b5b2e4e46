// Scene-flow accuracy metrics over pixels with ground truth.
//
// For a valid pixel (all three ground-truth components finite) with predicted flow p and true
// flow g (3D vectors, the dataset's scene units):
//   EPE       = |p - g| (Euclidean)
//   relative  = EPE / |g|  (+infinity when |g| = 0 and EPE > 0; 0 when both are 0)
//   epe3d     = mean EPE;  epe_x, epe_y, epe_z = mean |p_c - g_c| per component
//   acc05     = share of pixels with EPE < 0.05 OR relative < 5%
//   acc10     = share of pixels with EPE < 0.1  OR relative < 10%
//   outliers  = share of pixels with EPE > 0.3  OR relative > 10%   (issue #7's wording,
//               "EPE over 0.3 or over 10% relative"; the same as FlowNet3D's definition)
// Thresholds are absolute, in scene units: they assume the FlyingThings3D scale (baseline 1).
// Pixels with non-finite ground truth are skipped. A non-finite prediction at a valid pixel
// counts as an infinite error (the mean EPE becomes infinite, the pixel is an outlier).
#pragma once

#include <cstddef>

namespace sfrt::eval {

struct FlowMetrics {
  double epe3d = 0;
  double epe_x = 0;
  double epe_y = 0;
  double epe_z = 0;
  double acc05 = 0;
  double acc10 = 0;
  double outliers = 0;
  size_t valid_pixels = 0;    // pixels with finite ground truth
  size_t skipped_pixels = 0;  // pixels without (not part of any mean)
};

// Sums over any number of frames; Metrics() gives the means and shares (all 0 when no pixel
// was valid). Sums are in double, so the order of Add() calls does not matter beyond rounding.
class MetricsAccumulator {
 public:
  // pred, truth: pixels * 3 floats (x, y, z interleaved). pred == nullptr means zero flow.
  void Add(const float* pred, const float* truth, size_t pixels);
  void Merge(const MetricsAccumulator& other);
  FlowMetrics Metrics() const;
  size_t valid_pixels() const { return valid_; }

 private:
  double sum_epe_ = 0;
  double sum_abs_[3] = {0, 0, 0};
  size_t acc05_ = 0;
  size_t acc10_ = 0;
  size_t outliers_ = 0;
  size_t valid_ = 0;
  size_t skipped_ = 0;
};

}  // namespace sfrt::eval
