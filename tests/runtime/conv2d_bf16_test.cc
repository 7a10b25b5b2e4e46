// The bf16 convolution kernels (kernels/bf16_job.h). The reference (ref::Conv2dBf16Rows, the
// oracle) against the float32 reference convolution (ref::Conv2d) run on the same bf16-rounded
// inputs and weights; then the SIMD kernels (AVX512_BF16; NEON bfdot on aarch64) against the
// reference on SceneEDNet's layers (published widths at reduced spatial size, and the 1/16-width
// default model) and on edge shapes: odd input channel counts (a pair read past the pixel),
// output channels not a multiple of the block, strides, crops of both parities, phase kernels,
// every activation, float and bf16 outputs, and row and block sub-ranges called separately.
//
// Tolerances: the kernels sum in float32 in their own order (the reference in double), so a
// float output may differ by float32 rounding of the sum: |got - want| <= 2^-16 * sum |x * w|
// over the pixel's taps (a bound on the summation error for the sum lengths here, with room);
// a bf16 output is the rounding of such a value: within one bf16 unit in the last place of the
// reference, or the float bound.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "bf16_packing.h"
#include "kernels/bf16_job.h"
#include "kernels/int8_job.h"  // amx::EmulatedTileViolations
#include "kernels/ref/conv2d_bf16_ref.h"
#include "kernels/ref/conv2d_ref.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"

