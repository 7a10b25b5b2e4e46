// The int8 convolution kernels (kernels/int8_job.h). The reference (ref::Conv2dInt8Rows, the
// oracle) against the real arithmetic it approximates, computed in double on the dequantised
// values; then the SIMD kernels (AVX-512 VNNI; NEON sdot and usdot on aarch64) against the
// reference, byte for byte, on SceneEDNet's layers (published widths at reduced spatial size, and
// the 1/16-width default model) and on shapes chosen for the edges: input channels not a multiple
// of 4 (or of 16, what one NEON load serves), output channels not a multiple of the block, odd
// sizes, strides, crops, every activation, zero points at both ends, saturating output scales,
// float and uint8 outputs, and row and block sub-ranges called separately as threads would.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "int8_packing.h"
#include "kernels/int8_job.h"
#include "kernels/ref/conv2d_int8_ref.h"
#include "kernels/simd/amx_driver_inl.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#if SFRT_TEST_NEON_DOT
#include "kernels/neon/int8_neon.h"
#endif

namespace sfrt {
namespace {

// One convolution: an h x w x cin input (for `up`, the low-resolution map, upsampled 2x and
// cropped to C before a 3x3 stride-1 convolution), k x k kernel.
struct Int8Shape {
  int h, w, cin, cout, k, stride;
  Padding pads;
  bool up = false;
  int crop_top = 0, crop_left = 0, crop_bottom = 0, crop_right = 0;
  int extra_row_bytes = 0;  // the input is a view with rows this much further apart
  bool phases = false;      // `up` with the four phases' 2x2 kernels (ConvParams::phase_weights_q)
};

// Quantisation and epilogue of one run.
struct Int8Quant {
  int in_zero_point = 128;
  int out_zero_point = 128;
  Activation act = Activation::kLeakyRelu;
  bool out_float = false;
  float out_scale = 1.0f / 32;  // 1 / 256 saturates (|y| > 2 passes the +-512 clamp)
};

std::string Describe(const Int8Shape& s) {
  std::string d = std::to_string(s.h) + "x" + std::to_string(s.w) + "x" + std::to_string(s.cin) +
                  "->" + std::to_string(s.cout) + " k" + std::to_string(s.k) + " s" +
                  std::to_string(s.stride) + " pads " + std::to_string(s.pads.top) + "," +
                  std::to_string(s.pads.left) + "," + std::to_string(s.pads.bottom) + "," +
                  std::to_string(s.pads.right);
  if (s.up) {
    d += " up2x crop " + std::to_string(s.crop_top) + "," + std::to_string(s.crop_left) + "," +
         std::to_string(s.crop_bottom) + "," + std::to_string(s.crop_right);
  }
  if (s.extra_row_bytes > 0) d += " rowpad " + std::to_string(s.extra_row_bytes);
  if (s.phases) d += " phases";
  return d;
}

std::string Describe(const Int8Quant& q) {
  const char* act = q.act == Activation::kLeakyRelu ? "leaky"
                    : q.act == Activation::kRelu    ? "relu"
                                                    : "none";
  return std::string("zp in ") + std::to_string(q.in_zero_point) + " out " +
         std::to_string(q.out_zero_point) + " " + act + (q.out_float ? " float" : " u8") +
         " out_scale " + std::to_string(q.out_scale);
}

// TF "same" padding with the odd pixel at the end (PaddingRule::kSameUpper).
Padding SameUpper(int h, int w, int k, int s) {
  auto axis = [&](int n, int* before, int* after) {
    const int out = (n + s - 1) / s;
    const int total = std::max((out - 1) * s + k - n, 0);
    *before = total / 2;
    *after = total - *before;
  };
  Padding p;
  axis(h, &p.top, &p.bottom);
  axis(w, &p.left, &p.right);
  return p;
}

Int8Shape Conv(int h, int w, int cin, int cout, int stride) {
  return {h, w, cin, cout, 3, stride, SameUpper(h, w, 3, stride)};
}

// Nearest-2x upsample of h x w, crop, 3x3 stride 1 with one pixel of padding.
Int8Shape UpConv(int h, int w, int cin, int cout, int crop_top = 0, int crop_left = 0) {
  Int8Shape s{h, w, cin, cout, 3, 1, {1, 1, 1, 1}};
  s.up = true;
  s.crop_top = crop_top;
  s.crop_left = crop_left;
  return s;
}

// 64-byte-aligned packed weights.
struct AlignedBytes {
  explicit AlignedBytes(size_t n) : data(std::aligned_alloc(64, (n + 63) / 64 * 64 + 64)) {}
  ~AlignedBytes() { std::free(data); }
  AlignedBytes(const AlignedBytes&) = delete;
  AlignedBytes& operator=(const AlignedBytes&) = delete;
  void* data;
};

struct Int8Problem {
  Int8Shape shape;
  Int8Quant quant;
  std::vector<uint8_t> input;  // rows of w * cin + extra_row_bytes, then kInt8TensorSlack
  std::vector<int8_t> weights_q;
  std::vector<float> weight_scales, bias;
  std::vector<int8_t> phase_weights_q;  // [4][2][2][cin][cout] when shape.phases
  std::vector<float> phase_scales;      // [4][cout]
  ConvParams params;
  ConstByteView in;
  int c_h = 0, c_w = 0;  // the map the convolution reads (C, or the input)
  int out_h = 0, out_w = 0;
  int out_pixel_extra = 0;  // uint8 output pixels this many bytes further apart (a slice)
};

// Input bytes uniform in 0..255 from `seed` (the slack too: it must not matter), int8 weights
// uniform in -127..127 with per-channel scales that keep outputs of order 1 (input scale 4/255:
// real inputs within [-2, 2] about zero point 128), bias in [-0.5, 0.5).
Int8Problem MakeProblem(const Int8Shape& s, const Int8Quant& q, uint32_t seed) {
  Int8Problem pr;
  pr.shape = s;
  pr.quant = q;
  std::mt19937 rng(seed);
  const ptrdiff_t row = static_cast<ptrdiff_t>(s.w) * s.cin + s.extra_row_bytes;
  pr.input.resize(static_cast<size_t>(s.h * row) + kInt8TensorSlack);
  std::uniform_int_distribution<int> byte(0, 255);
  for (uint8_t& v : pr.input) v = static_cast<uint8_t>(byte(rng));
  const int taps = s.k * s.k;
  pr.weights_q.resize(static_cast<size_t>(taps) * s.cin * s.cout);
  std::uniform_int_distribution<int> weight(-127, 127);
  for (int8_t& v : pr.weights_q) v = static_cast<int8_t>(weight(rng));
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const float fan_in = static_cast<float>(taps * s.cin);
  pr.weight_scales.resize(s.cout);
  for (float& v : pr.weight_scales) v = (0.5f + unit(rng)) * 2.25f / (127.0f * std::sqrt(fan_in));
  pr.bias.resize(s.cout);
  for (float& v : pr.bias) v = unit(rng) - 0.5f;

  ConvParams& p = pr.params;
  p.in_channels = s.cin;
  p.out_channels = s.cout;
  p.kernel_h = p.kernel_w = s.k;
  p.stride_h = p.stride_w = s.stride;
  p.pads = s.pads;
  p.activation = q.act;
  p.leaky_slope = 0.3f;
  p.bias = pr.bias.data();
  p.precision = Precision::kInt8;
  p.weights_q = pr.weights_q.data();
  p.weight_scales = pr.weight_scales.data();
  p.input_quant = {4.0f / 255.0f, q.in_zero_point};
  p.output_quant = {q.out_scale, q.out_zero_point};
  if (s.phases) {
    // Independent of the 3x3 weights: a pixel computed from the wrong form differs.
    pr.phase_weights_q.resize(static_cast<size_t>(16) * s.cin * s.cout);
    for (int8_t& v : pr.phase_weights_q) v = static_cast<int8_t>(weight(rng));
    pr.phase_scales.resize(static_cast<size_t>(4) * s.cout);
    const float phase_fan_in = static_cast<float>(4 * s.cin);
    for (float& v : pr.phase_scales) {
      v = (0.5f + unit(rng)) * 2.25f / (127.0f * std::sqrt(phase_fan_in));
    }
    p.phase_weights_q = pr.phase_weights_q.data();
    p.phase_scales = pr.phase_scales.data();
  }

  pr.in = ConstByteView{pr.input.data(), s.h, s.w, s.cin, row};
  pr.c_h = s.up ? 2 * s.h - s.crop_top - s.crop_bottom : s.h;
  pr.c_w = s.up ? 2 * s.w - s.crop_left - s.crop_right : s.w;
  pr.out_h = (pr.c_h + s.pads.top + s.pads.bottom - s.k) / s.stride + 1;
  pr.out_w = (pr.c_w + s.pads.left + s.pads.right - s.k) / s.stride + 1;
  return pr;
}

// What PackInt8Conv quantises the problem's output with: nothing (float32 output) or its
// output_quant.
const QuantParams* OutQuant(const Int8Problem& pr) {
  return pr.quant.out_float ? nullptr : &pr.params.output_quant;
}

// An output tensor with kGuard spare elements after every row (which no kernel may write), all
// filled with a sentinel.
constexpr int kGuard = 5;
struct Output {
  Output(const Int8Problem& pr)
      : h(pr.out_h), w(pr.out_w), c(pr.shape.cout), stride(pr.shape.cout + pr.out_pixel_extra) {
    if (pr.quant.out_float) {
      f32.assign(static_cast<size_t>(h) * RowElements(), -12345.0f);
    } else {
      u8.assign(static_cast<size_t>(h) * RowElements(), 0xA5);
    }
  }
  ptrdiff_t RowElements() const { return static_cast<ptrdiff_t>(w) * stride + kGuard; }
  void Bind(Int8ConvArgs* args) {
    if (!f32.empty()) {
      args->out_f32 = TensorView{f32.data(), h, w, c, RowElements()};
    } else {
      args->out_u8 = ByteView{u8.data(), h, w, c, RowElements(), stride};
    }
  }
  int h, w, c;
  ptrdiff_t stride;  // elements between pixels
  std::vector<uint8_t> u8;
  std::vector<float> f32;
};

// Element e of an output, floats to the last bit.
std::string Value(const Output& out, ptrdiff_t e) {
  if (out.f32.empty()) return std::to_string(out.u8[e]);
  char text[48];
  std::snprintf(text, sizeof(text), "%.9g (%a)", out.f32[e], out.f32[e]);
  return text;
}

Int8ConvArgs ArgsFor(const Int8Problem& pr, const PackedInt8Conv* conv, Output* out) {
  Int8ConvArgs args;
  args.conv = conv;
  args.in = pr.in;
  args.pads = pr.shape.pads;
  args.upsampled = pr.shape.up;
  args.crop_top = pr.shape.crop_top;
  args.crop_left = pr.shape.crop_left;
  args.c_height = pr.c_h;
  args.c_width = pr.c_w;
  out->Bind(&args);
  return args;
}

// The packing a session gives `kernels`: their narrow kernel where they have one and the
// convolution is narrow (plain, at most 4 inputs and outputs).
PackedInt8Conv PackFor(const Int8Problem& pr, const IsaInt8Kernels* kernels, void* dst) {
  PackedInt8Conv conv = PackInt8Conv(pr.params, kernels->nr, OutQuant(pr), dst);
  conv.narrow = kernels->narrow_name[0] != '\0' && !pr.shape.up && Int8NarrowConv(pr.params);
  return conv;
}

// The reference's output, all rows at once.
Output RunReference(const Int8Problem& pr) {
  AlignedBytes packed(PackedInt8Bytes(pr.params, 0));
  const PackedInt8Conv conv = PackInt8Conv(pr.params, 0, OutQuant(pr), packed.data);
  Output out(pr);
  ref::Conv2dInt8Rows(ArgsFor(pr, &conv, &out), 0, pr.out_h, 0, 1);
  return out;
}

// ---------------------------------------------------------------------------------------------
// The reference against the real arithmetic.

// Dequantised input x = (q - z) * scale, upsampled and cropped for `up`, convolved with the
// dequantised weights in double, plus bias, activation; quantised (rounded half to even) when
// the output is uint8.
struct RealOutput {
  std::vector<double> y;      // before quantisation
  std::vector<double> scale;  // sum of |terms| per value, to bound float rounding
};
RealOutput RealConvolution(const Int8Problem& pr) {
  const Int8Shape& s = pr.shape;
  const ConvParams& p = pr.params;
  // The map the convolution reads, built explicitly.
  std::vector<double> src(static_cast<size_t>(pr.c_h) * pr.c_w * s.cin);
  for (int y = 0; y < pr.c_h; ++y) {
    for (int x = 0; x < pr.c_w; ++x) {
      const int sy = s.up ? (y + s.crop_top) / 2 : y;
      const int sx = s.up ? (x + s.crop_left) / 2 : x;
      for (int c = 0; c < s.cin; ++c) {
        src[(static_cast<size_t>(y) * pr.c_w + x) * s.cin + c] =
            (static_cast<double>(pr.in.pixel(sy, sx)[c]) - p.input_quant.zero_point) *
            static_cast<double>(p.input_quant.scale);
      }
    }
  }
  RealOutput r;
  r.y.assign(static_cast<size_t>(pr.out_h) * pr.out_w * s.cout, 0.0);
  r.scale.assign(r.y.size(), 0.0);
  for (int oy = 0; oy < pr.out_h; ++oy) {
    for (int ox = 0; ox < pr.out_w; ++ox) {
      double* y = &r.y[(static_cast<size_t>(oy) * pr.out_w + ox) * s.cout];
      double* mag = &r.scale[(static_cast<size_t>(oy) * pr.out_w + ox) * s.cout];
      for (int ky = 0; ky < s.k; ++ky) {
        const int iy = oy * s.stride - s.pads.top + ky;
        if (iy < 0 || iy >= pr.c_h) continue;
        for (int kx = 0; kx < s.k; ++kx) {
          const int ix = ox * s.stride - s.pads.left + kx;
          if (ix < 0 || ix >= pr.c_w) continue;
          const double* x = &src[(static_cast<size_t>(iy) * pr.c_w + ix) * s.cin];
          for (int ci = 0; ci < s.cin; ++ci) {
            const int8_t* w =
                &pr.weights_q[((static_cast<size_t>(ky) * s.k + kx) * s.cin + ci) * s.cout];
            for (int o = 0; o < s.cout; ++o) {
              const double term = x[ci] * w[o] * static_cast<double>(pr.weight_scales[o]);
              y[o] += term;
              mag[o] += std::abs(term);
            }
          }
        }
      }
      for (int o = 0; o < s.cout; ++o) {
        y[o] += pr.bias[o];
        mag[o] += std::abs(pr.bias[o]);
        if (p.activation == Activation::kLeakyRelu && y[o] < 0) {
          y[o] *= static_cast<double>(p.leaky_slope);
        } else if (p.activation == Activation::kRelu && y[o] < 0) {
          y[o] = 0;
        }
      }
    }
  }
  return r;
}

TEST(Int8Reference, MatchesRealArithmeticWithinOneQuantum) {
  const std::vector<Int8Shape> shapes = {
      Conv(17, 23, 12, 4, 2),            // conv0 of the 1/16-width model, odd size
      Conv(9, 12, 4, 8, 2),              // conv1
      Conv(7, 9, 32, 64, 1),             // conv4
      UpConv(4, 6, 64, 32),              // conv6: upsample -> conv
      UpConv(5, 7, 8, 4, 4, 0),          // conv9 with the 540-row crop
      UpConv(5, 7, 6, 5, 1, 3),          // odd crop
      Conv(9, 13, 64, 3, 1),             // the output convolution (float out below)
      Conv(5, 8, 256, 100, 2),           // wide, cout not a multiple of 64
      {6, 7, 3, 9, 5, 1, {2, 2, 2, 2}},  // 5x5
      {6, 7, 6, 9, 1, 1, {1, 0, 0, 1}},  // 1x1 with rows and columns of pure padding
  };
  const std::vector<Int8Quant> quants = {
      {128, 128, Activation::kLeakyRelu, false, 1.0f / 32},
      {0, 0, Activation::kRelu, false, 1.0f / 32},
      {255, 255, Activation::kNone, false, 1.0f / 256},  // saturating both ways
      {128, 0, Activation::kLeakyRelu, true, 1.0f},
      {7, 0, Activation::kNone, true, 1.0f},
  };
  int checked = 0;
  for (size_t i = 0; i < shapes.size(); ++i) {
    for (size_t j = 0; j < quants.size(); ++j) {
      const Int8Problem pr =
          MakeProblem(shapes[i], quants[j], 7 + 11 * static_cast<uint32_t>(i * quants.size() + j));
      SCOPED_TRACE(Describe(pr.shape) + " " + Describe(pr.quant));
      ASSERT_GT(pr.out_h, 0);
      ASSERT_GT(pr.out_w, 0);
      const Output got = RunReference(pr);
      const RealOutput want = RealConvolution(pr);
      const int cout = pr.shape.cout;
      int bad = 0, saturated = 0;
      for (int oy = 0; oy < pr.out_h; ++oy) {
        for (int ox = 0; ox < pr.out_w; ++ox) {
          for (int o = 0; o < cout; ++o) {
            const size_t wi = (static_cast<size_t>(oy) * pr.out_w + ox) * cout + o;
            const size_t gi = static_cast<size_t>(oy) * (pr.out_w * cout + kGuard) + ox * cout + o;
            const double y = want.y[wi];
            if (pr.quant.out_float) {
              // float(acc), the float multiplier and one multiply and add: a few ulps of the
              // magnitudes summed.
              const double tol = 1e-6 * want.scale[wi] + 1e-7;
              if (std::abs(static_cast<double>(got.f32[gi]) - y) > tol && bad++ < 5) {
                ADD_FAILURE() << "(" << oy << "," << ox << "," << o << "): " << got.f32[gi]
                              << " vs real " << y;
              }
            } else {
              const double t = std::clamp(y / pr.quant.out_scale, -512.0, 512.0);
              const double q = std::clamp(std::nearbyint(t) + pr.quant.out_zero_point, 0.0, 255.0);
              saturated += q == 0.0 || q == 255.0;
              if (std::abs(got.u8[gi] - q) > 1.0 && bad++ < 5) {
                ADD_FAILURE() << "(" << oy << "," << ox << "," << o << "): " << int(got.u8[gi])
                              << " vs real " << q << " (" << t << " quanta)";
              }
            }
            ++checked;
          }
        }
      }
      EXPECT_EQ(bad, 0);
      if (pr.quant.out_scale < 1.0f / 128) {
        EXPECT_GT(saturated, 0) << "a saturating case clamps";
      }
    }
  }
  EXPECT_GT(checked, 50000);
}

// ---------------------------------------------------------------------------------------------
// The SIMD kernels against the reference: the checks every ISA's kernel tables share, run by
// the fixture of each ISA (Int8Vnni, Int8NeonDot) on the tables that this CPU runs.

class Int8Kernels : public ::testing::Test {
 protected:
  // Runs every table's kernel on `pr` as threads would (rows split in three; the last third's
  // blocks split in two), and returns the number of output values compared per table, all of
  // which must equal the reference's bytes.
  size_t ExpectBitExact(const Int8Problem& pr) {
    SCOPED_TRACE(Describe(pr.shape) + " " + Describe(pr.quant));
    EXPECT_GT(pr.out_h, 0);
    EXPECT_GT(pr.out_w, 0);
    if (pr.out_h <= 0 || pr.out_w <= 0) return 0;
    const Output want = RunReference(pr);
    for (const IsaInt8Kernels* kernels : tables_) {
      SCOPED_TRACE(pr.shape.up ? kernels->upconv_name : kernels->conv_name);
      AlignedBytes packed(PackedInt8Bytes(pr.params, kernels->nr));
      PackedInt8Conv conv = PackFor(pr, kernels, packed.data);
      conv.amx_1x4 = amx_1x4_;
      Output got(pr);
      const Int8ConvArgs args = ArgsFor(pr, &conv, &got);
      const Int8ConvRowsFn fn = pr.shape.up ? kernels->upconv : kernels->conv;
      const int r1 = pr.out_h / 3, r2 = pr.out_h - pr.out_h / 3;
      const int half = conv.blocks / 2;
      fn(args, 0, r1, 0, conv.blocks);
      fn(args, r1, r2, 0, conv.blocks);
      fn(args, r2, pr.out_h, 0, half);
      fn(args, r2, pr.out_h, half, conv.blocks);
      ExpectSameBytes(pr, got, want);
    }
    return static_cast<size_t>(pr.out_h) * pr.out_w * pr.shape.cout;
  }

