// Every SIMD convolution kernel against the reference (kernels/ref/, the oracle), on a table of
// shapes chosen for the edges: channel tails of every vector width, strides, asymmetric and
// large pads, widths below and around the register tile, one-pixel images, cropped (strided)
// inputs. Plus the fused upsample-2x (+ crop) + 3x3 convolution against ref upsample, crop
// view and conv. Each test runs on every ISA this CPU executes; an ISA it cannot run is
// skipped with the reason.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "conv_packing.h"
#include "kernels/conv_job.h"
#include "kernels/ref/conv2d_ref.h"
#include "kernels/ref/resample_ref.h"
#include "sfrt/isa.h"

namespace sfrt {
namespace {

// FMA and a different association than the reference's add-after-multiply: the results differ
// by rounding only. Bound: this fraction of the largest reference magnitude (at least 1).
constexpr double kTolerance = 2e-6;

std::vector<float> Random(size_t n, uint32_t seed, float scale) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(-scale, scale);
  std::vector<float> v(n);
  for (float& x : v) x = dist(rng);
  return v;
}

// 64-byte-aligned float buffer for packed weights.
struct Aligned {
  explicit Aligned(size_t n) : data(static_cast<float*>(std::aligned_alloc(64, (n + 16) * 4))) {}
  ~Aligned() { std::free(data); }
  float* data;
};

double MaxRelativeError(const std::vector<float>& got, const std::vector<float>& want) {
  double max_ref = 1.0, max_err = 0.0;
  for (size_t i = 0; i < want.size(); ++i) {
    if (!std::isfinite(got[i])) return INFINITY;
    max_ref = std::max(max_ref, std::abs(double(want[i])));
    max_err = std::max(max_err, std::abs(double(got[i]) - want[i]));
  }
  return max_err / max_ref;
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

struct ConvCase {
  int h, w, cin, cout, k, stride;
  Padding pads;              // top, left, bottom, right
  int extra_row_floats = 0;  // input row stride beyond width * cin (a cropped view)
  Activation act = Activation::kLeakyRelu;
};

std::string Describe(const ConvCase& c) {
  return std::to_string(c.h) + "x" + std::to_string(c.w) + "x" + std::to_string(c.cin) + "->" +
         std::to_string(c.cout) + " k" + std::to_string(c.k) + " s" + std::to_string(c.stride) +
         " pads " + std::to_string(c.pads.top) + "," + std::to_string(c.pads.left) + "," +
         std::to_string(c.pads.bottom) + "," + std::to_string(c.pads.right) + " rowpad " +
         std::to_string(c.extra_row_floats);
}

const std::vector<ConvCase>& ConvCases() {
  static const std::vector<ConvCase> cases = {
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

TEST_P(Conv2dSimd, MatchesReferenceOnEveryShapeOfTheTable) {
  uint32_t seed = 1;
  for (const ConvCase& c : ConvCases()) {
    SCOPED_TRACE(Describe(c));
    const int out_h = (c.h + c.pads.top + c.pads.bottom - c.k) / c.stride + 1;
    const int out_w = (c.w + c.pads.left + c.pads.right - c.k) / c.stride + 1;
    ASSERT_GT(out_h, 0);
    ASSERT_GT(out_w, 0);
    const ptrdiff_t row = static_cast<ptrdiff_t>(c.w) * c.cin + c.extra_row_floats;
    const std::vector<float> input = Random(static_cast<size_t>(c.h) * row, seed++, 1.0f);
    const std::vector<float> weights = Random(static_cast<size_t>(c.k * c.k) * c.cin * c.cout,
                                              seed++, 1.0f / std::sqrt(float(c.k * c.k * c.cin)));
    const std::vector<float> bias = Random(c.cout, seed++, 0.5f);
    ConvParams p;
    p.in_channels = c.cin;
    p.out_channels = c.cout;
    p.kernel_h = p.kernel_w = c.k;
    p.stride_h = p.stride_w = c.stride;
    p.activation = c.act;
    p.leaky_slope = 0.3f;
    p.weights = weights.data();
    p.bias = bias.data();
    const ConstTensorView in{input.data(), c.h, c.w, c.cin, row};

    std::vector<float> want(static_cast<size_t>(out_h) * out_w * c.cout);
    ref::Conv2d(in, p, c.pads, DenseView(want.data(), out_h, out_w, c.cout));

    // Every tile shape of this ISA, each with its default input-channel block and with blocks
    // that leave a tail (cin not a multiple of the block) or sum one channel per pass.
    for (const ConvKernelVariant* v : Variants()) {
      Aligned packed(PackedConvFloats(p, v->nr, false));
      PackedConv pc = PackConv(p, v->nr, false, packed.data);
      for (int cin_block : {pc.cin_block, 1, 5, 16}) {
        SCOPED_TRACE(std::string(v->conv_name) + " cin_block " + std::to_string(cin_block));
        pc.cin_block = cin_block;
        std::vector<float> got(want.size(), NAN);
        ConvArgs args;
        args.conv = &pc;
        args.in = in;
        args.out = DenseView(got.data(), out_h, out_w, c.cout);
        args.pads = c.pads;
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

// The few-output kernel (vectorised over input channels) on the table's shapes with at most
// kFewOutChannels outputs and more: SceneEDNet's 64 -> 3 output convolution at an odd size,
// input-channel tails of every vector width, strides, pads, 5x5, one to four outputs.
TEST_P(Conv2dSimd, FewOutputKernelMatchesReference) {
  ASSERT_NE(kernels_->few_out, nullptr);
  const std::string name = kernels_->few_out_name;
  EXPECT_NE(name.find(std::string("__") + IsaName(GetParam())), std::string::npos) << name;
  std::vector<ConvCase> cases = {
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
  uint32_t seed = 500;
  for (const ConvCase& c : cases) {
    SCOPED_TRACE(Describe(c));
    const int out_h = (c.h + c.pads.top + c.pads.bottom - c.k) / c.stride + 1;
    const int out_w = (c.w + c.pads.left + c.pads.right - c.k) / c.stride + 1;
    const ptrdiff_t row = static_cast<ptrdiff_t>(c.w) * c.cin + c.extra_row_floats;
    const std::vector<float> input = Random(static_cast<size_t>(c.h) * row, seed++, 1.0f);
    const std::vector<float> weights = Random(static_cast<size_t>(c.k * c.k) * c.cin * c.cout,
                                              seed++, 1.0f / std::sqrt(float(c.k * c.k * c.cin)));
    const std::vector<float> bias = Random(c.cout, seed++, 0.5f);
    ConvParams p;
    p.in_channels = c.cin;
    p.out_channels = c.cout;
    p.kernel_h = p.kernel_w = c.k;
    p.stride_h = p.stride_w = c.stride;
    p.activation = c.act;
    p.leaky_slope = 0.3f;
    p.weights = weights.data();
    p.bias = bias.data();
    const ConstTensorView in{input.data(), c.h, c.w, c.cin, row};
    std::vector<float> want(static_cast<size_t>(out_h) * out_w * c.cout);
    ref::Conv2d(in, p, c.pads, DenseView(want.data(), out_h, out_w, c.cout));

    Aligned packed(PackedConvFewOutFloats(p));
    const PackedConv pc = PackConvFewOut(p, packed.data);
    std::vector<float> got(want.size(), NAN);
    ConvArgs args;
    args.conv = &pc;
    args.in = in;
    args.out = DenseView(got.data(), out_h, out_w, c.cout);
    args.pads = c.pads;
    kernels_->few_out(args, 0, out_h / 2, 0, 1);
    kernels_->few_out(args, out_h / 2, out_h, 0, 1);
    EXPECT_LE(MaxRelativeError(got, want), kTolerance);
  }
}

struct UpConvCase {
  int h, w, cin, cout;      // low-resolution input
  int crop_top, crop_left;  // removed from the upsampled map
  int crop_bottom, crop_right;
  Padding pads;
};

TEST_P(Conv2dSimd, FusedUpsampleConvMatchesUpsampleCropConvReference) {
  const std::vector<UpConvCase> cases = {
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
  uint32_t seed = 100;
  for (const UpConvCase& c : cases) {
    SCOPED_TRACE(std::to_string(c.h) + "x" + std::to_string(c.w) + "x" + std::to_string(c.cin) +
                 "->" + std::to_string(c.cout) + " crop " + std::to_string(c.crop_top) + "," +
                 std::to_string(c.crop_left) + "," + std::to_string(c.crop_bottom) + "," +
                 std::to_string(c.crop_right) + " pads " + std::to_string(c.pads.top) + "," +
                 std::to_string(c.pads.left) + "," + std::to_string(c.pads.bottom) + "," +
                 std::to_string(c.pads.right));
    const std::vector<float> low = Random(static_cast<size_t>(c.h) * c.w * c.cin, seed++, 1.0f);
    const std::vector<float> weights =
        Random(static_cast<size_t>(9) * c.cin * c.cout, seed++, 1.0f / std::sqrt(9.0f * c.cin));
    const std::vector<float> bias = Random(c.cout, seed++, 0.5f);
    ConvParams p;
    p.in_channels = c.cin;
    p.out_channels = c.cout;
    p.kernel_h = p.kernel_w = 3;
    p.activation = Activation::kLeakyRelu;
    p.leaky_slope = 0.3f;
    p.weights = weights.data();
    p.bias = bias.data();

    // Reference: upsample into a tensor, crop as a view, convolve.
    std::vector<float> up(static_cast<size_t>(4) * c.h * c.w * c.cin);
    const ConstTensorView low_view = DenseView(const_cast<float*>(low.data()), c.h, c.w, c.cin);
    const TensorView up_view = DenseView(up.data(), 2 * c.h, 2 * c.w, c.cin);
    ref::UpsampleNearest(low_view, 2, 2, up_view);
    ConstTensorView cropped = up_view;
    cropped.data = up_view.pixel(c.crop_top, c.crop_left);
    cropped.height = 2 * c.h - c.crop_top - c.crop_bottom;
    cropped.width = 2 * c.w - c.crop_left - c.crop_right;
    const int out_h = cropped.height + c.pads.top + c.pads.bottom - 2;
    const int out_w = cropped.width + c.pads.left + c.pads.right - 2;
    ASSERT_GT(out_h, 0);
    ASSERT_GT(out_w, 0);
    std::vector<float> want(static_cast<size_t>(out_h) * out_w * c.cout);
    ref::Conv2d(cropped, p, c.pads, DenseView(want.data(), out_h, out_w, c.cout));

    for (const ConvKernelVariant* v : Variants()) {
      Aligned packed(PackedConvFloats(p, v->nr, true));
      PackedConv pc = PackConv(p, v->nr, true, packed.data);
      for (int cin_block : {pc.cin_block, 1, 5, 16}) {
        SCOPED_TRACE(std::string(v->upconv_name) + " cin_block " + std::to_string(cin_block));
        pc.cin_block = cin_block;
        std::vector<float> got(want.size(), NAN);
        ConvArgs args;
        args.conv = &pc;
        args.in = low_view;
        args.out = DenseView(got.data(), out_h, out_w, c.cout);
        args.pads = c.pads;
        args.crop_top = c.crop_top;
        args.crop_left = c.crop_left;
        args.c_height = cropped.height;
        args.c_width = cropped.width;
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
