// Proves Session::Run performs no heap allocation: this program links the counting allocator
// (tests/common/counting_allocator.h). Not built with sanitizers, which own the allocator
// themselves.
#include <gtest/gtest.h>

#include <string>

#include "common/bf16_spec.h"
#include "common/counting_allocator.h"
#include "common/deconv_spec.h"
#include "common/float_ops_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "common/unet_spec.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/isa.h"
#include "sfrt/session.h"

namespace sfrt {
namespace {

TEST(ZeroAllocation, CountingHooksSeeAnAllocation) {
  // The hooks must be live, or the test below proves nothing.
  EXPECT_TRUE(sfrt::testing::CountingHooksAreLive());
}

// Every ISA this CPU runs (packed weights and the fused upsample-conv included), with one
// thread and with a pool of two (which must not create threads or allocate per Run).
// Every precision: float32; int8 (uint8 tensors, the input's quantisation, int8 kernels); bf16
// (bf16 tensors, the input's conversion, bf16 kernels).
TEST(ZeroAllocation, RunAllocatesNothingAtAnySizeUpToTheMaximum) {
  for (Precision precision : {Precision::kFloat32, Precision::kInt8, Precision::kBFloat16}) {
    SCOPED_TRACE(PrecisionName(precision));
    auto model = testing::LoadOrDie(
        precision == Precision::kInt8       ? testing::Int8Spec(exporter::SceneEdNetSpec(16))
        : precision == Precision::kBFloat16 ? testing::Bf16Spec(exporter::SceneEdNetSpec(16))
                                            : exporter::SceneEdNetSpec(16));
    for (Isa isa : SupportedIsas()) {
      for (int threads : {1, 2}) {
        SCOPED_TRACE(std::string(IsaName(isa)) + ", " + std::to_string(threads) + " threads");
        SessionOptions options;
        options.max_height = 96;
        options.max_width = 128;
        options.isa = isa;
        options.threads = threads;
        auto session = Session::Create(model, options);
        ASSERT_TRUE(session.ok()) << session.message();
        std::vector<float> input(96 * 128 * 12, 100.0f), output(96 * 128 * 3);
        std::vector<int64_t> step_end_ns((*session)->steps().size() + 1);
        for (auto [h, w] : {std::pair{96, 128}, {67, 121}, {1, 1}, {96, 128}}) {
          for (bool timed : {false, true}) {
            const long before = sfrt::testing::AllocationCount();
            const Status s = timed ? (*session)->Run(input, h, w, output, step_end_ns)
                                   : (*session)->Run(input, h, w, output);
            const long allocated = sfrt::testing::AllocationCount() - before;
            ASSERT_TRUE(s.ok()) << s.message();
            EXPECT_EQ(allocated, 0) << "Run(" << h << "x" << w << (timed ? ", timed" : "")
                                    << ") allocated " << allocated << " times";
          }
        }
      }
    }
  }
}

// The uint8 input path (RunQuantized), timed and not, on every ISA, with and without a pool.
TEST(ZeroAllocation, RunQuantizedAllocatesNothingAtAnySizeUpToTheMaximum) {
  auto model = testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16)));
  for (Isa isa : SupportedIsas()) {
    for (int threads : {1, 2}) {
      SCOPED_TRACE(std::string(IsaName(isa)) + ", " + std::to_string(threads) + " threads");
      SessionOptions options;
      options.max_height = 96;
      options.max_width = 128;
      options.isa = isa;
      options.threads = threads;
      auto session = Session::Create(model, options);
      ASSERT_TRUE(session.ok()) << session.message();
      ASSERT_TRUE((*session)->InputQuantization().has_value());
      std::vector<uint8_t> input((*session)->QuantizedInputBytes(96, 128), 100);
      std::vector<float> output(96 * 128 * 3);
      std::vector<int64_t> step_end_ns((*session)->steps().size() + 1);
      for (auto [h, w] : {std::pair{96, 128}, {67, 121}, {1, 1}, {96, 128}}) {
        for (bool timed : {false, true}) {
          const long before = sfrt::testing::AllocationCount();
          const Status s = timed ? (*session)->RunQuantized(input, h, w, output, step_end_ns)
                                 : (*session)->RunQuantized(input, h, w, output);
          const long allocated = sfrt::testing::AllocationCount() - before;
          ASSERT_TRUE(s.ok()) << s.message();
          EXPECT_EQ(allocated, 0) << "RunQuantized(" << h << "x" << w << (timed ? ", timed" : "")
                                  << ") allocated " << allocated << " times";
        }
      }
    }
  }
}

