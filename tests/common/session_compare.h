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
#include "sfrt/reference.h"
#include "sfrt/session.h"
#include "sfrt/shapes.h"

namespace sfrt::testing {

// Seeded pixels in [0, 255), height x width x channels.
inline std::vector<float> RandomImage(int height, int width, int channels, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(0.0f, 255.0f);
  std::vector<float> v(static_cast<size_t>(height) * width * channels);
  for (float& x : v) x = dist(rng);
  return v;
}

// One Run() of `model` on `input` with a session made with `options` (its maximum size set to
// exactly height x width); the output starts as NaN so anything not written fails the
// comparison. Empty on failure (with a test failure recorded).
inline std::vector<float> RunSession(std::shared_ptr<const Model> model, SessionOptions options,
                                     const std::vector<float>& input, int height, int width) {
  options.max_height = height;
  options.max_width = width;
  auto session = Session::Create(std::move(model), options);
  EXPECT_TRUE(session.ok()) << session.message();
  if (!session.ok()) return {};
  EXPECT_EQ((*session)->isa(), options.isa);
  auto shape = (*session)->OutputShape(height, width);
  EXPECT_TRUE(shape.ok()) << shape.message();
  if (!shape.ok()) return {};
  std::vector<float> out(shape->elements(), NAN);
  const Status s = (*session)->Run(input, height, width, out);
  EXPECT_TRUE(s.ok()) << s.message();
  return s.ok() ? out : std::vector<float>{};
}

// The same with default options but `isa` and `threads`.
inline std::vector<float> RunSession(std::shared_ptr<const Model> model, Isa isa, int threads,
                                     const std::vector<float>& input, int height, int width) {
  SessionOptions options;
  options.isa = isa;
  options.threads = threads;
  return RunSession(std::move(model), options, input, height, width);
}

// Runs `model` at each size on every ISA this CPU runs, with 1 and 2 threads, on seeded input
// of `channels` channels, and expects each output within `tolerance` (RelativeMaxError) of the
// reference forward (sfrt/reference.h).
inline void ExpectEveryIsaMatchesTheReferenceForward(
    const std::shared_ptr<const Model>& model, std::initializer_list<std::pair<int, int>> sizes,
    int channels, double tolerance, uint32_t seed = 4) {
  for (auto [h, w] : sizes) {
    const auto input = RandomImage(h, w, channels, seed);
    auto shape = InferOutputShape(*model, h, w);
    ASSERT_TRUE(shape.ok()) << shape.message();
    std::vector<float> want(shape->elements(), NAN);
    const Status s = RunReferenceForward(*model, input, h, w, want);
    ASSERT_TRUE(s.ok()) << s.message();
    for (Isa isa : SupportedIsas()) {
      for (int threads : {1, 2}) {
        SCOPED_TRACE(std::string(IsaName(isa)) + ", " + std::to_string(threads) + " threads, " +
                     std::to_string(h) + "x" + std::to_string(w));
        const auto got = RunSession(model, isa, threads, input, h, w);
        EXPECT_LE(RelativeMaxError(got, want), tolerance);
      }
    }
  }
}

}  // namespace sfrt::testing
