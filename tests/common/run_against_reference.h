// One whole-model run against a reference output held in NPY files (PyTorch's, from the fixture
// generators): pytorch_parity_test (models imported in the test) and exported_model_parity_test
// (model files exported on the host, run on a cross build) share it.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "common/relative_error.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/io/npy.h"
#include "sfrt/session.h"

namespace sfrt::testing {

// One line of a fixture directory's cases.txt (tests/fixtures/gen_sceneednet.py): the file stem
// and the input size.
struct ReferenceCase {
  std::string name;
  int height = 0;
  int width = 0;
};

// The cases listed in `dir`/cases.txt, "NAME HEIGHT WIDTH" per line; lines that do not parse are
// skipped (callers require a minimum count, so a missing list fails).
inline std::vector<ReferenceCase> ReadReferenceCases(const std::string& dir) {
  std::vector<ReferenceCase> cases;
  std::ifstream in(dir + "/cases.txt");
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    ReferenceCase c;
    if (fields >> c.name >> c.height >> c.width) cases.push_back(c);
  }
  return cases;
}

// Runs `model` on `isa` at the size of `input` (H, W, C) and returns RelativeMaxError of its
// output against `expected`, which must have the session's output shape; infinity, with a test
// failure saying why, when anything does not load, plan, run or match in shape. Prints one line
// naming `label`.
inline double RelativeErrorOfRun(const std::shared_ptr<const Model>& model,
                                 const io::NpyArray& input, const io::NpyArray& expected, Isa isa,
                                 const std::string& label) {
  if (input.shape.size() != 3) {
    ADD_FAILURE() << label << ": the input is not (H, W, C)";
    return INFINITY;
  }
  const int h = static_cast<int>(input.shape[0]), w = static_cast<int>(input.shape[1]);
  SessionOptions options;
  options.max_height = h;
  options.max_width = w;
  options.isa = isa;
  auto session = Session::Create(model, options);
  EXPECT_TRUE(session.ok()) << label << ": " << session.message();
  if (!session.ok()) return INFINITY;
  const Result<TensorShape> shape = (*session)->OutputShape(h, w);
  EXPECT_TRUE(shape.ok()) << label << ": " << shape.message();
  if (!shape.ok()) return INFINITY;
  EXPECT_EQ(expected.shape, (std::vector<int64_t>{shape->height, shape->width, shape->channels}))
      << label;
  if (expected.data.size() != shape->elements()) return INFINITY;
  std::vector<float> out(expected.data.size());
  const Status s = (*session)->Run(input.data, h, w, out);
  EXPECT_TRUE(s.ok()) << label << ": " << s.message();
  if (!s.ok()) return INFINITY;
  const double relative = RelativeMaxError(out, expected.data);
  std::printf("  %-10s %-52s %4dx%-4d relative error %.3g\n", IsaName(isa), label.c_str(), h, w,
              relative);
  return relative;
}

}  // namespace sfrt::testing
