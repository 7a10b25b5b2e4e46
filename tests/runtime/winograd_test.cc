// The Winograd F(2x2, 3x3) and F(4x4, 3x3) paths against the direct reference convolution
// (ref::Conv2d, the oracle): the scalar Winograd reference (kernels/ref/winograd_ref.h) and
// every SIMD tier this CPU executes, on SceneEDNet's real channel counts (conv4 512 -> 1024,
// conv5 1024 -> 1024) at small and odd sizes, its conv4/conv5 map size (34x60) and shapes that
// leave tails in tiles and channel vectors. The passes are called as two threads would, on
// split ranges.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "common/conv_problems.h"
#include "common/relative_error.h"
#include "conv_packing.h"
#include "kernels/conv_job.h"
#include "kernels/ref/winograd_ref.h"
#include "kernels/winograd_job.h"
#include "sfrt/isa.h"
#include "winograd_packing.h"
#include "winograd_run.h"

namespace sfrt {
namespace {

// Winograd rounds differently from direct summation: the transforms add up to alpha^2 terms
// and the constants of F(4x4) (up to 8 in AT, 5 in BT) amplify rounding. Bounds: this fraction
// of the largest reference magnitude, for inputs in [-1, 1] and weights scaled by
// 1 / sqrt(9 cin), so outputs are of order 1. Measured on these cases: F(2x2) at most ~1e-6,
// F(4x4) at most ~1e-5 (1024 channels).
constexpr double kToleranceF2 = 1e-5;
constexpr double kToleranceF4 = 1e-4;

using testing::AlignedFloats;
using testing::ConvProblem;
using testing::RelativeMaxError;
using testing::UpConvProblem;
using testing::UpConvShape;

struct Case {
  int h, w, cin, cout;
  Padding pads;  // top, left, bottom, right
  Activation act = Activation::kLeakyRelu;
};

std::string Describe(const Case& c) {
  return std::to_string(c.h) + "x" + std::to_string(c.w) + "x" + std::to_string(c.cin) + "->" +
         std::to_string(c.cout) + " pads " + std::to_string(c.pads.top) + "," +
         std::to_string(c.pads.left) + "," + std::to_string(c.pads.bottom) + "," +
         std::to_string(c.pads.right);
}

const std::vector<Case>& Cases() {
  static const std::vector<Case> cases = {
      {5, 7, 1024, 1024, {1, 1, 1, 1}},  // conv5's channels, odd size: partial tiles both ways
      {4, 9, 512, 1024, {1, 1, 1, 1}},   // conv4's channels
      {34, 60, 64, 80, {1, 1, 1, 1}},    // conv4/conv5's map at 540x960
      {9, 13, 67, 70, {1, 1, 1, 1}},     // channel tails of every vector width
      {1, 1, 64, 64, {1, 1, 1, 1}},      // one pixel: every tap but the centre padded
      {2, 3, 70, 65, {1, 1, 1, 1}},      // smaller than one F(4x4) tile
      {11, 6, 33, 17, {0, 0, 2, 2}, Activation::kRelu},  // asymmetric pads
      {6, 11, 16, 40, {2, 2, 0, 0}, Activation::kNone},
      {7, 10, 64, 96, {1, 0, 1, 2}},
  };
  return cases;
}

// The problems of Cases(), built once: the direct reference on 1024 channels is slow.
const ConvProblem& ProblemOf(size_t index) {
  static std::vector<std::unique_ptr<ConvProblem>> problems(Cases().size());
  if (problems[index] == nullptr) {
    const Case& c = Cases()[index];
    problems[index] = std::make_unique<ConvProblem>(testing::MakeConvProblem(
        {c.h, c.w, c.cin, c.cout, 3, 1, c.pads, 0, c.act}, 3 * static_cast<uint32_t>(index) + 1));
  }
  return *problems[index];
}

class WinogradRef : public ::testing::TestWithParam<int> {};

TEST_P(WinogradRef, MatchesDirectReferenceOnEveryShapeOfTheTable) {
  const int m = GetParam();
  for (size_t i = 0; i < Cases().size(); ++i) {
    const Case& c = Cases()[i];
    SCOPED_TRACE(Describe(c));
    const ConvProblem& pr = ProblemOf(i);
    ASSERT_GT(pr.out_h, 0);
    std::vector<float> got(pr.want.size(), NAN);
    ref::Conv2dWinograd(pr.in, pr.params, c.pads, m,
                        DenseView(got.data(), pr.out_h, pr.out_w, c.cout));
    EXPECT_LE(RelativeMaxError(got, pr.want), m == 2 ? kToleranceF2 : kToleranceF4);
  }
}

INSTANTIATE_TEST_SUITE_P(F2AndF4, WinogradRef, ::testing::Values(2, 4),
                         [](const ::testing::TestParamInfo<int>& param) {
                           return "F" + std::to_string(param.param) + "x" +
                                  std::to_string(param.param);
                         });

struct IsaAndTile {
  Isa isa;
  int m;
};

class WinogradSimd : public ::testing::TestWithParam<IsaAndTile> {
 protected:
  void SetUp() override {
    if (!IsaSupported(GetParam().isa)) {
      GTEST_SKIP() << "this CPU or build cannot run " << IsaName(GetParam().isa)
                   << " (supported: " << SupportedIsaList() << ")";
    }
    kernels_ = WinogradKernelsFor(GetParam().isa, GetParam().m);
    ASSERT_NE(kernels_, nullptr);
  }
  const WinogradKernels* kernels_ = nullptr;
};

TEST_P(WinogradSimd, MatchesDirectReferenceOnEveryShapeOfTheTable) {
  const int m = GetParam().m;
  EXPECT_EQ(kernels_->m, m);
  const std::string name = kernels_->name;
  EXPECT_NE(name.find(std::string("conv2d_winograd_f") + std::to_string(m) + "x" +
                      std::to_string(m) + "_3x3__" + IsaName(GetParam().isa)),
            std::string::npos)
      << name;
  EXPECT_TRUE(name.ends_with("x" + std::to_string(kernels_->nr))) << name;  // the product tile
  for (size_t i = 0; i < Cases().size(); ++i) {
    const Case& c = Cases()[i];
    SCOPED_TRACE(Describe(c) + " " + name);
    const ConvProblem& pr = ProblemOf(i);
    AlignedFloats packed(PackedWinogradFloats(pr.params, m, kernels_->nr));
    const PackedWinograd w = PackWinograd(pr.params, m, kernels_->nr, packed.data);
    WinogradArgs args;
    args.conv = &w;
    args.in = pr.in;
    std::vector<float> got(pr.want.size(), NAN);
    args.out = DenseView(got.data(), pr.out_h, pr.out_w, c.cout);
    args.pads = c.pads;
    args.tiles_h = WinogradTiles(pr.out_h, m);
    args.tiles_w = WinogradTiles(pr.out_w, m);
    const size_t points = static_cast<size_t>(w.alpha) * w.alpha;
    const int tiles = args.tiles_h * args.tiles_w;
    ASSERT_EQ(WinogradScratchFloats(w, pr.out_h, pr.out_w),
              points * tiles * (w.k_stride + w.n_stride));
    AlignedFloats scratch(WinogradScratchFloats(w, pr.out_h, pr.out_w));
    args.v = scratch.data;
    args.m = scratch.data + points * tiles * w.k_stride;
    const int items = static_cast<int>(points) * w.blocks;
    kernels_->input(args, 0, tiles / 2);
    kernels_->input(args, tiles / 2, tiles);
    kernels_->product(args, 0, items / 3);
    kernels_->product(args, items / 3, items);
    kernels_->output(args, 0, tiles / 2);
    kernels_->output(args, tiles / 2, tiles);
    EXPECT_LE(RelativeMaxError(got, pr.want), m == 2 ? kToleranceF2 : kToleranceF4);
  }
}

// Band by band of tile rows (RunWinogradBands, as a session runs a large layer): one row per
// band, three, and the whole grid in one give the whole-grid result on every shape.
TEST_P(WinogradSimd, BandsOfTileRowsGiveTheWholeGridsResult) {
  const int m = GetParam().m;
  auto serial = [](int n, auto fn, void* ctx) { fn(ctx, 0, n); };
  for (size_t i = 0; i < Cases().size(); ++i) {
    const Case& c = Cases()[i];
    SCOPED_TRACE(Describe(c) + " " + kernels_->name);
    const ConvProblem& pr = ProblemOf(i);
    AlignedFloats packed(PackedWinogradFloats(pr.params, m, kernels_->nr));
    const PackedWinograd w = PackWinograd(pr.params, m, kernels_->nr, packed.data);
    const int tiles_h = WinogradTiles(pr.out_h, m);
    std::vector<float> whole;
    for (int band_rows : {tiles_h, 1, 3}) {
      SCOPED_TRACE("band of " + std::to_string(band_rows) + " tile rows");
      AlignedFloats scratch(WinogradBandScratchFloats(w, band_rows, pr.out_w));
      std::vector<float> got(pr.want.size(), NAN);
      RunWinogradBands(*kernels_, w, band_rows, scratch.data, pr.in,
                       DenseView(got.data(), pr.out_h, pr.out_w, c.cout), c.pads, serial);
      EXPECT_LE(RelativeMaxError(got, pr.want), m == 2 ? kToleranceF2 : kToleranceF4);
      if (whole.empty()) {
        whole = got;
      } else {
        EXPECT_EQ(got, whole);  // the same sums, band or not
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(EveryIsa, WinogradSimd,
                         ::testing::Values(IsaAndTile{Isa::kAvx2, 2}, IsaAndTile{Isa::kAvx2, 4},
                                           IsaAndTile{Isa::kAvx512, 2}, IsaAndTile{Isa::kAvx512, 4},
                                           IsaAndTile{Isa::kNeon, 2}, IsaAndTile{Isa::kNeon, 4}),
                         [](const ::testing::TestParamInfo<IsaAndTile>& param) {
                           return std::string(IsaName(param.param.isa)) + "_F" +
                                  std::to_string(param.param.m) + "x" +
                                  std::to_string(param.param.m);
                         });

class WinogradUpSimd : public ::testing::TestWithParam<Isa> {
 protected:
  void SetUp() override {
    if (!IsaSupported(GetParam())) {
      GTEST_SKIP() << "this CPU or build cannot run " << IsaName(GetParam())
                   << " (supported: " << SupportedIsaList() << ")";
    }
    up_ = WinogradUpKernelsFor(GetParam());
    conv_ = ConvKernelsFor(GetParam());
    ASSERT_NE(up_, nullptr);
    ASSERT_NE(conv_, nullptr);
  }
  const WinogradKernels* up_ = nullptr;
  const IsaConvKernels* conv_ = nullptr;
};

// The fused upsample(2x) -> crop -> 3x3 convolution with the interior on the F(2x2, 2x2) phase
// path (in bands of one, two and all tile rows) and the border on the direct kernel, against
// the reference upsample, crop view and direct convolution.
TEST_P(WinogradUpSimd, FusedUpsampleConvMatchesUpsampleCropConvReference) {
  const std::string name = up_->name;
  EXPECT_NE(name.find(std::string("upconv2x_conv3x3_winograd_f2x2_2x2__") + IsaName(GetParam())),
            std::string::npos)
      << name;
  EXPECT_TRUE(name.ends_with("x" + std::to_string(up_->nr))) << name;
  const std::vector<UpConvShape> cases = {
      {17, 30, 128, 64, 4, 0, 0, 0, {1, 1, 1, 1}},  // conv9's channels, up4 + crop of 540x960
      {5, 8, 1024, 512, 0, 0, 0, 0, {1, 1, 1, 1}},  // conv6's channels
      {9, 12, 67, 70, 0, 0, 0, 0, {1, 1, 1, 1}},    // channel tails
      {5, 8, 64, 65, 1, 1, 0, 0, {1, 1, 1, 1}},     // odd crop: phases swap
      {6, 9, 64, 64, 3, 5, 1, 1, {1, 1, 1, 1}},     // crops on every side
      {4, 7, 64, 80, 0, 1, 0, 0, {0, 0, 2, 2}},     // explicit asymmetric pads
      {4, 7, 64, 80, 1, 0, 0, 0, {2, 2, 0, 0}},
      {1, 1, 64, 64, 0, 0, 0, 0, {1, 1, 1, 1}},  // no interior pixel
      {2, 3, 64, 64, 1, 0, 0, 0, {1, 1, 1, 1}},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const UpConvShape& c = cases[i];
    SCOPED_TRACE(Describe(c));
    const UpConvProblem pr = testing::MakeUpConvProblem(c, 700 + 3 * static_cast<uint32_t>(i));
    ASSERT_FALSE(pr.want.empty());  // the shape has an output
    const int out_h = pr.out_h, out_w = pr.out_w;
    const ConvParams& p = pr.params;
    const std::vector<float>& want = pr.want;

    const ConvKernelVariant& v = PickConvVariant(*conv_, c.cout);
    AlignedFloats border(PackedConvFloats(p, v.nr, false));
    const PackedConv pc = PackConv(p, v.nr, false, border.data);
    AlignedFloats packed(PackedWinogradUpFloats(p, up_->nr));
    const PackedWinograd w = PackWinogradUp(p, up_->nr, packed.data);
    ConvArgs args;
    args.conv = &pc;
    args.in = pr.low_view;
    args.pads = c.pads;
    args.crop_top = c.crop_top;
    args.crop_left = c.crop_left;
    args.c_height = pr.cropped.height;
    args.c_width = pr.cropped.width;
    const UpGrid grid = UpGridOf(out_h, out_w, c.pads, pr.cropped.height, pr.cropped.width,
                                 c.crop_top, c.crop_left);
    for (int band_rows : {1, 2, UpWinogradBandRows(w, grid.tiles_h, grid.tiles_w)}) {
      SCOPED_TRACE("band rows " + std::to_string(band_rows));
      std::vector<float> got(want.size(), NAN);
      args.out = DenseView(got.data(), out_h, out_w, c.cout);
      args.skip_interior = false;
      AlignedFloats scratch(UpWinogradScratchFloats(w, band_rows, grid.tiles_w));
      // As two threads would: each pass split in two ranges.
      auto parallel = [](int n, void (*fn)(void*, int, int), void* ctx) {
        fn(ctx, 0, n / 2);
        fn(ctx, n / 2, n);
      };
      RunUpWinogradBands(*up_, w, band_rows, scratch.data, args, parallel);
      args.skip_interior = true;
      v.upconv(args, 0, out_h, 0, pc.blocks);
      EXPECT_LE(RelativeMaxError(got, want), kToleranceF2);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(EveryIsa, WinogradUpSimd,
                         ::testing::Values(Isa::kAvx2, Isa::kAvx512, Isa::kNeon),
                         [](const ::testing::TestParamInfo<Isa>& param) {
                           return std::string(IsaName(param.param));
                         });

TEST(WinogradPlanRule, TakesWideStrideOne3x3AndLeavesTheRest) {
  ConvParams p;
  p.kernel_h = p.kernel_w = 3;
  p.in_channels = 1024;
  p.out_channels = 1024;
  EXPECT_TRUE(WinogradApplies(p));
  p.out_channels = 3;  // SceneEDNet's output convolution
  EXPECT_FALSE(WinogradApplies(p));
  p.out_channels = 1024;
  p.stride_h = p.stride_w = 2;  // conv0..conv3
  EXPECT_FALSE(WinogradApplies(p));
  p.stride_h = p.stride_w = 1;
  p.kernel_h = p.kernel_w = 5;
  EXPECT_FALSE(WinogradApplies(p));
}

}  // namespace
}  // namespace sfrt
