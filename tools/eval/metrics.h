// Scene-flow accuracy metrics over pixels with ground truth.
//
// For a valid pixel (all three ground-truth components finite) with predicted flow p and true
// flow g (3D vectors, the dataset's scene units):
//   EPE       = |p - g| (Euclidean)
//   relative  = EPE / |g|  (+infinity when |g| = 0 and EPE > 0; 0 when both are 0)
//   epe3d     = mean EPE;  epe_x, epe_y, epe_z = mean |p_c - g_c| per component
//   acc05     = share of pixels with EPE < 0.05 OR relative < 5%
//   acc10     = share of pixels with EPE < 0.1  OR relative < 10%
//   outliers  = share of pixels with EPE > 0.3  OR relative > 10%
// (the usual scene-flow definitions, FlowNet3D's (Liu et al., CVPR 2019): one of the two
// conditions is enough). The thresholds are the ShareRule table below, which the metric, the
// `sfrt eval --help` text and the JSON's "definitions" all read.
// Thresholds are absolute, in scene units: they assume the FlyingThings3D scale (baseline 1).
// Pixels with non-finite ground truth are skipped. A non-finite prediction at a valid pixel
// counts as an infinite error (the mean EPE becomes infinite, the pixel is an outlier).
#pragma once

#include <cstddef>
#include <string>

namespace sfrt::eval {

// One share metric: the pixels whose EPE or relative error passes a threshold. A "below" rule
// (ACC) counts a pixel when EPE < epe_threshold OR relative < relative_threshold; an "above"
// rule (outliers) when EPE > epe_threshold OR relative > relative_threshold.
struct ShareRule {
  const char* key;            // JSON key and FlowMetrics field, e.g. "acc05"
  const char* label;          // column of the printed table, e.g. "ACC.05"
  bool above;                 // true: counts errors above the thresholds
  double epe_threshold;       // absolute, scene units
  double relative_threshold;  // EPE / |gt|: 0.05 = 5%

  constexpr bool Counts(double epe, double relative) const {
    return above ? (epe > epe_threshold || relative > relative_threshold)
                 : (epe < epe_threshold || relative < relative_threshold);
  }
  // "share with EPE > 0.3 or EPE/|gt| > 10%".
  std::string Definition() const;
};

inline constexpr ShareRule kAcc05{"acc05", "ACC.05", false, 0.05, 0.05};
inline constexpr ShareRule kAcc10{"acc10", "ACC.10", false, 0.1, 0.1};
inline constexpr ShareRule kOutliers{"outliers", "outliers", true, 0.3, 0.1};
inline constexpr ShareRule kShareRules[] = {kAcc05, kAcc10, kOutliers};

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
