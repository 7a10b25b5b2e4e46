// The error measure of kernel and whole-model comparisons (issue 4): the largest absolute
// difference relative to the largest reference magnitude.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace sfrt::testing {

// max |got - want| / max(min_scale, max |want|): infinity when sizes differ, `want` is empty,
// the denominator is zero (all-zero `want` with min_scale 0) or `got` holds a non-finite value.
// min_scale > 0 bounds the error absolutely where the reference is small (kernel tests use 1).
inline double RelativeMaxError(const std::vector<float>& got, const std::vector<float>& want,
                               double min_scale = 0.0) {
  if (got.size() != want.size() || want.empty()) return INFINITY;
  double max_ref = min_scale, max_err = 0.0;
  for (size_t i = 0; i < want.size(); ++i) {
    if (!std::isfinite(got[i])) return INFINITY;
    max_ref = std::max(max_ref, std::abs(double(want[i])));
    max_err = std::max(max_err, std::abs(double(got[i]) - double(want[i])));
  }
  return max_ref > 0 ? max_err / max_ref : INFINITY;
}

}  // namespace sfrt::testing