// Graphs (SceneEDNet-U with a residual Add, in float32, int8 and bf16; a decoder of transposed
// convolutions) and a chain of every float32-only layer kind (pooling, dilated and grouped
// convolutions, ChannelAffine, Resize): skip tensors, Concat, Add, ConvTranspose2D, Pool2D,
// Resize and ChannelAffine steps, the conversions before int8 and bf16 convolutions, grouped and
// dilated convolutions on the reference kernel, and the views Run() keeps of every layer's
// output, on every ISA and with a pool.
TEST(ZeroAllocation, RunOfAGraphAllocatesNothingAtAnySizeUpToTheMaximum) {
  const exporter::ModelSpec unet = testing::SceneEdNetUSpec(16, 1, true);
  for (auto model : {testing::LoadOrDie(unet), testing::LoadOrDie(testing::Int8Spec(unet)),
                     testing::LoadOrDie(testing::Bf16Spec(unet)),
                     testing::LoadOrDie(testing::TwoLevelDecoderSpec()),
                     testing::LoadOrDie(testing::FloatOpsChainSpec())})
    for (Isa isa : SupportedIsas()) {
      for (int threads : {1, 2}) {
        SCOPED_TRACE(model->metadata().name + ", " + std::string(IsaName(isa)) + ", " +
                     std::to_string(threads) + " threads");
        SessionOptions options;
        options.max_height = 96;
        options.max_width = 128;
        options.isa = isa;
        options.threads = threads;
        auto session = Session::Create(model, options);
        ASSERT_TRUE(session.ok()) << session.message();
        std::vector<float> input(96 * 128 * 12, 100.0f), output(96 * 128 * 3);
        for (auto [h, w] : {std::pair{96, 128}, {67, 121}, {1, 1}, {96, 128}}) {
          const long before = sfrt::testing::AllocationCount();
          const Status s = (*session)->Run(input, h, w, output);
          const long allocated = sfrt::testing::AllocationCount() - before;
          ASSERT_TRUE(s.ok()) << s.message();
          EXPECT_EQ(allocated, 0) << "Run(" << h << "x" << w << ") allocated " << allocated
                                  << " times";
        }
      }
    }
}

TEST(ZeroAllocation, OutputShapeAllocatesNothing) {
  for (bool graph : {false, true}) {
    SCOPED_TRACE(graph ? "graph" : "chain");
    auto model =
        testing::LoadOrDie(graph ? testing::SceneEdNetUSpec(16) : exporter::SceneEdNetSpec(16));
    SessionOptions options;
    options.max_height = 96;
    options.max_width = 128;
    auto session = Session::Create(model, options);
    ASSERT_TRUE(session.ok()) << session.message();
    for (auto [h, w] : {std::pair{96, 128}, {67, 121}, {1, 1}}) {
      const long before = sfrt::testing::AllocationCount();
      Result<TensorShape> shape = (*session)->OutputShape(h, w);
      const long allocated = sfrt::testing::AllocationCount() - before;
      ASSERT_TRUE(shape.ok()) << shape.message();
      EXPECT_EQ(shape->height, h);
      EXPECT_EQ(shape->width, w);
      EXPECT_EQ(shape->channels, 3);
      EXPECT_EQ(allocated, 0) << "OutputShape(" << h << "x" << w << ") allocated " << allocated
                              << " times";
    }
  }
}

}  // namespace
}  // namespace sfrt
