// Whole-model comparisons of one Session configuration against another (usually an optimised
// ISA against the reference path): seeded inputs, one run, and the error measure of issue 4.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "common/relative_error.h"  // RelativeMaxError, used with RunSession
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

}  // namespace sfrt::testing