namespace sfrt {
namespace {

// One convolution: an h x w x cin input (for `up`, the low-resolution map, upsampled 2x and
// cropped to C before a 3x3 stride-1 convolution), k x k kernel.
struct Bf16Shape {
  int h, w, cin, cout, k, stride;
  Padding pads;
  bool up = false;
  int crop_top = 0, crop_left = 0, crop_bottom = 0, crop_right = 0;
  bool phases = false;  // `up` with the four phases' 2x2 kernels
  Activation act = Activation::kLeakyRelu;
  bool out_float = false;
};

std::string Describe(const Bf16Shape& s) {
  std::string d = std::to_string(s.h) + "x" + std::to_string(s.w) + "x" + std::to_string(s.cin) +
                  "->" + std::to_string(s.cout) + " k" + std::to_string(s.k) + " s" +
                  std::to_string(s.stride) + " pads " + std::to_string(s.pads.top) + "," +
                  std::to_string(s.pads.left) + "," + std::to_string(s.pads.bottom) + "," +
                  std::to_string(s.pads.right);
  if (s.up) {
    d += " up2x crop " + std::to_string(s.crop_top) + "," + std::to_string(s.crop_left) + "," +
         std::to_string(s.crop_bottom) + "," + std::to_string(s.crop_right);
  }
  if (s.phases) d += " phases";
  d += s.act == Activation::kLeakyRelu ? " leaky" : s.act == Activation::kRelu ? " relu" : " none";
  d += s.out_float ? " float" : " bf16";
  return d;
}

// TF "same" padding with the odd pixel at the end.
Padding SameUpper(int h, int w, int k, int s) {
  auto axis = [&](int n, int* before, int* after) {
    const int out = (n + s - 1) / s;
    const int total = std::max(0, (out - 1) * s + k - n);
    *before = total / 2;
    *after = total - *before;
  };
  Padding p;
  axis(h, &p.top, &p.bottom);
  axis(w, &p.left, &p.right);
  return p;
}

Bf16Shape Conv(int h, int w, int cin, int cout, int stride, int k = 3) {
  return {h, w, cin, cout, k, stride, SameUpper(h, w, k, stride)};
}

// Upsample 2x, crop (top, left; the same amounts at the bottom and right unless set), then a
// 3x3 stride-1 "same" convolution.
Bf16Shape UpConv(int h, int w, int cin, int cout, int crop_top = 0, int crop_left = 0) {
  Bf16Shape s{h, w, cin, cout, 3, 1, {1, 1, 1, 1}, true, crop_top, crop_left, 0, 0};
  return s;
}

struct Problem {
  Bf16Shape shape;
  ConvParams params;
  std::vector<float> weights, bias;
  std::vector<uint16_t> in;  // h x w x cin bf16
  int c_h = 0, c_w = 0;      // the map the convolution reads
  int out_h = 0, out_w = 0;
};

Problem MakeProblem(const Bf16Shape& s, uint32_t seed) {
  Problem pr;
  pr.shape = s;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> x(-1.0f, 1.0f);
  const float wscale = 1.0f / std::sqrt(static_cast<float>(s.k * s.k * s.cin));
  std::normal_distribution<float> wd(0.0f, wscale);
  pr.weights.resize(static_cast<size_t>(s.k) * s.k * s.cin * s.cout);
  for (float& v : pr.weights) v = wd(rng);
  pr.bias.resize(static_cast<size_t>(s.cout));
  for (float& v : pr.bias) v = 0.1f * x(rng);
  pr.in.resize(static_cast<size_t>(s.h) * s.w * s.cin);
  for (uint16_t& v : pr.in) v = FloatToBf16(x(rng));
  ConvParams& p = pr.params;
  p.in_channels = s.cin;
  p.out_channels = s.cout;
  p.kernel_h = p.kernel_w = s.k;
  p.stride_h = p.stride_w = s.stride;
  p.pads = s.pads;
  p.activation = s.act;
  p.leaky_slope = 0.1f;
  p.weights = pr.weights.data();
  p.bias = pr.bias.data();
  p.precision = Precision::kBFloat16;
  pr.c_h = s.up ? 2 * s.h - s.crop_top - s.crop_bottom : s.h;
  pr.c_w = s.up ? 2 * s.w - s.crop_left - s.crop_right : s.w;
  pr.out_h = (pr.c_h + s.pads.top + s.pads.bottom - s.k) / s.stride + 1;
  pr.out_w = (pr.c_w + s.pads.left + s.pads.right - s.k) / s.stride + 1;
  return pr;
}

struct Aligned {
  explicit Aligned(size_t bytes) : data(std::aligned_alloc(64, (bytes + 63) / 64 * 64 + 64)) {}
  ~Aligned() { std::free(data); }
  Aligned(const Aligned&) = delete;
  Aligned& operator=(const Aligned&) = delete;
  void* data;
};

struct Output {
  std::vector<float> f;
  std::vector<uint16_t> h;
};

// Runs `fn` (a kernel table entry, or the reference) over the whole output.
Output RunConv(const Problem& pr, const PackedBf16Conv& conv, Bf16ConvRowsFn fn, int blocks) {
  const Bf16Shape& s = pr.shape;
  Output out;
  Bf16ConvArgs a;
  a.conv = &conv;
  // The input with zeroed slack after it, as the session's arena leaves.
  std::vector<uint16_t> in(pr.in.size() + kBf16TensorSlack, 0);
  std::copy(pr.in.begin(), pr.in.end(), in.begin());
  a.in = {in.data(), s.h, s.w, s.cin, static_cast<ptrdiff_t>(s.w) * s.cin};
  a.pads = s.pads;
  if (s.up) {
    a.upsampled = true;
    a.crop_top = s.crop_top;
    a.crop_left = s.crop_left;
    a.c_height = pr.c_h;
    a.c_width = pr.c_w;
  }
  const size_t n = static_cast<size_t>(pr.out_h) * pr.out_w * s.cout;
  if (s.out_float) {
    out.f.assign(n, -7.0f);
    a.out_f32 = DenseView(out.f.data(), pr.out_h, pr.out_w, s.cout);
  } else {
    out.h.assign(n, 0xdead);
    a.out_bf16 = DenseBf16View(out.h.data(), pr.out_h, pr.out_w, s.cout);
  }
  fn(a, 0, pr.out_h, 0, blocks);
  return out;
}

Output RunReference(const Problem& pr) {
  const bool phases = pr.shape.phases;
  Aligned packed(PackedBf16Bytes(pr.params, 0, phases));
  const PackedBf16Conv conv = PackBf16Conv(pr.params, 0, phases, pr.shape.out_float, packed.data);
  return RunConv(pr, conv, ref::Conv2dBf16Rows, 1);
}

// sum over taps and input channels of |x * w| for output (oy, ox, o), on the 3x3 weights (an
// upper bound for the phase kernels' sums too, within bf16 rounding of the weights).
std::vector<double> AbsSums(const Problem& pr) {
  const Bf16Shape& s = pr.shape;
  std::vector<double> sums(static_cast<size_t>(pr.out_h) * pr.out_w * s.cout, 0.0);
  for (int oy = 0; oy < pr.out_h; ++oy) {
    for (int ox = 0; ox < pr.out_w; ++ox) {
      double* d = &sums[(static_cast<size_t>(oy) * pr.out_w + ox) * s.cout];
      for (int ky = 0; ky < s.k; ++ky) {
        const int cy = oy * s.stride - s.pads.top + ky;
        if (cy < 0 || cy >= pr.c_h) continue;
        for (int kx = 0; kx < s.k; ++kx) {
          const int cx = ox * s.stride - s.pads.left + kx;
          if (cx < 0 || cx >= pr.c_w) continue;
          const int iy = s.up ? (cy + s.crop_top) / 2 : cy;
          const int ix = s.up ? (cx + s.crop_left) / 2 : cx;
          const uint16_t* x = &pr.in[(static_cast<size_t>(iy) * s.w + ix) * s.cin];
          for (int ci = 0; ci < s.cin; ++ci) {
            const double xv = std::fabs(Bf16ToFloat(x[ci]));
            const float* w =
                &pr.weights[(static_cast<size_t>(ky * s.k + kx) * s.cin + ci) * s.cout];
            for (int o = 0; o < s.cout; ++o) d[o] += xv * std::fabs(w[o]);
          }
        }
      }
    }
  }
  return sums;
}

// Compares got with want under the tolerances above; returns the values compared.
size_t ExpectClose(const Problem& pr, const Output& got, const Output& want) {
  const std::vector<double> sums = AbsSums(pr);
  const double kSumTol = std::ldexp(1.0, -16);
  size_t bad = 0;
  const size_t n = sums.size();
  for (size_t k = 0; k < n; ++k) {
    const double bound = kSumTol * (2.0 * sums[k] + 1.0);
    double g, w, tol = bound;
    if (pr.shape.out_float) {
      g = got.f[k];
      w = want.f[k];
    } else {
      g = Bf16ToFloat(got.h[k]);
      w = Bf16ToFloat(want.h[k]);
      tol = std::max(bound, std::ldexp(std::fabs(w), -7));
    }
    if (!(std::fabs(g - w) <= tol)) {
      if (++bad <= 5) {
        ADD_FAILURE() << "value " << k << " (pixel " << k / pr.shape.cout << ", channel "
                      << k % pr.shape.cout << "): got " << g << ", want " << w << ", tolerance "
                      << tol;
      }
    }
  }
  EXPECT_EQ(bad, 0u) << "of " << n << " values";
  return n;
}

TEST(Bf16Rounding, RoundsToNearestEvenAndKeepsInfinitiesAndNans) {
  EXPECT_EQ(FloatToBf16(1.0f), 0x3f80);
  EXPECT_EQ(FloatToBf16(-2.0f), 0xc000);
  // 1 + 2^-8 is halfway between 1 and 1 + 2^-7: to even (1). 1 + 3 * 2^-8: up to 1 + 2^-6.
  EXPECT_EQ(FloatToBf16(1.0f + std::ldexp(1.0f, -8)), 0x3f80);
  EXPECT_EQ(FloatToBf16(1.0f + 3 * std::ldexp(1.0f, -8)), 0x3f82);
  EXPECT_EQ(FloatToBf16(1.0f + std::ldexp(1.0f, -8) + std::ldexp(1.0f, -20)), 0x3f81);
  EXPECT_EQ(FloatToBf16(INFINITY), 0x7f80);
  EXPECT_EQ(FloatToBf16(-INFINITY), 0xff80);
  EXPECT_EQ(FloatToBf16(3.4e38f), 0x7f80) << "rounds past the largest bf16 to infinity";
  const uint16_t nan = FloatToBf16(std::nanf(""));
  EXPECT_TRUE(std::isnan(Bf16ToFloat(nan)));
  EXPECT_TRUE(std::isnan(Bf16ToFloat(FloatToBf16(std::bit_cast<float>(0x7f800001u)))))
      << "a NaN whose payload sits in the low bits stays NaN, not infinity";
  for (float v : {0.0f, -0.0f, 1.5f, 3.140625f, -0x1.8p-100f, 65280.0f}) {
    EXPECT_EQ(Bf16ToFloat(FloatToBf16(v)), v) << v << " is a bf16 value";
  }
}

// The reference against ref::Conv2d (float32) on the same bf16-rounded inputs and weights: the
// same function up to float32 rounding of the sums.
TEST(Bf16Reference, MatchesTheFloat32ReferenceOnRoundedValues) {
  const std::vector<Bf16Shape> shapes = {
      Conv(17, 23, 12, 4, 2), Conv(9, 12, 4, 8, 2),    Conv(7, 9, 32, 64, 1),
      Conv(9, 13, 64, 3, 1),  Conv(5, 8, 256, 100, 2), Conv(6, 7, 3, 9, 1, 5),
      Conv(6, 7, 6, 9, 1, 1),
  };
  uint32_t seed = 3;
  for (Bf16Shape s : shapes) {
    for (bool out_float : {true, false}) {
      s.out_float = out_float;
      const Problem pr = MakeProblem(s, seed++);
      SCOPED_TRACE(Describe(s));
      const Output got = RunReference(pr);
      // The float32 oracle on the rounded values, rounded to bf16 for a bf16 output.
      std::vector<float> rounded_w(pr.weights.size());
      for (size_t k = 0; k < rounded_w.size(); ++k) {
        rounded_w[k] = Bf16ToFloat(FloatToBf16(pr.weights[k]));
      }
      std::vector<float> in(pr.in.size());
      for (size_t k = 0; k < in.size(); ++k) in[k] = Bf16ToFloat(pr.in[k]);
      ConvParams p = pr.params;
      p.precision = Precision::kFloat32;
      p.weights = rounded_w.data();
      Output want;
      want.f.resize(static_cast<size_t>(pr.out_h) * pr.out_w * s.cout);
      ref::Conv2d({in.data(), s.h, s.w, s.cin, static_cast<ptrdiff_t>(s.w) * s.cin}, p, s.pads,
                  DenseView(want.f.data(), pr.out_h, pr.out_w, s.cout));
      if (!out_float) {
        want.h.resize(want.f.size());
        for (size_t k = 0; k < want.f.size(); ++k) want.h[k] = FloatToBf16(want.f[k]);
      }
      ExpectClose(pr, got, want);
    }
  }
}

class Bf16Kernels : public ::testing::Test {
 protected:
  // The SIMD table against the reference on one problem; returns the values compared.
  size_t ExpectMatchesReference(const Problem& pr) {
    SCOPED_TRACE(Describe(pr.shape));
    const Output want = RunReference(pr);
    const bool phases = pr.shape.phases;
    Aligned packed(PackedBf16Bytes(pr.params, kernels_->nr, phases));
    PackedBf16Conv conv =
        PackBf16Conv(pr.params, kernels_->nr, phases, pr.shape.out_float, packed.data);
    conv.amx_1x4 = amx_1x4_;
    const Output got =
        RunConv(pr, conv, pr.shape.up ? kernels_->upconv : kernels_->conv, conv.blocks);
    return ExpectClose(pr, got, want);
  }

