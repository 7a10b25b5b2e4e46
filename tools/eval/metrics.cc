#include "eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <nlohmann/json.hpp>

namespace sfrt::eval {

const char* ThresholdsName(Thresholds thresholds) {
  return thresholds == Thresholds::kAbsolute ? "absolute" : "relative";
}

std::string ShareRule::Definition(Thresholds thresholds) const {
  const char* op = above ? ">" : "<";
  char text[96];
  if (thresholds == Thresholds::kRelative) {
    std::snprintf(text, sizeof(text), "share with EPE/|gt| %s %g%%", op, relative_threshold * 100);
  } else {
    std::snprintf(text, sizeof(text), "share with EPE %s %g or EPE/|gt| %s %g%%", op, epe_threshold,
                  op, relative_threshold * 100);
  }
  return text;
}

void MetricsAccumulator::Add(const float* pred, const float* truth, size_t pixels) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < pixels; ++i) {
    const float* g = truth + 3 * i;
    if (!std::isfinite(g[0]) || !std::isfinite(g[1]) || !std::isfinite(g[2])) {
      ++skipped_;
      continue;
    }
    ++valid_;
    double diff[3];
    bool finite = true;
    for (int c = 0; c < 3; ++c) {
      const double p = pred == nullptr ? 0.0 : static_cast<double>(pred[3 * i + c]);
      if (!std::isfinite(p)) finite = false;
      diff[c] = p - static_cast<double>(g[c]);
    }
    double epe = kInf;
    if (finite) {
      epe = std::sqrt(diff[0] * diff[0] + diff[1] * diff[1] + diff[2] * diff[2]);
      for (int c = 0; c < 3; ++c) sum_abs_[c] += std::fabs(diff[c]);
    } else {
      for (double& s : sum_abs_) s = kInf;
    }
    sum_epe_ += epe;
    const double norm =
        std::sqrt(static_cast<double>(g[0]) * g[0] + static_cast<double>(g[1]) * g[1] +
                  static_cast<double>(g[2]) * g[2]);
    const double rel = norm > 0 ? epe / norm : (epe > 0 ? kInf : 0.0);
    if (kAcc05.Counts(epe, rel, thresholds_)) ++acc05_;
    if (kAcc10.Counts(epe, rel, thresholds_)) ++acc10_;
    if (kOutliers.Counts(epe, rel, thresholds_)) ++outliers_;
    const double position = norm > 0 ? (std::log10(norm) - kLowestDecade) * kBinsPerDecade : -1;
    ++gt_bins_[static_cast<size_t>(std::clamp(std::floor(position) + 1, 0.0, double{kBins - 1}))];
  }
}

void MetricsAccumulator::Merge(const MetricsAccumulator& other) {
  sum_epe_ += other.sum_epe_;
  for (int c = 0; c < 3; ++c) sum_abs_[c] += other.sum_abs_[c];
  acc05_ += other.acc05_;
  acc10_ += other.acc10_;
  outliers_ += other.outliers_;
  valid_ += other.valid_;
  skipped_ += other.skipped_;
  for (size_t b = 0; b < gt_bins_.size(); ++b) gt_bins_[b] += other.gt_bins_[b];
}

std::string ExactDouble(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%a", v);
  return buf;
}

Result<double> ReadExactDouble(const nlohmann::json& value, const std::string& key) {
  if (!value.is_string()) return Status::Error(key + ": expected a hexadecimal float string");
  const std::string text = value.get<std::string>();
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0') return Status::Error(key + ": '" + text + "' is not a number");
  return v;
}

Result<uint64_t> ReadCount(const nlohmann::json& state, const char* key) {
  if (!state.contains(key) || !state[key].is_number_unsigned()) {
    return Status::Error(std::string(key) + ": expected a count");
  }
  return state[key].get<uint64_t>();
}