  // Byte for byte, the guards after every row included.
  static void ExpectSameBytes(const Int8Problem& pr, const Output& got, const Output& want) {
    const size_t n = pr.quant.out_float ? got.f32.size() * sizeof(float) : got.u8.size();
    const uint8_t* g =
        pr.quant.out_float ? reinterpret_cast<const uint8_t*>(got.f32.data()) : got.u8.data();
    const uint8_t* w =
        pr.quant.out_float ? reinterpret_cast<const uint8_t*>(want.f32.data()) : want.u8.data();
    if (std::memcmp(g, w, n) != 0) {
      const size_t elem = pr.quant.out_float ? sizeof(float) : 1;
      size_t i = 0;
      while (std::memcmp(g + i, w + i, elem) == 0) i += elem;
      const ptrdiff_t e = static_cast<ptrdiff_t>(i / elem), row = got.RowElements();
      const int oy = static_cast<int>(e / row), ox = static_cast<int>((e % row) / got.stride);
      const int o = static_cast<int>((e % row) % got.stride);
      ADD_FAILURE() << "first difference at (" << oy << "," << ox << "," << o << ")"
                    << (e % row >= static_cast<ptrdiff_t>(pr.out_w) * got.stride ? " (a row guard)"
                        : o >= pr.shape.cout ? " (between pixels)"
                                             : "")
                    << ": got " << Value(got, e) << ", reference " << Value(want, e);
    }
  }