  void CheckEveryModelLayer();
  void CheckEdgeShapes();
  void CheckRowAndBlockRanges();
  void CheckAmxBlocking();
  void CheckColumnRanges();

  const IsaBf16Kernels* kernels_ = nullptr;
  bool amx_1x4_ = false;  // PackedBf16Conv::amx_1x4
};

class Bf16Avx512 : public Bf16Kernels {
 protected:
  void SetUp() override {
    kernels_ = Bf16KernelsFor(Isa::kAvx512);
    if (kernels_ == nullptr) {
      GTEST_SKIP() << "no AVX512_BF16 kernels on this CPU or in this build (supported ISAs: "
                   << SupportedIsaList() << ")";
    }
  }
};

class Bf16Neon : public Bf16Kernels {
 protected:
  void SetUp() override {
    kernels_ = Bf16KernelsFor(Isa::kNeon);
    if (kernels_ == nullptr) {
      GTEST_SKIP() << "no NEON bf16 kernels here (aarch64 with the BF16 extension only; "
                      "supported ISAs: "
                   << SupportedIsaList() << ")";
    }
  }
};

// The AMX bf16 kernels' blocking over the scalar emulation of the tiles (every CPU), and the
// hardware's kernels where the CPU and the OS let sfrt use AMX.
class Bf16AmxEmulated : public Bf16Kernels {
 protected:
  void SetUp() override {
    kernels_ = amx::Bf16KernelsEmulated();
    violations_before_ = amx::EmulatedTileViolations();
  }
  void TearDown() override {
    EXPECT_EQ(amx::EmulatedTileViolations(), violations_before_)
        << "a tile operation broke AMX's rules";
  }
  long violations_before_ = 0;
};

class Bf16Amx : public Bf16Kernels {
 protected:
  void SetUp() override {
    kernels_ = avx512::Bf16KernelsAmx();
    if (kernels_ == nullptr) {
      GTEST_SKIP() << "no AMX-BF16 here (the emulated tiles, Bf16AmxEmulated, test the same "
                      "blocking)";
    }
  }
};

TEST_F(Bf16Avx512, KernelNamesCarryIsaAndTile) {
  EXPECT_EQ(kernels_->nr, 64);
  for (const std::string name : {kernels_->conv_name, kernels_->upconv_name}) {
    EXPECT_NE(name.find("bf16__avx512bf16_"), std::string::npos) << name;
    EXPECT_TRUE(name.ends_with("x" + std::to_string(kernels_->nr))) << name;
  }
  // Four pixels x four output channels.
  EXPECT_EQ(std::string(kernels_->few_out_name), "conv2d_fewout_bf16__avx512bf16_8x3");
}

TEST_F(Bf16Neon, KernelNamesCarryIsaAndTile) {
  EXPECT_EQ(kernels_->nr, 16);
  for (const std::string name : {kernels_->conv_name, kernels_->upconv_name}) {
    EXPECT_NE(name.find("bf16__neon_bfdot_"), std::string::npos) << name;
    EXPECT_TRUE(name.ends_with("x" + std::to_string(kernels_->nr))) << name;
  }
}

// SceneEDNet's layers in order at the published widths on small maps, and the 1/16-width
// default model; the fused layers with their phase kernels, as a session runs them.
void Bf16Kernels::CheckEveryModelLayer() {
  auto up = [](Bf16Shape s) {
    s.phases = true;
    return s;
  };
  auto out_float = [](Bf16Shape s) {
    s.out_float = true;
    return s;
  };
  const std::vector<Bf16Shape> layers = {
      // published widths
      Conv(11, 19, 12, 64, 2),
      Conv(10, 13, 64, 128, 2),
      Conv(7, 11, 128, 256, 2),
      Conv(5, 10, 256, 512, 2),
      Conv(3, 9, 512, 1024, 1),
      Conv(3, 9, 1024, 1024, 1),
      up(UpConv(2, 5, 1024, 512)),
      up(UpConv(3, 5, 512, 256)),
      up(UpConv(4, 7, 256, 128)),
      up(UpConv(5, 8, 128, 64, 4, 0)),
      out_float(Conv(7, 13, 64, 3, 1)),
      // the 1/16-width default model at 96x128 and below
      Conv(48, 64, 12, 4, 2),
      Conv(24, 32, 4, 8, 2),
      Conv(12, 16, 8, 16, 2),
      Conv(6, 8, 16, 32, 2),
      Conv(3, 4, 32, 64, 1),
      Conv(3, 4, 64, 64, 1),
      up(UpConv(3, 4, 64, 32)),
      up(UpConv(6, 8, 32, 16)),
      up(UpConv(12, 16, 16, 8)),
      up(UpConv(24, 32, 8, 4, 4, 0)),
      out_float(Conv(44, 64, 4, 3, 1)),
  };
  size_t values = 0;
  uint32_t seed = 100;
  for (const Bf16Shape& s : layers) values += ExpectMatchesReference(MakeProblem(s, seed++));
  std::printf("[          ] %zu layers, %zu output values\n", layers.size(), values);
}

TEST_F(Bf16Avx512, MatchesTheReferenceOnEveryModelLayer) { CheckEveryModelLayer(); }
TEST_F(Bf16Neon, MatchesTheReferenceOnEveryModelLayer) { CheckEveryModelLayer(); }

// The kernels' edges, each with every activation and both output types.
void Bf16Kernels::CheckEdgeShapes() {
  std::vector<Bf16Shape> shapes = {
      Conv(7, 31, 3, 100, 1),        // cin 3: the last pair reads past the pixel
      Conv(6, 9, 7, 17, 2),          // odd cin, cout not a multiple of 16
      Conv(5, 11, 9, 65, 1, 1),      // 1x1, one channel past a block of 64
      Conv(6, 7, 5, 9, 1, 5),        // 5x5
      Conv(9, 10, 33, 130, 2),       // three blocks, the last partial
      UpConv(5, 8, 12, 35, 1, 1),    // fused, odd crop, without phases
      UpConv(6, 9, 7, 17, 2, 1),     //
      UpConv(1, 1, 5, 6),            // a single pixel: no interior
      UpConv(3, 23, 37, 100, 4, 1),  // long rows: full tiles of every second pixel
      UpConv(4, 30, 24, 64, 0, 3),   //
      UpConv(2, 40, 32, 130, 0, 1),  //
  };
  for (size_t i = 5; i < shapes.size(); i += 2) shapes[i].phases = true;
  // Few outputs (at most 4, at least 16 inputs): tiles of 8 pixels (4 for 4 outputs), then of
  // 4, where the window is inside the input, single pixels elsewhere.
  for (const Bf16Shape& few : {
           Conv(6, 37, 64, 3, 1),     // the output layer's channels; 3 single pixels
           Conv(5, 14, 64, 3, 1),     // 8 + 4 pixels inside each row
           Conv(5, 30, 35, 4, 2),     // odd cin past one load (a masked tail), stride 2
           Conv(7, 22, 16, 1, 1, 5),  // 5x5, one output
           Conv(4, 41, 130, 2, 1),    // five loads per tap
           Conv(3, 9, 24, 3, 1, 7),   // 7x7 on 3 rows: no window inside the input
       }) {
    shapes.push_back(few);
  }
  Bf16Shape s = UpConv(4, 7, 9, 20, 0, 1);
  s.phases = true;
  s.pads = {0, 0, 2, 2};
  shapes.push_back(s);
  size_t values = 0;
  uint32_t seed = 500;
  for (Bf16Shape shape : shapes) {
    for (Activation act : {Activation::kLeakyRelu, Activation::kRelu, Activation::kNone}) {
      for (bool out_float : {false, true}) {
        shape.act = act;
        shape.out_float = out_float;
        values += ExpectMatchesReference(MakeProblem(shape, seed++));
      }
    }
  }
  std::printf("[          ] %zu output values\n", values);
}

TEST_F(Bf16Avx512, MatchesTheReferenceOnEdgeShapes) { CheckEdgeShapes(); }
TEST_F(Bf16Neon, MatchesTheReferenceOnEdgeShapes) { CheckEdgeShapes(); }

// Every row and every block called on its own (the finest split a pool makes), in reverse order,
// gives what one call gives, bit for bit (each output value is computed by one call).
void Bf16Kernels::CheckRowAndBlockRanges() {
  const int cout = 2 * kernels_->nr + kernels_->nr * 11 / 32;
  for (Bf16Shape shape : {Conv(9, 14, 20, cout, 1), UpConv(4, 7, 20, cout, 1, 1)}) {
    shape.phases = shape.up;
    const Problem pr = MakeProblem(shape, 77);
    SCOPED_TRACE(Describe(pr.shape));
    Aligned packed(PackedBf16Bytes(pr.params, kernels_->nr, shape.phases));
    const PackedBf16Conv conv =
        PackBf16Conv(pr.params, kernels_->nr, shape.phases, false, packed.data);
    ASSERT_EQ(conv.blocks, 3);
    const Bf16ConvRowsFn fn = shape.up ? kernels_->upconv : kernels_->conv;
    const Output whole = RunConv(pr, conv, fn, conv.blocks);
    struct Split {
      Bf16ConvRowsFn fn;
      int rows, blocks;
    };
    // RunConv() with the split calls: a table entry that calls fn per row and block, in reverse.
    static thread_local Split split;
    split = {fn, pr.out_h, conv.blocks};
    const Output pieces = RunConv(
        pr, conv,
        [](const Bf16ConvArgs& a, int, int, int, int) {
          for (int row = split.rows - 1; row >= 0; --row) {
            for (int blk = split.blocks - 1; blk >= 0; --blk)
              split.fn(a, row, row + 1, blk, blk + 1);
          }
        },
        conv.blocks);
    EXPECT_EQ(pieces.h, whole.h);
  }
}

TEST_F(Bf16Avx512, RowAndBlockRangesCalledSeparatelyComposeTheWholeOutput) {
  CheckRowAndBlockRanges();
}
TEST_F(Bf16Neon, RowAndBlockRangesCalledSeparatelyComposeTheWholeOutput) {
  CheckRowAndBlockRanges();
}

// The conversion step: every ISA's ToBf16 gives FloatToBf16's bits, on rows of every length
// modulo the vector (and a view whose rows are further apart), for values at the rounding
// boundaries, denormals, infinities and NaNs.
TEST(Bf16Conversion, EveryIsaGivesTheBitsOfFloatToBf16) {
  std::mt19937 rng(9);
  std::uniform_int_distribution<uint32_t> any_bits;
  std::vector<float> specials = {0.0f,
                                 -0.0f,
                                 1.0f,
                                 INFINITY,
                                 -INFINITY,
                                 std::nanf(""),
                                 std::bit_cast<float>(0x7f800001u),
                                 std::bit_cast<float>(0x00000001u),
                                 std::bit_cast<float>(0x3f808000u),
                                 std::bit_cast<float>(0x3f818000u),
                                 std::bit_cast<float>(0x7f7fffffu),
                                 3.0e38f};
  for (Isa isa : SupportedIsas()) {
    const ToBf16Kernel kernel = ToBf16KernelFor(isa);
    SCOPED_TRACE(std::string(IsaName(isa)) + " " + kernel.name);
    if (Bf16KernelsAvailable(isa)) {
      // avx512amx converts with avx512's kernel.
      const std::string vector_isa = isa == Isa::kAvx512Amx ? "avx512" : IsaName(isa);
      EXPECT_NE(std::string(kernel.name).find(vector_isa), std::string::npos);
    }
    for (int width : {1, 5, 7, 16, 17, 33}) {
      const int h = 3, c = 3, stride = width * c + 5;
      std::vector<float> in(static_cast<size_t>(h) * stride);
      for (size_t k = 0; k < in.size(); ++k) {
        in[k] = k < specials.size() ? specials[k] : std::bit_cast<float>(any_bits(rng));
      }
      std::vector<uint16_t> got(static_cast<size_t>(h) * width * c + 8, 0xabcd);
      kernel.fn({in.data(), h, width, c, stride}, DenseBf16View(got.data(), h, width, c), 0, h);
      for (int y = 0; y < h; ++y) {
        for (int k = 0; k < width * c; ++k) {
          const float v = in[static_cast<size_t>(y) * stride + k];
          ASSERT_EQ(got[static_cast<size_t>(y) * width * c + k], FloatToBf16(v))
              << "row " << y << " value " << k << " bits 0x" << std::hex
              << std::bit_cast<uint32_t>(v);
        }
      }
      for (size_t k = static_cast<size_t>(h) * width * c; k < got.size(); ++k) {
        ASSERT_EQ(got[k], 0xabcd) << "wrote past the tensor";
      }
    }
  }
}

// Shapes where the AMX tiles do the work: rows with groups of 16 interior pixels, input pairs
// under one chunk of 16, exactly one, a chunk and a tail, several; output blocks of 64, partial
// and several, few outputs (one C tile); 1x1, 3x3 and 5x5; strides 1 and 2; both outputs. The
// fused upsample with phase kernels: both crop parities, a chunk and a tail, partial blocks, few
// outputs, rows whose last tile overlaps the one before.
void Bf16Kernels::CheckAmxBlocking() {
  std::vector<Bf16Shape> shapes = {
      Conv(5, 40, 3, 64, 1),
      Conv(4, 41, 12, 100, 1),
      Conv(5, 75, 36, 64, 2),
      Conv(3, 38, 32, 64, 1),
      Conv(4, 50, 50, 130, 1),
      Conv(3, 35, 100, 64, 1),
      Conv(3, 34, 256, 128, 1),
      Conv(3, 34, 1024, 64, 1),
      Conv(4, 40, 20, 70, 1, 1),
      Conv(6, 44, 9, 33, 2, 5),
      Conv(5, 12, 64, 64, 1),
      Conv(4, 40, 64, 3, 1),
      // The same layouts with 16 pairs or more, which the tiles take (fewer: the fallback).
      Conv(4, 50, 80, 130, 1),
      Conv(4, 40, 32, 70, 1, 1),
      Conv(6, 80, 32, 33, 2, 5),
      Conv(3, 70, 32, 70, 1),
      // The 2 x 2 blocking's halves of 32 channels with one channel tile in the last (40:
      // 2 + 1 C tiles) and a block of one half (20), rows of an odd number of pixel tiles.
      Conv(3, 40, 64, 40, 1),
      Conv(4, 33, 32, 20, 1),
  };
  for (Bf16Shape up :
       {UpConv(4, 20, 32, 64), UpConv(3, 24, 32, 130, 1, 1), UpConv(3, 19, 50, 64, 0, 1),
        UpConv(4, 37, 64, 3, 4, 0), UpConv(2, 17, 32, 64, 1, 0), UpConv(3, 20, 32, 100, 0, 1)}) {
    up.phases = true;
    shapes.push_back(up);
  }
  // Two epilogues each (the epilogue is the scalar one whatever the shape; EdgeShapes has all).
  size_t values = 0;
  uint32_t seed = 800;
  for (Bf16Shape shape : shapes) {
    for (auto [act, out_float] :
         {std::pair{Activation::kLeakyRelu, false}, std::pair{Activation::kRelu, true}}) {
      shape.act = act;
      shape.out_float = out_float;
      values += ExpectMatchesReference(MakeProblem(shape, seed++));
    }
  }
  std::printf("[          ] %zu output values\n", values);
}

// Each row as three column ranges (Bf16ConvArgs::col_begin/col_end) gives what one call gives.
void Bf16Kernels::CheckColumnRanges() {
  for (const Bf16Shape& shape : {Conv(5, 37, 20, 70, 1), Conv(6, 41, 9, 33, 2)}) {
    const Problem pr = MakeProblem(shape, 93);
    SCOPED_TRACE(Describe(pr.shape));
    Aligned packed(PackedBf16Bytes(pr.params, kernels_->nr, false));
    const PackedBf16Conv conv = PackBf16Conv(pr.params, kernels_->nr, false, false, packed.data);
    const Output whole = RunConv(pr, conv, kernels_->conv, conv.blocks);
    static thread_local Bf16ConvRowsFn fn;
    fn = kernels_->conv;
    const Output pieces = RunConv(
        pr, conv,
        [](const Bf16ConvArgs& a, int r0, int r1, int b0, int b1) {
          Bf16ConvArgs part = a;
          const int w = a.out_bf16.width;
          for (auto [b, e] : {std::pair{0, 1}, {1, 9}, {9, w}}) {
            part.col_begin = b;
            part.col_end = e;
            fn(part, r0, r1, b0, b1);
          }
        },
        conv.blocks);
    EXPECT_EQ(pieces.h, whole.h);
  }
}

TEST_F(Bf16Avx512, ColumnRangesComposeTheWholeRow) { CheckColumnRanges(); }
TEST_F(Bf16Neon, ColumnRangesComposeTheWholeRow) { CheckColumnRanges(); }
TEST_F(Bf16AmxEmulated, ColumnRangesComposeTheWholeRow) { CheckColumnRanges(); }
TEST_F(Bf16AmxEmulated, MatchesTheReferenceOnEdgeShapes) { CheckEdgeShapes(); }
TEST_F(Bf16AmxEmulated, MatchesTheReferenceWhereTheTilesDoTheWork) { CheckAmxBlocking(); }
TEST_F(Bf16AmxEmulated, The1x4BlockingMatchesTheReferenceWhereThe2x2WouldRun) {
  amx_1x4_ = true;  // KernelTuning::amx_pairs false
  CheckAmxBlocking();
}
TEST_F(Bf16AmxEmulated, RowAndBlockRangesCalledSeparatelyComposeTheWholeOutput) {
  CheckRowAndBlockRanges();
}
TEST_F(Bf16Amx, MatchesTheReferenceOnEveryModelLayer) { CheckEveryModelLayer(); }
TEST_F(Bf16Amx, MatchesTheReferenceWhereTheTilesDoTheWork) { CheckAmxBlocking(); }
TEST_F(Bf16Amx, The1x4BlockingMatchesTheReferenceWhereThe2x2WouldRun) {
  amx_1x4_ = true;
  CheckAmxBlocking();
}
TEST_F(Bf16Amx, KernelNamesCarryIsaAndTileAndTheSessionGetsThem) {
  EXPECT_EQ(std::string(kernels_->conv_name), "conv2d_bf16__avx512amx_16x64");
  EXPECT_EQ(std::string(kernels_->upconv_name), "upconv2d_bf16__avx512amx_16x64");
  EXPECT_EQ(Bf16KernelsFor(Isa::kAvx512Amx), kernels_);
  // avx512 keeps the AVX512_BF16 kernels, so that the two can be compared on one CPU.
  ASSERT_NE(Bf16KernelsFor(Isa::kAvx512), nullptr);
  EXPECT_NE(std::string(Bf16KernelsFor(Isa::kAvx512)->conv_name).find("avx512bf16"),
            std::string::npos);
}

TEST(Bf16Dispatch, OnlyAvx512WithBf16AndNeonWithBf16HaveBf16Kernels) {
  EXPECT_EQ(Bf16KernelsFor(Isa::kRef), nullptr);
  EXPECT_EQ(Bf16KernelsFor(Isa::kAvx2), nullptr);
  if (!IsaSupported(Isa::kNeon)) {
    EXPECT_EQ(Bf16KernelsFor(Isa::kNeon), nullptr);
  }
  if (!IsaSupported(Isa::kAvx512)) {
    EXPECT_EQ(Bf16KernelsFor(Isa::kAvx512), nullptr);
    EXPECT_EQ(Bf16KernelsFor(Isa::kAvx512Amx), nullptr);
  }
  EXPECT_EQ(Bf16KernelsAvailable(Isa::kRef), false);
}

}  // namespace
}  // namespace sfrt