nlohmann::json MetricsAccumulator::State() const {
  nlohmann::json s;
  s["sum_epe"] = ExactDouble(sum_epe_);
  s["sum_abs"] = {ExactDouble(sum_abs_[0]), ExactDouble(sum_abs_[1]), ExactDouble(sum_abs_[2])};
  s["acc05"] = acc05_;
  s["acc10"] = acc10_;
  s["outliers"] = outliers_;
  s["valid"] = valid_;
  s["skipped"] = skipped_;
  nlohmann::json bins = nlohmann::json::array();
  for (size_t b = 0; b < gt_bins_.size(); ++b) {
    if (gt_bins_[b] != 0) bins.push_back({b, gt_bins_[b]});
  }
  s["gt_bins"] = bins;
  return s;
}

Result<MetricsAccumulator> MetricsAccumulator::FromState(const nlohmann::json& s,
                                                         Thresholds thresholds) {
  MetricsAccumulator m(thresholds);
  if (!s.is_object()) return Status::Error("metrics state: expected an object");
  Result<double> sum = ReadExactDouble(s.value("sum_epe", nlohmann::json()), "sum_epe");
  if (!sum.ok()) return sum.status();
  m.sum_epe_ = *sum;
  if (!s.contains("sum_abs") || !s["sum_abs"].is_array() || s["sum_abs"].size() != 3) {
    return Status::Error("sum_abs: expected 3 hexadecimal floats");
  }
  for (int c = 0; c < 3; ++c) {
    Result<double> v = ReadExactDouble(s["sum_abs"][c], "sum_abs");
    if (!v.ok()) return v.status();
    m.sum_abs_[c] = *v;
  }
  size_t* counts[] = {&m.acc05_, &m.acc10_, &m.outliers_, &m.valid_, &m.skipped_};
  const char* keys[] = {"acc05", "acc10", "outliers", "valid", "skipped"};
  for (int i = 0; i < 5; ++i) {
    Result<uint64_t> n = ReadCount(s, keys[i]);
    if (!n.ok()) return n.status();
    *counts[i] = static_cast<size_t>(*n);
  }
  if (!s.contains("gt_bins") || !s["gt_bins"].is_array()) {
    return Status::Error("gt_bins: expected [bin, count] pairs");
  }
  for (const nlohmann::json& pair : s["gt_bins"]) {
    if (!pair.is_array() || pair.size() != 2 || !pair[0].is_number_unsigned() ||
        !pair[1].is_number_unsigned() || pair[0].get<uint64_t>() >= m.gt_bins_.size()) {
      return Status::Error("gt_bins: expected [bin, count] pairs with bins below " +
                           std::to_string(m.gt_bins_.size()));
    }
    m.gt_bins_[pair[0].get<size_t>()] = pair[1].get<uint64_t>();
  }
  return m;
}

FlowMetrics MetricsAccumulator::Metrics() const {
  FlowMetrics m;
  m.valid_pixels = valid_;
  m.skipped_pixels = skipped_;
  if (valid_ == 0) return m;
  const double n = static_cast<double>(valid_);
  m.epe3d = sum_epe_ / n;
  m.epe_x = sum_abs_[0] / n;
  m.epe_y = sum_abs_[1] / n;
  m.epe_z = sum_abs_[2] / n;
  m.acc05 = static_cast<double>(acc05_) / n;
  m.acc10 = static_cast<double>(acc10_) / n;
  m.outliers = static_cast<double>(outliers_) / n;
  // The bin holding the middle pixel, read at its geometric centre (0 for the zero bin).
  uint64_t seen = 0;
  for (size_t b = 0; b < gt_bins_.size(); ++b) {
    seen += gt_bins_[b];
    if (2 * seen < valid_) continue;
    m.gt_median =
        b == 0 ? 0.0
               : std::pow(10.0, kLowestDecade + (static_cast<double>(b) - 0.5) / kBinsPerDecade);
    break;
  }
  return m;
}

}  // namespace sfrt::eval
