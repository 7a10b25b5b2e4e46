// Whole-model comparisons of one Session configuration against another (usually an optimised
// ISA against the reference path): seeded inputs, one run, and the error measure of issue 4.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "sfrt/isa.h"
#include "sfrt/session.h"

namespace sfrt::testing {

// Seeded pixels in [0, 255), height x width x channels.
inline std::vector<float> RandomImage(int height, int width, int channels, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(0.0f, 255.0f);
  std::vector<float> v(static_cast<size_t>(height) * width * channels);
  for (float& x : v) x = dist(rng);
  return v;
}

// One Run() of `model` on `input` with a session planned for exactly height x width; the output
// starts as NaN so anything not written fails the comparison. Empty on failure (with a test
// failure recorded).
inline std::vector<float> RunSession(std::shared_ptr<const Model> model, Isa isa, int threads,
                                     const std::vector<float>& input, int height, int width) {
  SessionOptions options;
  options.max_height = height;
  options.max_width = width;
  options.isa = isa;
  options.threads = threads;
  auto session = Session::Create(std::move(model), options);
  EXPECT_TRUE(session.ok()) << session.message();
  if (!session.ok()) return {};
  EXPECT_EQ((*session)->isa(), isa);
  auto shape = (*session)->OutputShape(height, width);
  EXPECT_TRUE(shape.ok()) << shape.message();
  if (!shape.ok()) return {};
  std::vector<float> out(shape->elements(), NAN);
  const Status s = (*session)->Run(input, height, width, out);
  EXPECT_TRUE(s.ok()) << s.message();
  return s.ok() ? out : std::vector<float>{};
}

// max |got - want| / max |want|: infinity when sizes differ, `want` is empty or all zero, or
// `got` holds a non-finite value.
inline double RelativeMaxError(const std::vector<float>& got, const std::vector<float>& want) {
  if (got.size() != want.size() || want.empty()) return INFINITY;
  double max_ref = 0.0, max_err = 0.0;
  for (size_t i = 0; i < want.size(); ++i) {
    if (!std::isfinite(got[i])) return INFINITY;
    max_ref = std::max(max_ref, std::abs(double(want[i])));
    max_err = std::max(max_err, std::abs(double(got[i]) - double(want[i])));
  }
  return max_ref > 0 ? max_err / max_ref : INFINITY;
}

}  // namespace sfrt::testing