  void CheckEveryModelLayer();
  void CheckEdgeShapes();
  void CheckPhaseKernels();
  void CheckRowAndBlockRanges();
  void CheckAmxBlocking();
  void CheckColumnRanges();
  void CheckSlices();

  // The tables under test (set by the ISA's fixture; the reference runs once for all of them).
  bool amx_1x4_ = false;  // PackedInt8Conv::amx_1x4 for the kernels under test
  std::vector<const IsaInt8Kernels*> tables_;
};

class Int8Vnni : public Int8Kernels {
 protected:
  void SetUp() override {
    kernels_ = Int8KernelsFor(Isa::kAvx512);
    if (kernels_ == nullptr) {
      GTEST_SKIP() << "no AVX-512 VNNI int8 kernels on this CPU or in this build (supported ISAs: "
                   << SupportedIsaList() << ")";
    }
    tables_ = {kernels_};
  }

  const IsaInt8Kernels* kernels_ = nullptr;
};

// The AMX kernels' blocking and packing over the scalar emulation of the tiles (every CPU), and
// the hardware's kernels where the CPU and the OS let sfrt use AMX.
class Int8AmxEmulated : public Int8Kernels {
 protected:
  void SetUp() override {
    tables_ = {amx::Int8KernelsEmulated()};
    violations_before_ = amx::EmulatedTileViolations();
  }
  void TearDown() override {
    EXPECT_EQ(amx::EmulatedTileViolations(), violations_before_)
        << "a tile operation broke AMX's rules (shapes beyond palette 1, or a tdpbusd whose "
           "operands disagree)";
  }
  long violations_before_ = 0;
};

class Int8Amx : public Int8Kernels {
 protected:
  void SetUp() override {
    const IsaInt8Kernels* amx = avx512::Int8KernelsAmx();
    if (amx == nullptr) {
      GTEST_SKIP() << "no AMX here (it needs AMX-TILE and AMX-INT8, the OS's tile state, palette "
                      "1 in CPUID leaf 0x1D and Linux's tile permission): the emulated tiles "
                      "(Int8AmxEmulated) test the same blocking";
    }
    tables_ = {amx};
  }
};

// The NEON dot-product kernels: usdot (i8mm) and sdot (dotprod), each where the CPU has it (both
// under qemu-aarch64 -cpu max).
class Int8NeonDot : public Int8Kernels {
 protected:
  void SetUp() override {
#if SFRT_TEST_NEON_DOT
    usdot_ = neon::Int8KernelsUsdot();
    sdot_ = neon::Int8KernelsSdot();
    if (sdot_ == nullptr && usdot_ == nullptr) {
      GTEST_SKIP() << "this CPU lacks the dot-product extension (HWCAP_ASIMDDP): the NEON int8 "
                      "kernels are off";
    }
    for (const IsaInt8Kernels* k : {usdot_, sdot_}) {
      if (k != nullptr) tables_.push_back(k);
    }
    if (usdot_ == nullptr) std::printf("[          ] no i8mm (HWCAP2_I8MM): sdot only\n");
#else
    GTEST_SKIP() << "no NEON dot-product int8 kernels in this build (aarch64 only; supported "
                    "ISAs: "
                 << SupportedIsaList() << ")";
#endif
  }

