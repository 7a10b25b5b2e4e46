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
// (the usual scene-flow definitions: one of the two conditions is enough; ACC as FlowNet3D's
// (Liu et al., CVPR 2019), whose code compares with <=, and the outliers as HPLFlowNet's (Gu et
// al., CVPR 2019), whose code writes all three with < and >, as here). They apply to every pixel
// with ground truth; eval/conventions.h scores each paper's own mask and rules. The thresholds
// are the ShareRule table below, which the metric, the `sfrt eval --help` text and the JSON's
// "definitions" all read.
// Thresholds are absolute, in scene units: they assume the FlyingThings3D scale (baseline 1).
// A robot's metric data moves far less per frame (the default model's scenes: about 0.02 m), so
// there zero flow passes ACC.05 and ACC.10 whatever its error: Thresholds::kRelative
// keeps only the relative conditions (EPE/|gt| below or above the same percentages), which do
// not depend on the scene's scale. The ground truth's median |g| (FlowMetrics::gt_median) tells
// which case a data set is; sfrt eval prints a note when it is below the absolute thresholds.
// Pixels with non-finite ground truth are skipped. A non-finite prediction at a valid pixel
// counts as an infinite error (the mean EPE becomes infinite, the pixel is an outlier).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "sfrt/status.h"

namespace sfrt::eval {

// One share metric: the pixels whose EPE or relative error passes a threshold. A "below" rule
// (ACC) counts a pixel when EPE < epe_threshold OR relative < relative_threshold; an "above"
// rule (outliers) when EPE > epe_threshold OR relative > relative_threshold.
// Which conditions a share rule uses: both (FlowNet3D's definitions, the default) or only the
// relative one ("absolute" / "relative", as `sfrt eval --thresholds` spells them).
enum class Thresholds { kAbsolute, kRelative };
const char* ThresholdsName(Thresholds thresholds);

struct ShareRule {
  const char* key;            // JSON key and FlowMetrics field, e.g. "acc05"
  const char* label;          // column of the printed table, e.g. "ACC.05"
  bool above;                 // true: counts errors above the thresholds
  double epe_threshold;       // absolute, scene units
  double relative_threshold;  // EPE / |gt|: 0.05 = 5%

  constexpr bool Counts(double epe, double relative,
                        Thresholds thresholds = Thresholds::kAbsolute) const {
    const bool absolute = thresholds == Thresholds::kAbsolute;
    return above ? ((absolute && epe > epe_threshold) || relative > relative_threshold)
                 : ((absolute && epe < epe_threshold) || relative < relative_threshold);
  }
  // "share with EPE > 0.3 or EPE/|gt| > 10%" (kRelative: "share with EPE/|gt| > 10%").
  std::string Definition(Thresholds thresholds = Thresholds::kAbsolute) const;
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
  // The median |g| of the valid pixels, from a histogram of 100 bins per decade (within 1.2%):
  // the data set's scale of motion, to judge the absolute thresholds against.
  double gt_median = 0;
};

// Sums over any number of frames; Metrics() gives the means and shares (all 0 when no pixel
// was valid). Sums are in double, so the order of Add() calls does not matter beyond rounding.
class MetricsAccumulator {
 public:
  MetricsAccumulator() = default;
  explicit MetricsAccumulator(Thresholds thresholds) : thresholds_(thresholds) {}
  // pred, truth: pixels * 3 floats (x, y, z interleaved). pred == nullptr means zero flow.
  void Add(const float* pred, const float* truth, size_t pixels);
  void Merge(const MetricsAccumulator& other);
  FlowMetrics Metrics() const;
  // The raw sums and counts, for a shard's partial result (eval/shards.h) that merges exactly:
  // doubles as hexadecimal floats (exact, infinities included), the histogram as its non-empty
  // bins. FromState refuses a malformed state, naming the key.
  nlohmann::json State() const;
  static Result<MetricsAccumulator> FromState(const nlohmann::json& state, Thresholds thresholds);
  size_t valid_pixels() const { return valid_; }

 private:
  double sum_epe_ = 0;
  double sum_abs_[3] = {0, 0, 0};
  size_t acc05_ = 0;
  size_t acc10_ = 0;
  size_t outliers_ = 0;
  size_t valid_ = 0;
  size_t skipped_ = 0;
  Thresholds thresholds_ = Thresholds::kAbsolute;
  // |g| in log bins: bin 0 holds |g| below 10^kLowestDecade (zero motion included).
  static constexpr int kBinsPerDecade = 100;
  static constexpr int kLowestDecade = -9;
  static constexpr int kBins = 18 * kBinsPerDecade + 2;  // 1e-9 .. 1e9, and the two ends
  std::array<uint64_t, kBins> gt_bins_{};
};

// A shard's partial sums written exactly: a double as a hexadecimal float ("%a", infinities
// included), read back bit for bit; a count. The readers' errors name `key`.
std::string ExactDouble(double v);
Result<double> ReadExactDouble(const nlohmann::json& value, const std::string& key);
Result<uint64_t> ReadCount(const nlohmann::json& state, const char* key);

}  // namespace sfrt::eval
