// Every SIMD convolution kernel against the reference (kernels/ref/, the oracle), on a table of
// shapes chosen for the edges: channel tails of every vector width, strides, asymmetric and
// large pads, widths below and around the register tile, one-pixel images, cropped (strided)
// inputs. Plus the fused upsample-2x (+ crop) + 3x3 convolution against ref upsample, crop
// view and conv. Each test runs on every ISA this CPU executes; an ISA it cannot run is
// skipped with the reason.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "common/conv_problems.h"
#include "common/relative_error.h"
#include "conv_packing.h"
#include "kernels/conv_job.h"
#include "sfrt/isa.h"

namespace sfrt {
namespace {

// FMA and a different association than the reference's add-after-multiply: the results differ
// by rounding only. Bound: this fraction of the largest reference magnitude (at least 1).
constexpr double kTolerance = 2e-6;

using testing::AlignedFloats;
using testing::ConvProblem;
using testing::ConvShape;
using testing::UpConvProblem;
using testing::UpConvShape;

// Bounded absolutely where the reference is small (below 1).
double MaxRelativeError(const std::vector<float>& got, const std::vector<float>& want) {
  return testing::RelativeMaxError(got, want, 1.0);
}

// A kernel call of `pc` over `in` with `pads`, writing `got` as a dense out_h x out_w x cout map.
ConvArgs CallInto(const PackedConv& pc, const ConstTensorView& in, const Padding& pads,
                  std::vector<float>& got, int out_h, int out_w, int cout) {
  ConvArgs args;
  args.conv = &pc;
  args.in = in;
  args.out = DenseView(got.data(), out_h, out_w, cout);
  args.pads = pads;
  return args;
}

class Conv2dSimd : public ::testing::TestWithParam<Isa> {
 protected:
  void SetUp() override {
    if (!IsaSupported(GetParam())) {
      GTEST_SKIP() << "this CPU or build cannot run " << IsaName(GetParam())
                   << " (supported: " << SupportedIsaList() << ")";
    }
    kernels_ = ConvKernelsFor(GetParam());
    ASSERT_NE(kernels_, nullptr);
  }
  std::vector<const ConvKernelVariant*> Variants() const {
    std::vector<const ConvKernelVariant*> v;
    for (int i = 0; i < kernels_->count; ++i) v.push_back(&kernels_->variants[i]);
    return v;
  }
  const IsaConvKernels* kernels_ = nullptr;
};

const std::vector<ConvShape>& ConvCases() {
  static const std::vector<ConvShape> cases = {
      {17, 23, 12, 64, 3, 2, {0, 0, 1, 1}},     // conv0 at an odd size, TF same-upper
      {16, 24, 12, 64, 3, 2, {0, 0, 1, 1}},     // conv0, even
      {9, 13, 64, 3, 3, 1, {1, 1, 1, 1}},       // the 64 -> 3 output convolution
      {7, 31, 5, 17, 3, 1, {1, 1, 1, 1}},       // tails everywhere
      {6, 19, 8, 33, 3, 1, {1, 1, 1, 1}},       // one past a 32-channel block
      {5, 40, 16, 48, 3, 1, {1, 1, 1, 1}},      // 1.5 wide blocks
      {8, 8, 3, 8, 3, 1, {1, 1, 1, 1}},         // exactly one AVX2 narrow block
      {5, 9, 7, 16, 3, 2, {1, 1, 1, 1}},        // PyTorch-style symmetric pads, stride 2
      {11, 5, 4, 4, 3, 2, {1, 0, 1, 0}},        // pads on rows only
      {1, 1, 12, 20, 3, 1, {1, 1, 1, 1}},       // one pixel: all taps but the centre padded
      {1, 37, 6, 9, 3, 1, {1, 1, 1, 1}},        // one row
      {23, 1, 6, 9, 3, 1, {1, 1, 1, 1}},        // one column
      {6, 7, 10, 12, 1, 1, {0, 0, 0, 0}},       // 1x1
      {9, 14, 3, 21, 5, 1, {2, 2, 2, 2}},       // 5x5
      {12, 12, 4, 6, 3, 3, {1, 1, 1, 1}},       // stride 3
      {10, 26, 9, 40, 3, 1, {2, 0, 0, 2}},      // asymmetric, large pads
      {9, 18, 12, 32, 3, 1, {1, 1, 1, 1}, 60},  // input is a view with a row stride
      {9, 18, 12, 35, 3, 1, {1, 1, 1, 1}, 0, Activation::kRelu},
      {9, 18, 12, 35, 3, 2, {0, 1, 1, 1}, 0, Activation::kNone},
      {4, 29, 70, 65, 3, 1, {1, 1, 1, 1}},  // 70 input channels: blocks of 16/32 leave tails
      {13, 7, 33, 64, 3, 1, {1, 1, 1, 1}},  // width below the tile, cin one past 32
  };
  return cases;
}

// The session's loop order for a plain convolution (ConvArgs::rows_first): rows first where
// reading the input once per block would cost more than reading the weights once per row.
TEST(ConvRowsFirst, GoesRowsFirstWhereTheInputPerBlockOutweighsTheWeightsPerRow) {
  auto conv = [](int cin, int cout, int nr) {
    PackedConv p;
    p.in_channels = cin;
    p.out_channels = cout;
    p.kernel_h = p.kernel_w = 3;
    p.nr = nr;
    p.blocks = (cout + nr - 1) / nr;
    return p;
  };
  auto map = [](int h, int w, int c) {
    return ConstTensorView{nullptr, h, w, c, static_cast<ptrdiff_t>(w) * c};
  };
  // SceneEDNet at 540x960. conv1 (stride 2): 33 MB of input for each of 8 blocks of 16, or
  // each of 2 blocks of 64, against 0.3 MB of weights that stay in cache.
  EXPECT_TRUE(ConvRowsFirst(conv(64, 128, 16), map(270, 480, 64), 135));
  EXPECT_TRUE(ConvRowsFirst(conv(64, 128, 64), map(270, 480, 64), 135));
  // conv3 in blocks of 64: 8 x 8.4 MB of input against 34 rows x 4.7 MB of weights.
  EXPECT_FALSE(ConvRowsFirst(conv(256, 512, 64), map(68, 120, 256), 34));
  // conv5 computed directly: 64 x 8.4 MB against 34 x 37.7 MB.
  EXPECT_FALSE(ConvRowsFirst(conv(1024, 1024, 16), map(34, 60, 1024), 34));
  // One block: the orders are the same.
  EXPECT_FALSE(ConvRowsFirst(conv(64, 16, 16), map(270, 480, 64), 135));
}

// Profiles and `sfrt bench` name kernels by these strings: each names its ISA and ends with
// its register tile's output channels (nr), e.g. conv2d_f32__avx512_6x64.
TEST_P(Conv2dSimd, VariantNamesCarryIsaAndOutputChannelBlock) {
  const std::string isa = std::string("__") + IsaName(GetParam()) + "_";
  for (const ConvKernelVariant* v : Variants()) {
    for (const std::string name : {v->conv_name, v->upconv_name}) {
      EXPECT_NE(name.find(isa), std::string::npos) << name;
      EXPECT_TRUE(name.ends_with("x" + std::to_string(v->nr))) << name << " nr " << v->nr;
    }
  }
}

TEST_P(Conv2dSimd, MatchesReferenceOnEveryShapeOfTheTable) {
  for (size_t i = 0; i < ConvCases().size(); ++i) {
    const ConvShape& c = ConvCases()[i];
    SCOPED_TRACE(Describe(c));
    const ConvProblem pr = testing::MakeConvProblem(c, 1 + 3 * static_cast<uint32_t>(i));
    ASSERT_FALSE(pr.want.empty());  // the shape has an output
    const int out_h = pr.out_h, out_w = pr.out_w;
    const ConvParams& p = pr.params;
    const std::vector<float>& want = pr.want;

    // Every tile shape of this ISA, each with its default input-channel block and with blocks
    // that leave a tail (cin not a multiple of the block) or sum one channel per pass, blocks
    // first and rows first.
    for (const ConvKernelVariant* v : Variants()) {
      AlignedFloats packed(PackedConvFloats(p, v->nr, false));
      PackedConv pc = PackConv(p, v->nr, false, packed.data);
      for (int cin_block : {pc.cin_block, 1, 5, 16}) {
        for (const bool rows_first : {false, true}) {
          SCOPED_TRACE(std::string(v->conv_name) + " cin_block " + std::to_string(cin_block) +
                       (rows_first ? " rows first" : " blocks first"));
          pc.cin_block = cin_block;
          std::vector<float> got(want.size(), NAN);
          ConvArgs args = CallInto(pc, pr.in, c.pads, got, out_h, out_w, c.cout);
          args.rows_first = rows_first;
          // As two threads would call it: two row ranges, and the blocks split in two.
          const int half_blocks = pc.blocks / 2;
          v->conv(args, 0, out_h / 2, 0, pc.blocks);
          v->conv(args, out_h / 2, out_h, 0, half_blocks);
          v->conv(args, out_h / 2, out_h, half_blocks, pc.blocks);
          EXPECT_LE(MaxRelativeError(got, want), kTolerance);
        }
      }
    }
  }
}

// The few-output kernel (vectorised over input channels) on the table's shapes with at most
// kFewOutChannels outputs and more: SceneEDNet's 64 -> 3 output convolution at an odd size,
// input-channel tails of every vector width, strides, pads, 5x5, one to four outputs.
TEST_P(Conv2dSimd, FewOutputKernelMatchesReference) {
  ASSERT_NE(kernels_->few_out, nullptr);
  const std::string name = kernels_->few_out_name;
  EXPECT_NE(name.find(std::string("__") + IsaName(GetParam())), std::string::npos) << name;
  const std::vector<ConvShape> cases = {
      {33, 47, 64, 3, 3, 1, {1, 1, 1, 1}},  // the output convolution
      {9, 13, 64, 3, 3, 1, {1, 1, 1, 1}, 0, Activation::kNone},
      {7, 20, 70, 3, 3, 1, {1, 1, 1, 1}},  // 70 = 64 + 6: a partial vector
      {5, 9, 17, 1, 3, 1, {1, 1, 1, 1}},   // one output
      {6, 11, 40, 2, 3, 2, {0, 0, 1, 1}},  // two outputs, stride 2, TF same-upper
      {8, 15, 24, 4, 5, 1, {2, 2, 2, 2}, 0, Activation::kRelu},  // four outputs, 5x5
      {1, 1, 16, 3, 3, 1, {1, 1, 1, 1}},                         // one pixel
      {10, 26, 33, 3, 3, 1, {2, 0, 0, 2}},                       // asymmetric, large pads
      {9, 18, 16, 3, 3, 1, {1, 1, 1, 1}, 48},  // input is a view with a row stride
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const ConvShape& c = cases[i];
    SCOPED_TRACE(Describe(c));
    const ConvProblem pr = testing::MakeConvProblem(c, 500 + 3 * static_cast<uint32_t>(i));
    ASSERT_FALSE(pr.want.empty());  // the shape has an output
    const int out_h = pr.out_h, out_w = pr.out_w;
    const std::vector<float>& want = pr.want;

    AlignedFloats packed(PackedConvFewOutFloats(pr.params));
    const PackedConv pc = PackConvFewOut(pr.params, packed.data);
    std::vector<float> got(want.size(), NAN);
    const ConvArgs args = CallInto(pc, pr.in, c.pads, got, out_h, out_w, c.cout);
    kernels_->few_out(args, 0, out_h / 2, 0, 1);
    kernels_->few_out(args, out_h / 2, out_h, 0, 1);
    EXPECT_LE(MaxRelativeError(got, want), kTolerance);
  }
}

TEST_P(Conv2dSimd, FusedUpsampleConvMatchesUpsampleCropConvReference) {
  const std::vector<UpConvShape> cases = {
      {34, 60, 16, 8, 4, 0, 0, 0, {1, 1, 1, 1}},  // SceneEDNet's up4 + crop at 540x960 / 16
      {5, 8, 12, 32, 0, 0, 0, 0, {1, 1, 1, 1}},
      {5, 8, 12, 35, 1, 1, 0, 0, {1, 1, 1, 1}},  // odd crop: phases swap
      {5, 8, 12, 35, 3, 5, 0, 0, {1, 1, 1, 1}},
      {6, 9, 7, 17, 2, 1, 1, 1, {1, 1, 1, 1}},  // crops on every side
      {4, 7, 9, 3, 1, 0, 0, 0, {1, 1, 1, 1}},   // three output channels
      {4, 7, 9, 20, 0, 1, 0, 0, {0, 0, 2, 2}},  // explicit asymmetric pads
      {4, 7, 9, 20, 1, 0, 0, 0, {2, 2, 0, 0}},
      {1, 1, 5, 6, 0, 0, 0, 0, {1, 1, 1, 1}},     // 2x2 upsampled: no interior pixel
      {1, 9, 5, 6, 1, 0, 0, 0, {1, 1, 1, 1}},     // a single upsampled row after the crop
      {3, 30, 24, 64, 0, 3, 0, 0, {1, 1, 1, 1}},  // long rows: full register tiles
      {3, 23, 37, 70, 4, 1, 0, 0, {1, 1, 1, 1}},  // cin 37, cout 70: every tail, odd width
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const UpConvShape& c = cases[i];
    SCOPED_TRACE(Describe(c));
    const UpConvProblem pr = testing::MakeUpConvProblem(c, 100 + 3 * static_cast<uint32_t>(i));
    ASSERT_FALSE(pr.want.empty());  // the shape has an output
    const int out_h = pr.out_h, out_w = pr.out_w;
    const ConvParams& p = pr.params;
    const std::vector<float>& want = pr.want;

    for (const ConvKernelVariant* v : Variants()) {
      AlignedFloats packed(PackedConvFloats(p, v->nr, true));
      PackedConv pc = PackConv(p, v->nr, true, packed.data);
      for (int cin_block : {pc.cin_block, 1, 5, 16}) {
        SCOPED_TRACE(std::string(v->upconv_name) + " cin_block " + std::to_string(cin_block));
        pc.cin_block = cin_block;
        std::vector<float> got(want.size(), NAN);
        ConvArgs args = CallInto(pc, pr.low_view, c.pads, got, out_h, out_w, c.cout);
        args.crop_top = c.crop_top;
        args.crop_left = c.crop_left;
        args.c_height = pr.cropped.height;
        args.c_width = pr.cropped.width;
        v->upconv(args, 0, 1, 0, pc.blocks);
        v->upconv(args, 1, out_h, 0, pc.blocks);
        EXPECT_LE(MaxRelativeError(got, want), 4 * kTolerance);
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(EveryIsa, Conv2dSimd,
                         ::testing::Values(Isa::kAvx2, Isa::kAvx512, Isa::kNeon),
                         [](const ::testing::TestParamInfo<Isa>& param) {
                           return std::string(IsaName(param.param));
                         });

}  // namespace
}  // namespace sfrt