  const IsaInt8Kernels* sdot_ = nullptr;
  const IsaInt8Kernels* usdot_ = nullptr;
};

// The epilogue variants a layer is checked with: zero points at 0, 128 and 255, every
// activation, uint8 (normal and saturating scales) and float outputs; ReLU into a uint8 output
// whose zero point is not 0 (negative sums must give the zero point, not less).
std::vector<Int8Quant> EveryQuant() {
  return {
      {128, 128, Activation::kLeakyRelu, false, 1.0f / 32},
      {0, 0, Activation::kRelu, false, 1.0f / 32},
      {200, 100, Activation::kRelu, false, 1.0f / 256},
      {255, 255, Activation::kNone, false, 1.0f / 256},
      {128, 0, Activation::kLeakyRelu, false, 1.0f / 256},
      {3, 128, Activation::kLeakyRelu, true, 1.0f},
      {255, 0, Activation::kRelu, true, 1.0f},
  };
}

// The AMX kernels' tile epilogue (AVX-512 code shared with the VNNI and AVX512_BF16 kernels)
// gives the emulated tiles' scalar one's bytes on random sums: int8 with every epilogue variant
// (ReLU folded into the quantisation or not, zero points, saturating scales, float output) and
// bf16 with each activation into bf16 and float, for every count of valid channels' vectors. It
// runs wherever AVX-512 VNNI and AVX512_BF16 do, so a CPU without AMX tests it too.
TEST(AmxTileEpilogue, MatchesTheEmulatedTilesEpilogueBitForBit) {
  const avx512::AmxTileFinishFn finish = avx512::AmxTileFinish();
  if (finish == nullptr) {
    GTEST_SKIP() << "needs AVX-512 VNNI and AVX512_BF16 and a build with the AMX kernels";
  }
  constexpr int kTile = simd::kAmxPixels * 16;  // 32-bit values per C tile
  std::mt19937 rng(31);
  // Sums whose outputs land inside 0..255 and past both ends.
  std::uniform_int_distribution<int32_t> big(-(1 << 14), 1 << 14);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  alignas(64) int32_t sums[4 * kTile];
  alignas(64) float float_sums[4 * kTile];  // bf16's, passed as their bits
  alignas(64) int32_t init[64];
  alignas(64) float multiplier[64];
  alignas(64) float bias[64];
  constexpr size_t kPixelBytes = 64 * sizeof(float);
  std::vector<uint8_t> got(simd::kAmxPixels * kPixelBytes), want(got.size());
  int runs = 0;
  // Both epilogues of one tile, pixels `step` bytes apart, into equally prefilled outputs.
  auto compare = [&](bool quantized, const int32_t* bits, const simd::DotEpilogue& e,
                     ptrdiff_t step, const std::string& what) {
    std::fill(got.begin(), got.end(), 0xA5);
    std::fill(want.begin(), want.end(), 0xA5);
    finish(quantized, bits, quantized ? init : nullptr, e, got.data(), step);
    if (quantized) {
      simd::AmxFinishScalar<true>(bits, init, e, want.data(), step);
    } else {
      simd::AmxFinishScalar<false>(bits, nullptr, e, want.data(), step);
    }
    EXPECT_EQ(got, want) << what;
    ++runs;
  };
  for (int valid : {64, 50, 33, 16, 5}) {
    for (const Int8Quant& q : EveryQuant()) {
      for (int32_t& v : sums) v = big(rng);
      for (int o = 0; o < 64; ++o) {
        init[o] = big(rng) / 16;
        multiplier[o] = (1.5f + unit(rng)) * 1e-4f;
        bias[o] = unit(rng);
      }
      const simd::DotEpilogue e = {multiplier,       bias,        q.act,
                                   0.125f,           q.out_float, 1.0f / q.out_scale,
                                   q.out_zero_point, valid};
      compare(true, sums, e, q.out_float ? kPixelBytes : 64,
              "int8, " + std::to_string(valid) + " channels, " + Describe(q));
    }
    for (Activation act : {Activation::kNone, Activation::kRelu, Activation::kLeakyRelu}) {
      for (bool out_float : {false, true}) {
        for (float& v : float_sums) v = 8.0f * unit(rng);
        for (int o = 0; o < 64; ++o) bias[o] = unit(rng);
        const simd::DotEpilogue e = {nullptr, bias, act, 0.125f, out_float, 0.0f, 0, valid};
        compare(false, reinterpret_cast<const int32_t*>(float_sums), e,
                out_float ? kPixelBytes : 64 * sizeof(uint16_t),
                "bf16, " + std::to_string(valid) + " channels, activation " +
                    std::to_string(static_cast<int>(act)) + (out_float ? ", float out" : ""));
      }
    }
  }
  std::printf("[          ] %d tiles of 16 pixels bit for bit\n", runs);
}

TEST_F(Int8Vnni, KernelNamesCarryIsaAndTile) {
  EXPECT_EQ(kernels_->nr, 64);
  for (const std::string name : {kernels_->conv_name, kernels_->upconv_name}) {
    EXPECT_NE(name.find("u8s8__avx512vnni_"), std::string::npos) << name;
    EXPECT_TRUE(name.ends_with("x" + std::to_string(kernels_->nr))) << name;
  }
  // Four pixels x four output channels; 16 pixels x four output channels.
  EXPECT_EQ(std::string(kernels_->few_out_name), "conv2d_fewout_u8s8__avx512vnni_8x3");
  EXPECT_EQ(std::string(kernels_->narrow_name), "conv2d_narrow_u8s8__avx512vnni_16x4");
}

TEST_F(Int8NeonDot, KernelNamesCarryIsaAndTileAndTheSessionGetsTheBest) {
  for (const IsaInt8Kernels* k : tables_) {
    EXPECT_EQ(k->nr, 16);
    const std::string isa = k == usdot_ ? "u8s8__neon_usdot_" : "u8s8__neon_sdot_";
    for (const std::string name : {k->conv_name, k->upconv_name}) {
      EXPECT_NE(name.find(isa), std::string::npos) << name;
      EXPECT_TRUE(name.ends_with("x" + std::to_string(k->nr))) << name;
    }
  }
  EXPECT_EQ(Int8KernelsFor(Isa::kNeon), tables_.front()) << "usdot where i8mm exists, else sdot";
}

// SceneEDNet's layers in order, at the published widths on small maps (conv0..conv3 at stride 2
// from odd and even sizes, conv4/conv5 at 1024 channels, the four upsample -> conv layers, the
// last with the 540-row crop of 4, the 64 -> 3 float output), and the 1/16-width default model.
void Int8Kernels::CheckEveryModelLayer() {
  struct Layer {
    Int8Shape shape;
    bool out_float;
  };
  const std::vector<Layer> published = {
      {Conv(11, 19, 12, 64, 2), false},  {Conv(10, 13, 64, 128, 2), false},
      {Conv(7, 11, 128, 256, 2), false}, {Conv(5, 10, 256, 512, 2), false},
      {Conv(3, 9, 512, 1024, 1), false}, {Conv(3, 9, 1024, 1024, 1), false},
      {UpConv(2, 5, 1024, 512), false},  {UpConv(3, 5, 512, 256), false},
      {UpConv(4, 7, 256, 128), false},   {UpConv(5, 8, 128, 64, 4, 0), false},
      {Conv(7, 13, 64, 3, 1), true},
  };
  const std::vector<Layer> default_model = {
      {Conv(24, 32, 12, 4, 2), false},     {Conv(12, 16, 4, 8, 2), false},
      {Conv(6, 8, 8, 16, 2), false},       {Conv(3, 4, 16, 32, 2), false},
      {Conv(2, 2, 32, 64, 1), false},      {Conv(2, 2, 64, 64, 1), false},
      {UpConv(2, 2, 64, 32), false},       {UpConv(4, 4, 32, 16), false},
      {UpConv(8, 8, 16, 8), false},        {UpConv(16, 16, 8, 4, 4, 0), false},
      {Conv(27, 32, 4, 3, 1), true},       {Conv(48, 64, 12, 4, 2), false},  // at 96x128
      {UpConv(12, 17, 8, 4, 4, 0), false},
  };
  size_t values = 0;
  int runs = 0;
  uint32_t seed = 1000;
  for (const std::vector<Layer>* table : {&published, &default_model}) {
    for (const Layer& layer : *table) {
      for (Int8Quant q : EveryQuant()) {
        if (q.out_float != layer.out_float) continue;
        values += ExpectBitExact(MakeProblem(layer.shape, q, seed++));
        ++runs;
      }
    }
  }
  RecordProperty("values", std::to_string(values));
  std::printf("[          ] %d runs, %zu output values bit for bit, %zu kernel table(s)\n", runs,
              values, tables_.size());
}

TEST_F(Int8Vnni, MatchesReferenceBitForBitOnEveryModelLayer) { CheckEveryModelLayer(); }
TEST_F(Int8NeonDot, MatchesReferenceBitForBitOnEveryModelLayer) { CheckEveryModelLayer(); }

// Shapes for the edges of the kernels, each with every epilogue variant.
void Int8Kernels::CheckEdgeShapes() {
  const std::vector<Int8Shape> shapes = {
      {7, 31, 3, 100, 3, 1, {1, 1, 1, 1}},  // cin 3 (reads past each pixel), cout 100
      {8, 17, 6, 70, 3, 2, {0, 0, 1, 1}},   // cin 6, stride 2, odd width
      {9, 8, 12, 65, 3, 2, {1, 1, 1, 1}},   // one channel past a block
      {5, 40, 16, 48, 3, 1, {1, 1, 1, 1}},  // three vectors: the 8x3 tile
      {6, 19, 5, 33, 3, 1, {1, 1, 1, 1}},   // 8x3 with a partial vector
      {6, 23, 9, 20, 3, 1, {1, 1, 1, 1}},   // 8x2
      {5, 21, 7, 1, 3, 1, {1, 1, 1, 1}},    // one output channel
      {1, 1, 12, 20, 3, 1, {1, 1, 1, 1}},   // one pixel: every tap but the centre is padding
      {1, 37, 6, 9, 3, 1, {1, 1, 1, 1}},    // one row
      {23, 1, 6, 9, 3, 1, {1, 1, 1, 1}},    // one column
      {6, 7, 10, 12, 1, 1, {0, 0, 0, 0}},   // 1x1
      {6, 7, 10, 12, 1, 1, {1, 2, 1, 0}},   // 1x1 with rows and columns of pure padding
      {9, 14, 3, 21, 5, 1, {2, 2, 2, 2}},   // 5x5
      {12, 12, 4, 6, 3, 3, {1, 1, 1, 1}},   // stride 3
      {10, 26, 9, 40, 3, 1, {2, 0, 0, 2}},  // asymmetric, large pads
      {11, 19, 8, 8, 7, 2, {3, 3, 3, 3}},   // 7x7 (49 taps), stride 2
      {9, 18, 12, 32, 3, 1, {1, 1, 1, 1}, false, 0, 0, 0, 0, 60},  // input view, row stride
      {9, 18, 13, 130, 3, 1, {1, 1, 1, 1}, false, 0, 0, 0, 0, 3},  // cin 13, 3 blocks
      {3, 60, 64, 192, 3, 1, {1, 1, 1, 1}},                        // long rows of full 6x64 tiles
      {7, 13, 20, 19, 3, 1, {1, 1, 1, 1}},  // cin 20: one 16-channel load and one group
      {6, 11, 28, 44, 3, 2, {1, 1, 1, 1}},  // cin 28: one 16-channel load and three groups
      {5, 12, 42, 13, 3, 1, {1, 1, 1, 1}},  // cin 42: two 16-channel loads, 3 groups, 2 junk
      {4, 23, 16, 12, 3, 1, {1, 1, 1, 1}},  // NEON 8x3 on long rows
      {6, 19, 10, 56, 3, 1, {1, 1, 1, 1}},  // 4 vectors, the last partial (56 of 64 bytes)
      // Few outputs (at most 4, at least 16 inputs): tiles of 8 pixels (4 for 4 outputs), then
      // of 4, where the window is inside the input, single pixels elsewhere.
      {6, 37, 64, 3, 3, 1, {1, 1, 1, 1}},   // the output layer's channels; 3 single pixels
      {5, 14, 64, 3, 3, 1, {1, 1, 1, 1}},   // 8 + 4 pixels inside each row
      {5, 30, 70, 4, 3, 2, {1, 1, 1, 1}},   // cin 70 (a masked tail), stride 2
      {7, 22, 16, 1, 5, 1, {2, 2, 2, 2}},   // 5x5, one output
      {4, 41, 130, 2, 3, 1, {0, 0, 2, 2}},  // three loads per tap, pads at the bottom and right
      {5, 11, 20, 3, 3, 1, {1, 1, 1, 1}, false, 0, 0, 0, 0, 40},  // input view, row stride
      {3, 9, 24, 3, 7, 1, {3, 3, 3, 3}},                          // no window inside the input
      // Narrow (at most 4 inputs and 4 outputs): blocks of 16 pixels where the window is inside
      // the input, the tiles elsewhere.
      {6, 40, 4, 3, 3, 1, {1, 1, 1, 1}},  // the 1/16-width output layer; a partial block
      {5, 37, 3, 4, 3, 1, {1, 1, 1, 1}},  // cin 3: pixels 3 bytes apart (a gather)
      {7, 41, 1, 2, 3, 2, {1, 1, 1, 1}},  // cin 1, stride 2 (a gather)
      {6, 35, 4, 1, 5, 1, {2, 2, 2, 2}},  // 5x5, one output
      {4, 20, 2, 3, 3, 1, {0, 0, 2, 2}},  // pads at the bottom and right
      {5, 38, 4, 3, 3, 1, {1, 1, 1, 1}, false, 0, 0, 0, 0, 20},  // input view, row stride
      UpConv(5, 8, 12, 35, 1, 1),                                // odd crop: phases swap
      UpConv(5, 8, 6, 70, 3, 5),
      UpConv(6, 9, 7, 17),
      UpConv(1, 1, 5, 6),     // 2x2 upsampled: no interior pixel
      UpConv(1, 9, 3, 6, 1),  // a single upsampled row after the crop
      UpConv(3, 23, 37, 100, 4, 1),
      UpConv(4, 30, 24, 64, 0, 3),
  };
  std::vector<Int8Shape> more = shapes;
  // Crops on every side, explicit asymmetric pads.
  Int8Shape s = UpConv(6, 9, 7, 17, 2, 1);
  s.crop_bottom = s.crop_right = 1;
  more.push_back(s);
  s = UpConv(4, 7, 9, 20, 0, 1);
  s.pads = {0, 0, 2, 2};
  more.push_back(s);
  s = UpConv(4, 7, 9, 20, 1, 0);
  s.pads = {2, 2, 0, 0};
  s.extra_row_bytes = 5;
  more.push_back(s);

  size_t values = 0;
  int runs = 0;
  uint32_t seed = 5000;
  for (const Int8Shape& shape : more) {
    for (const Int8Quant& q : EveryQuant()) {
      values += ExpectBitExact(MakeProblem(shape, q, seed++));
      ++runs;
    }
  }
  std::printf("[          ] %d runs, %zu output values bit for bit, %zu kernel table(s)\n", runs,
              values, tables_.size());
}

TEST_F(Int8Vnni, MatchesReferenceBitForBitOnEdgeShapes) { CheckEdgeShapes(); }
TEST_F(Int8NeonDot, MatchesReferenceBitForBitOnEdgeShapes) { CheckEdgeShapes(); }

// The fused upsample with phase kernels (the interior from the 2x2 kernel of each pixel's
// phase, the border from the 3x3 weights): crops of both parities, rows long enough for full
// tiles of every second pixel, partial vectors and blocks, each with every epilogue variant.
void Int8Kernels::CheckPhaseKernels() {
  std::vector<Int8Shape> shapes = {
      UpConv(5, 8, 12, 35, 1, 1),  UpConv(5, 8, 6, 70, 3, 5),    UpConv(6, 9, 7, 17),
      UpConv(1, 1, 5, 6),          UpConv(1, 9, 3, 6, 1),        UpConv(3, 23, 37, 100, 4, 1),
      UpConv(4, 30, 24, 64, 0, 3), UpConv(4, 13, 20, 16, 0, 0),  UpConv(3, 17, 64, 12, 1, 0),
      UpConv(5, 21, 16, 4, 4, 0),  UpConv(2, 40, 32, 130, 0, 1),
  };
  Int8Shape s = UpConv(6, 9, 7, 17, 2, 1);
  s.crop_bottom = s.crop_right = 1;
  shapes.push_back(s);
  s = UpConv(4, 7, 9, 20, 0, 1);
  s.pads = {0, 0, 2, 2};
  shapes.push_back(s);
  s = UpConv(4, 7, 9, 20, 1, 0);
  s.pads = {2, 2, 0, 0};
  s.extra_row_bytes = 5;
  shapes.push_back(s);
  size_t values = 0;
  int runs = 0;
  uint32_t seed = 9000;
  for (Int8Shape shape : shapes) {
    shape.phases = true;
    for (const Int8Quant& q : EveryQuant()) {
      values += ExpectBitExact(MakeProblem(shape, q, seed++));
      ++runs;
    }
  }
  std::printf("[          ] %d runs, %zu output values bit for bit, %zu kernel table(s)\n", runs,
              values, tables_.size());
}

TEST_F(Int8Vnni, MatchesReferenceBitForBitWithPhaseKernels) { CheckPhaseKernels(); }
TEST_F(Int8AmxEmulated, MatchesReferenceBitForBitWithPhaseKernels) { CheckPhaseKernels(); }
TEST_F(Int8Amx, MatchesReferenceBitForBitWithPhaseKernels) { CheckPhaseKernels(); }
TEST_F(Int8NeonDot, MatchesReferenceBitForBitWithPhaseKernels) { CheckPhaseKernels(); }

// Every row and every block called on its own (the finest split a pool makes), in reverse
// order, on a layer with three blocks, the last partial (150 channels for blocks of 64, 37 for
// blocks of 16).
void Int8Kernels::CheckRowAndBlockRanges() {
  for (const IsaInt8Kernels* kernels : tables_) {
    SCOPED_TRACE(kernels->conv_name);
    const int cout = 2 * kernels->nr + kernels->nr * 11 / 32;
    for (const Int8Shape& shape : {Conv(9, 14, 20, cout, 1), UpConv(4, 7, 20, cout, 1, 1)}) {
      const Int8Problem pr = MakeProblem(shape, Int8Quant{}, 77);
      SCOPED_TRACE(Describe(pr.shape));
      const Output want = RunReference(pr);
      AlignedBytes packed(PackedInt8Bytes(pr.params, kernels->nr));
      const PackedInt8Conv conv =
          PackInt8Conv(pr.params, kernels->nr, &pr.params.output_quant, packed.data);
      ASSERT_EQ(conv.blocks, 3);
      Output got(pr);
      const Int8ConvArgs args = ArgsFor(pr, &conv, &got);
      const Int8ConvRowsFn fn = shape.up ? kernels->upconv : kernels->conv;
      for (int row = pr.out_h - 1; row >= 0; --row) {
        for (int blk = conv.blocks - 1; blk >= 0; --blk) fn(args, row, row + 1, blk, blk + 1);
      }
      EXPECT_EQ(got.u8, want.u8);
    }
  }
}

TEST_F(Int8Vnni, RowAndBlockRangesCalledSeparatelyComposeTheWholeOutput) {
  CheckRowAndBlockRanges();
}
TEST_F(Int8NeonDot, RowAndBlockRangesCalledSeparatelyComposeTheWholeOutput) {
  CheckRowAndBlockRanges();
}

// Shapes where the tiles do the work (the model table's maps are mostly narrower than a tile, so
// with the emulation they would test the fallback, slowly): rows with groups of 16 interior
// pixels (stride 1 and 2)
// and leftovers, input channels of one group (3: read past the pixel), under one chunk of 16
// groups (12, 36), exactly one (64), a chunk and a tail (100, 200), several (256, 1024); one,
// partial and several output blocks of 64; 1x1, 3x3 and 5x5; a float output; rows too short for
// a tile; the few-output layer (one C tile); under 16 groups the fallback computes the layer, so
// the 1x1, 5x5, padded and row-stride layouts come again with 16 groups or more. The fused upsample
// with phase kernels, where the tiles take each column phase's interior pixels: both crop parities,
// a chunk and a tail, partial blocks, few outputs, rows whose last tile overlaps the one before,
// asymmetric pads.
void Int8Kernels::CheckAmxBlocking() {
  std::vector<Int8Shape> shapes = {
      Conv(5, 40, 3, 64, 1),
      Conv(4, 41, 12, 100, 1),
      Conv(5, 75, 36, 64, 2),
      Conv(3, 38, 64, 64, 1),
      Conv(4, 50, 100, 130, 1),
      Conv(3, 35, 200, 64, 1),
      Conv(3, 34, 256, 128, 1),
      Conv(3, 34, 1024, 64, 1),
      {4, 40, 20, 70, 1, 1, SameUpper(4, 40, 1, 1)},
      {6, 44, 9, 33, 5, 2, SameUpper(6, 44, 5, 2)},
      Conv(5, 12, 64, 64, 1),
      Conv(5, 40, 64, 3, 1),
      // The same layouts with 16 groups or more, which the tiles take.
      Conv(4, 50, 160, 130, 1),
      {4, 40, 64, 70, 1, 1, SameUpper(4, 40, 1, 1)},
      {6, 80, 64, 33, 5, 2, SameUpper(6, 80, 5, 2)},
      Conv(3, 70, 64, 70, 1),
      // The 2 x 2 blocking's halves of 32 channels with one channel tile in the last (40:
      // 2 + 1 C tiles) and a block of one half (20), rows of an odd number of pixel tiles.
      Conv(3, 40, 128, 40, 1),
      Conv(4, 33, 64, 20, 1),
  };
  Int8Shape padded = Conv(6, 37, 40, 64, 1);
  padded.pads = {0, 2, 2, 0};
  shapes.push_back(padded);
  Int8Shape view = Conv(5, 36, 24, 64, 1);
  view.extra_row_bytes = 7;
  shapes.push_back(view);
  for (int cin : {64, 96}) {
    Int8Shape wide_padded = Conv(6, 37, cin, 64, 1);
    wide_padded.pads = {0, 2, 2, 0};
    wide_padded.extra_row_bytes = 5;
    shapes.push_back(wide_padded);
  }
  for (Int8Shape up :
       {UpConv(4, 20, 64, 64), UpConv(3, 24, 64, 130, 1, 1), UpConv(3, 19, 100, 64, 0, 1),
        UpConv(4, 37, 128, 3, 4, 0), UpConv(2, 17, 64, 64, 1, 0), UpConv(3, 20, 64, 100, 0, 1)}) {
    up.phases = true;
    shapes.push_back(up);
  }
  Int8Shape up_pads = UpConv(3, 21, 64, 70, 1, 0);
  up_pads.phases = true;
  up_pads.pads = {0, 2, 2, 0};
  up_pads.extra_row_bytes = 5;
  shapes.push_back(up_pads);
  size_t values = 0;
  uint32_t seed = 7000;
  for (const Int8Shape& shape : shapes) {
    for (const Int8Quant& q : EveryQuant()) {
      if (shape.cout == 3 && !q.out_float) continue;
      values += ExpectBitExact(MakeProblem(shape, q, seed++));
    }
  }
  std::printf("[          ] %zu output values bit for bit\n", values);
}

// Each row computed as three column ranges (Int8ConvArgs::col_begin/col_end, as the AMX kernels
// hand their borders over), splits inside the border and inside the interior, gives the whole
// row's bytes, for the plain convolution, the fused upsample, the few-output layer and the
// narrow one (float output, as the model's); and a call for columns [9, 12) alone writes nothing
// outside them.
void Int8Kernels::CheckColumnRanges() {
  for (const IsaInt8Kernels* kernels : tables_) {
    SCOPED_TRACE(kernels->conv_name);
    Int8Shape up = UpConv(4, 19, 20, 70, 1, 1);  // the fused upsample, phase kernels
    up.phases = true;
    for (const Int8Shape& shape : {Conv(5, 37, 20, 70, 1), Conv(6, 41, 9, 33, 2), up,
                                   Conv(4, 37, 64, 3, 1), Conv(4, 40, 4, 3, 1)}) {
      Int8Quant quant;
      quant.out_float = shape.cout == 3;
      const Int8Problem pr = MakeProblem(shape, quant, 91);
      SCOPED_TRACE(Describe(pr.shape));
      const Output want = RunReference(pr);
      AlignedBytes packed(PackedInt8Bytes(pr.params, kernels->nr));
      const PackedInt8Conv conv = PackFor(pr, kernels, packed.data);
      const Int8ConvRowsFn fn = shape.up ? kernels->upconv : kernels->conv;
      Output got(pr);
      Int8ConvArgs args = ArgsFor(pr, &conv, &got);
      for (auto [b, e] : {std::pair{0, 1}, {1, 9}, {9, pr.out_w}}) {
        args.col_begin = b;
        args.col_end = e;
        fn(args, 0, pr.out_h, 0, conv.blocks);
      }
      ExpectSameBytes(pr, got, want);

      Output part(pr);
      const Output untouched(pr);
      args = ArgsFor(pr, &conv, &part);
      args.col_begin = 9;
      args.col_end = 12;
      fn(args, 0, pr.out_h, 0, conv.blocks);
      const size_t pixel_bytes = static_cast<size_t>(pr.shape.cout) *
                                 (pr.quant.out_float ? sizeof(float) : sizeof(uint8_t));
      for (int y = 0; y < pr.out_h; ++y) {
        for (int x = 0; x < pr.out_w; ++x) {
          const size_t at = (static_cast<size_t>(y) * part.RowElements() +
                             static_cast<size_t>(x) * pr.shape.cout) *
                            (pr.quant.out_float ? sizeof(float) : sizeof(uint8_t));
          const auto* p = pr.quant.out_float
                              ? reinterpret_cast<const uint8_t*>(part.f32.data()) + at
                              : part.u8.data() + at;
          const auto* u = pr.quant.out_float
                              ? reinterpret_cast<const uint8_t*>(untouched.f32.data()) + at
                              : untouched.u8.data() + at;
          const bool inside = x >= 9 && x < 12;
          EXPECT_EQ(std::memcmp(p, u, pixel_bytes) != 0, inside)
              << "pixel (" << y << "," << x << ") " << (inside ? "not written" : "written");
        }
      }
    }
  }
}

TEST_F(Int8Vnni, ColumnRangesComposeTheWholeRow) { CheckColumnRanges(); }
TEST_F(Int8NeonDot, ColumnRangesComposeTheWholeRow) { CheckColumnRanges(); }
TEST_F(Int8AmxEmulated, ColumnRangesComposeTheWholeRow) { CheckColumnRanges(); }

// The problem with its input copied into a slice of wider pixels (`in_extra` bytes of 0x5A after
// each pixel's channels) and its uint8 output written as a slice (`out_extra` sentinel bytes
// after each pixel's channels), as a session lays out tensors that live in a Concat's.
Int8Problem AsSlices(const Int8Problem& dense, int in_extra, int out_extra) {
  Int8Problem pr = dense;
  const ConstByteView& d = dense.in;
  const ptrdiff_t stride = d.channels + in_extra;
  const ptrdiff_t row = d.width * stride + dense.shape.extra_row_bytes;
  pr.input.assign(static_cast<size_t>(d.height * row) + kInt8TensorSlack, 0x5A);
  for (int y = 0; y < d.height; ++y) {
    for (int x = 0; x < d.width; ++x) {
      std::memcpy(pr.input.data() + y * row + x * stride, d.pixel(y, x),
                  static_cast<size_t>(d.channels));
    }
  }
  pr.in = ConstByteView{pr.input.data(), d.height, d.width, d.channels, row, stride};
  pr.out_pixel_extra = out_extra;
  return pr;
}

// Convolutions that read their input from a slice of wider pixels and write their uint8 output
// into one (a Concat's tensor): every kernel gives the reference's bytes, the bytes between the
// slices untouched, and the reference gives on slices what it gives on dense tensors. Channel
// counts that are multiples of 4 (what a session puts in slices), plain, strided and fused
// upsampling convolutions, partial blocks.
void Int8Kernels::CheckSlices() {
  // Wide enough, with 64 input channels, for the AMX tiles too (the second and the last).
  std::vector<Int8Shape> shapes = {Conv(7, 19, 16, 24, 1),     Conv(5, 37, 64, 70, 1),
                                   Conv(9, 11, 12, 8, 2),      UpConv(4, 9, 32, 16, 1, 1),
                                   UpConv(5, 6, 8, 100, 0, 0), UpConv(3, 20, 64, 64, 1, 0),
                                   Conv(5, 23, 64, 4, 1),    // few outputs
                                   Conv(5, 37, 4, 4, 1),     // narrow
                                   Conv(4, 21, 16, 56, 1)};  // 4 vectors, the last partial
  shapes[3].phases = shapes[5].phases = true;
  size_t values = 0;
  uint32_t seed = 4100;
  for (const Int8Shape& shape : shapes) {
    for (auto [in_extra, out_extra] : {std::pair{4, 12}, {64, 4}}) {
      const Int8Problem dense = MakeProblem(shape, Int8Quant{}, seed++);
      const Int8Problem sliced = AsSlices(dense, in_extra, out_extra);
      SCOPED_TRACE(Describe(shape) + " extra " + std::to_string(in_extra) + "/" +
                   std::to_string(out_extra));
      const Output want = RunReference(dense);
      const Output got = RunReference(sliced);
      for (int y = 0; y < dense.out_h; ++y) {
        for (int x = 0; x < dense.out_w; ++x) {
          const uint8_t* a = want.u8.data() + y * want.RowElements() + x * want.stride;
          const uint8_t* b = got.u8.data() + y * got.RowElements() + x * got.stride;
          ASSERT_EQ(std::memcmp(a, b, static_cast<size_t>(shape.cout)), 0) << y << "," << x;
          for (int e = 0; e < out_extra; ++e) ASSERT_EQ(b[shape.cout + e], 0xA5);
        }
      }
      values += ExpectBitExact(sliced);
    }
  }
  std::printf("[          ] %zu output values bit for bit in slices, %zu kernel table(s)\n", values,
              tables_.size());
}

TEST_F(Int8Vnni, ReadsAndWritesSlicesOfWiderPixels) { CheckSlices(); }
TEST_F(Int8NeonDot, ReadsAndWritesSlicesOfWiderPixels) { CheckSlices(); }
TEST_F(Int8AmxEmulated, ReadsAndWritesSlicesOfWiderPixels) { CheckSlices(); }
TEST_F(Int8Amx, ReadsAndWritesSlicesOfWiderPixels) { CheckSlices(); }

TEST(AmxTiles, ConfigurationFitsPalette1ForEveryChannelCount) {
  for (int groups = 1; groups <= 256; ++groups) {
    const simd::AmxTileConfig c = simd::AmxConfigFor(groups);
    EXPECT_EQ(c.palette, 1);
    for (int t = 0; t < 8; ++t) {
      EXPECT_LE(c.rows[t], 16) << groups;
      EXPECT_LE(c.colsb[t], 64) << groups;
    }
    EXPECT_EQ(simd::AmxPairs(groups), groups >= 16 && groups % 16 == 0) << groups;
    if (simd::AmxPairs(groups)) {
      // The 2 x 2 blocking: A tiles 4, 5 and B tiles 6, 7 of 16 groups each.
      for (int t = 4; t < 8; ++t) {
        EXPECT_EQ(c.rows[t], 16) << groups;
        EXPECT_EQ(c.colsb[t], 64) << groups;
      }
      continue;
    }
    // A's bytes per row are 4x B's rows (tdpbusd's K), for the full chunks and for the tail.
    EXPECT_EQ(c.colsb[4], 4 * c.rows[5]) << groups;
    EXPECT_EQ(c.colsb[6], 4 * c.rows[7]) << groups;
    const int full = c.rows[5], tail = c.rows[7];
    EXPECT_EQ(groups / full * full + tail, groups) << "every group in one chunk";
    EXPECT_EQ(tail == 0, groups <= 16) << groups;
  }
}

TEST_F(Int8AmxEmulated, MatchesReferenceBitForBitOnEdgeShapes) { CheckEdgeShapes(); }
TEST_F(Int8AmxEmulated, MatchesReferenceBitForBitWhereTheTilesDoTheWork) { CheckAmxBlocking(); }
TEST_F(Int8AmxEmulated, The1x4BlockingMatchesReferenceBitForBitWhereThe2x2WouldRun) {
  amx_1x4_ = true;  // KernelTuning::amx_pairs false
  CheckAmxBlocking();
}
TEST_F(Int8AmxEmulated, RowAndBlockRangesCalledSeparatelyComposeTheWholeOutput) {
  CheckRowAndBlockRanges();
}
TEST_F(Int8Amx, MatchesReferenceBitForBitOnEveryModelLayer) { CheckEveryModelLayer(); }
TEST_F(Int8Amx, MatchesReferenceBitForBitWhereTheTilesDoTheWork) { CheckAmxBlocking(); }
TEST_F(Int8Amx, The1x4BlockingMatchesReferenceBitForBitWhereThe2x2WouldRun) {
  amx_1x4_ = true;
  CheckAmxBlocking();
}
TEST_F(Int8Amx, KernelNamesCarryIsaAndTileAndTheSessionGetsThem) {
  EXPECT_EQ(std::string(tables_.front()->conv_name), "conv2d_u8s8__avx512amx_16x64");
  EXPECT_EQ(std::string(tables_.front()->upconv_name), "upconv2d_u8s8__avx512amx_16x64");
  EXPECT_TRUE(IsaSupported(Isa::kAvx512Amx));
  EXPECT_EQ(BestIsa(), Isa::kAvx512Amx);
  EXPECT_EQ(Int8KernelsFor(Isa::kAvx512Amx), tables_.front());
  // avx512 keeps the VNNI kernels, so that the two can be compared on one CPU.
  ASSERT_NE(Int8KernelsFor(Isa::kAvx512), nullptr);
  EXPECT_EQ(std::string(Int8KernelsFor(Isa::kAvx512)->conv_name), "conv2d_u8s8__avx512vnni_6x64");
}

TEST(Int8Dispatch, OnlyAvx512WithVnniAndNeonWithDotProductHaveInt8Kernels) {
  EXPECT_EQ(Int8KernelsFor(Isa::kRef), nullptr);
  EXPECT_EQ(Int8KernelsFor(Isa::kAvx2), nullptr);
  if (!IsaSupported(Isa::kNeon)) {
    EXPECT_EQ(Int8KernelsFor(Isa::kNeon), nullptr);
  }
#if SFRT_TEST_NEON_DOT
  EXPECT_EQ(Int8KernelsFor(Isa::kNeon), neon::Int8Kernels());
#endif
  if (!IsaSupported(Isa::kAvx512)) {
    EXPECT_EQ(Int8KernelsFor(Isa::kAvx512), nullptr);
    EXPECT_EQ(Int8KernelsFor(Isa::kAvx512Amx), nullptr);
  }
}

}  // namespace
}  // namespace sfrt
