// sfrt/pipeline/stats.h: percentiles against hand-computed values, summaries, the step
// recorder and tables, and step labels on the bundled demo model.
#include "sfrt/pipeline/stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "common/bf16_spec.h"
#include "common/int8_spec.h"
#include "common/model_builders.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/model.h"
#include "sfrt/session.h"

namespace sfrt::profiling {
namespace {

TEST(Percentile, InterpolatesLinearlyBetweenRanks) {
  // 1..10: position q * 9.
  const std::vector<double> v = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  EXPECT_DOUBLE_EQ(PercentileOfSorted(v, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(PercentileOfSorted(v, 0.5), 5.5);      // between 5 and 6
  EXPECT_DOUBLE_EQ(PercentileOfSorted(v, 0.9), 9.1);      // position 8.1
  EXPECT_DOUBLE_EQ(PercentileOfSorted(v, 0.99), 9.91);    // position 8.91
  EXPECT_DOUBLE_EQ(PercentileOfSorted(v, 0.999), 9.991);  // position 8.991
  EXPECT_DOUBLE_EQ(PercentileOfSorted(v, 1.0), 10.0);
  EXPECT_DOUBLE_EQ(PercentileOfSorted(v, 1.5), 10.0);  // clamped
  EXPECT_DOUBLE_EQ(PercentileOfSorted(v, -1), 1.0);
}

TEST(Percentile, SortsUnorderedValues) {
  EXPECT_DOUBLE_EQ(Percentile({3, 1, 2}, 0.5), 2.0);
  EXPECT_DOUBLE_EQ(Percentile({3, 1, 2}, 0.25), 1.5);
  EXPECT_DOUBLE_EQ(Percentile({20, 10}, 0.9), 19.0);
  EXPECT_DOUBLE_EQ(Percentile({7}, 0.99), 7.0);
}

TEST(Percentile, EmptyIsNaN) {
  EXPECT_TRUE(std::isnan(Percentile({}, 0.5)));
  const Summary s = Summarize({});
  EXPECT_EQ(s.count, 0u);
  EXPECT_EQ(s.max, 0.0);
}

TEST(Summarize, MatchesHandComputedValues) {
  const std::vector<double> v = {10, 9, 8, 7, 6, 5, 4, 3, 2, 1};
  const Summary s = Summarize(v);
  EXPECT_EQ(s.count, 10u);
  EXPECT_DOUBLE_EQ(s.min, 1);
  EXPECT_DOUBLE_EQ(s.max, 10);
  EXPECT_DOUBLE_EQ(s.mean, 5.5);
  EXPECT_NEAR(s.stddev, std::sqrt(8.25), 1e-12);  // population: (n^2 - 1) / 12
  EXPECT_DOUBLE_EQ(s.p50, 5.5);
  EXPECT_DOUBLE_EQ(s.p90, 9.1);
  EXPECT_DOUBLE_EQ(s.p99, 9.91);
  EXPECT_DOUBLE_EQ(s.p999, 9.991);
  EXPECT_DOUBLE_EQ(s.At(99.9), 9.991);
  EXPECT_DOUBLE_EQ(s.At(100), 10);
  EXPECT_DOUBLE_EQ(s.At(50), 5.5);
  EXPECT_TRUE(std::isnan(s.At(75)));
}

TEST(RunningStats, PopulationStddevOfTextbookSeries) {
  RunningStats r;
  for (double v : {2, 4, 4, 4, 5, 5, 7, 9}) r.Add(v);
  EXPECT_EQ(r.count(), 8u);
  EXPECT_DOUBLE_EQ(r.mean(), 5.0);
  EXPECT_NEAR(r.stddev(), 2.0, 1e-12);
  EXPECT_DOUBLE_EQ(r.min(), 2.0);
  EXPECT_DOUBLE_EQ(r.max(), 9.0);
  RunningStats one;
  one.Add(3);
  EXPECT_EQ(one.stddev(), 0.0);
}

TEST(ParsePercentile, AcceptsLabelsAndNumbers) {
  double p = 0;
  ASSERT_TRUE(ParsePercentile("p99", &p));
  EXPECT_EQ(p, 99);
  ASSERT_TRUE(ParsePercentile("p99.9", &p));
  EXPECT_EQ(p, 99.9);
  ASSERT_TRUE(ParsePercentile("P50", &p));
  EXPECT_EQ(p, 50);
  ASSERT_TRUE(ParsePercentile("90", &p));
  EXPECT_EQ(p, 90);
  ASSERT_TRUE(ParsePercentile("max", &p));
  EXPECT_EQ(p, 100);
  ASSERT_TRUE(ParsePercentile("median", &p));
  EXPECT_EQ(p, 50);
  for (const char* bad : {"", "p", "p0", "p101", "abc", "p99x", "-5", "nan"}) {
    EXPECT_FALSE(ParsePercentile(bad, &p)) << bad;
  }
  EXPECT_EQ(PercentileLabel(99.9), "p99.9");
  EXPECT_EQ(PercentileLabel(50), "p50");
  EXPECT_EQ(PercentileLabel(100), "max");
}

TEST(StepRecorder, TurnsTimestampsIntoDurationsAndGrows) {
  StepRecorder rec(3, 1);
  const std::vector<int64_t> stamps = {1000000, 3000000, 3500000, 7000000};
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(rec.Add(stamps));
  EXPECT_FALSE(rec.Add(std::vector<int64_t>{1, 2, 3}));
  ASSERT_EQ(rec.runs(), 5u);
  const auto ms = rec.durations_ms();
  ASSERT_EQ(ms.size(), 15u);
  for (size_t r = 0; r < 5; ++r) {
    EXPECT_DOUBLE_EQ(ms[r * 3 + 0], 2.0);
    EXPECT_DOUBLE_EQ(ms[r * 3 + 1], 0.5);
    EXPECT_DOUBLE_EQ(ms[r * 3 + 2], 3.5);
    EXPECT_DOUBLE_EQ(rec.total_ms(r), 6.0);
  }
}

std::vector<StepLabel> ThreeLabels() {
  std::vector<StepLabel> labels(3);
  labels[0] = {0, 0, "conv1", "conv", "k_a", "fp32"};
  labels[1] = {1, 1, "crop1", "crop", "view", "fp32"};
  labels[2] = {2, 3, "up+conv2", "conv", "k_b", "int8"};
  return labels;
}

TEST(StepTable, MediansSharesTopAndOps) {
  // Two runs of three steps: {2, 0.5, 3.5} and {4, 0.5, 1.5} ms.
  const std::vector<double> ms = {2, 0.5, 3.5, 4, 0.5, 1.5};
  const std::vector<StepRow> rows = StepTable(ThreeLabels(), ms);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_DOUBLE_EQ(rows[0].ms.p50, 3.0);
  EXPECT_DOUBLE_EQ(rows[1].ms.p50, 0.5);
  EXPECT_DOUBLE_EQ(rows[2].ms.p50, 2.5);
  EXPECT_DOUBLE_EQ(rows[0].ms.max, 4.0);
  // Shares of the mean total 6 ms.
  EXPECT_DOUBLE_EQ(rows[0].share, 0.5);
  EXPECT_DOUBLE_EQ(rows[1].share, 0.5 / 6);
  EXPECT_DOUBLE_EQ(rows[2].share, 2.5 / 6);
  EXPECT_EQ(rows[2].label.name, "up+conv2");

  const std::vector<StepRow> top = TopSteps(rows, 2);
  ASSERT_EQ(top.size(), 2u);
  EXPECT_EQ(top[0].step, 0u);
  EXPECT_EQ(top[1].step, 2u);
  EXPECT_EQ(TopSteps(rows, 10).size(), 3u);

  const std::vector<OpRow> ops = ByOp(rows);
  ASSERT_EQ(ops.size(), 2u);
  EXPECT_EQ(ops[0].op, "conv");
  EXPECT_EQ(ops[0].steps, 2u);
  EXPECT_DOUBLE_EQ(ops[0].median_ms, 5.5);
  EXPECT_DOUBLE_EQ(ops[0].mean_ms, 5.5);
  EXPECT_DOUBLE_EQ(ops[0].share, 5.5 / 6);
  EXPECT_EQ(ops[1].op, "crop");
  EXPECT_DOUBLE_EQ(ops[1].share, 0.5 / 6);

  const std::string table = FormatStepTable(rows);
  EXPECT_NE(table.find("median ms"), std::string::npos);
  EXPECT_NE(table.find("up+conv2"), std::string::npos);
  EXPECT_NE(table.find("50.0%"), std::string::npos);
  EXPECT_NE(FormatOpTable(ops).find("91.7%"), std::string::npos);
}

// Two configurations: the first's steps in its order, then a step only the second has; each
// median, and the second's against the first's ("-" where a step is missing).
TEST(StepComparison, PutsTheMediansSideBySideAgainstTheFirst) {
  const std::vector<StepRow> first = StepTable(ThreeLabels(), std::vector<double>{2, 0.5, 3.5});
  std::vector<StepLabel> labels = ThreeLabels();
  labels[1] = {1, 1, "copy1", "concat", "ref::ConcatRowsU8", "int8"};
  const std::vector<StepRow> second = StepTable(labels, std::vector<double>{1, 0.25, 7});
  const std::vector<std::vector<StepRow>> both = {first, second};
  const std::string table = FormatStepComparison(both);
  const std::string expected =
      "layers        [1] ms      [2] ms   [2]/[1]\n"
      "conv1          2.000       1.000     0.500\n"
      "crop1          0.500           -         -\n"
      "up+conv2       3.500       7.000     2.000\n"
      "copy1              -       0.250         -\n";
  EXPECT_EQ(table, expected);
}

TEST(StepTable, EmptyWhenSizesDoNotFit) {
  EXPECT_TRUE(StepTable(ThreeLabels(), std::vector<double>{1, 2}).empty());
  EXPECT_TRUE(StepTable({}, std::vector<double>{1, 2}).empty());
}

// The bundled 1/16-width SceneEDNet: every step is labelled, fused steps say so, and recorded
// step durations add up to each run's total.
TEST(LabelSteps, DemoModelStepsAreNamedAndAddUp) {
  const std::string path = std::string(SFRT_SOURCE_DIR) + "/tools/demo/sceneednet-w16-demo.sfrt";
  auto model = Model::LoadFile(path);
  ASSERT_TRUE(model.ok()) << model.message();
  SessionOptions options;
  options.max_height = 35;
  options.max_width = 61;
  auto session = Session::Create(*model, options);
  ASSERT_TRUE(session.ok()) << session.message();
  const std::vector<StepLabel> labels = LabelSteps(**session);
  const auto steps = (*session)->steps();
  ASSERT_EQ(labels.size(), steps.size());
  bool fused = false;
  for (size_t i = 0; i < labels.size(); ++i) {
    EXPECT_FALSE(labels[i].name.empty());
    EXPECT_FALSE(labels[i].op.empty());
    EXPECT_EQ(labels[i].kernel, steps[i].kernel);
    if (steps[i].last_layer > steps[i].first_layer) {
      fused = true;
      EXPECT_NE(labels[i].op.find("(fused)"), std::string::npos) << labels[i].op;
      EXPECT_NE(labels[i].name.find('+'), std::string::npos) << labels[i].name;
    }
  }
  if ((*session)->isa() != Isa::kRef) {
    EXPECT_TRUE(fused);
  }

  std::vector<float> input(35 * 61 * 12, 1.0f);
  auto out = (*session)->OutputShape(35, 61);
  ASSERT_TRUE(out.ok());
  std::vector<float> output(out->elements());
  std::vector<int64_t> stamps(steps.size() + 1);
  StepRecorder rec(steps.size(), 3);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE((*session)->Run(input, 35, 61, output, stamps).ok());
    ASSERT_TRUE(rec.Add(stamps));
    EXPECT_NEAR(rec.total_ms(static_cast<size_t>(i)), (stamps.back() - stamps.front()) * 1e-6,
                1e-9);
  }
  const std::vector<StepRow> rows = StepTable(labels, rec.durations_ms());
  double share = 0;
  for (const StepRow& r : rows) {
    EXPECT_GE(r.ms.min, 0.0);
    share += r.share;
  }
  EXPECT_NEAR(share, 1.0, 1e-9);
}

// The step converting the input says what it converts to, and each reduced-precision
// convolution's op starts with its precision (1/16-width SceneEDNet in int8 and in bf16).
TEST(LabelSteps, ConversionsAndConvolutionsNameTheirPrecision) {
  struct Case {
    std::shared_ptr<const Model> model;
    std::string conversion;
    std::string prefix;
  };
  const std::vector<Case> cases = {
      {testing::LoadOrDie(testing::Int8Spec(exporter::SceneEdNetSpec(16))), "quantize uint8",
       "int8 "},
      {testing::LoadOrDie(testing::Bf16Spec(exporter::SceneEdNetSpec(16))), "round to bf16",
       "bf16 "},
  };
  for (const Case& c : cases) {
    ASSERT_NE(c.model, nullptr);
    SessionOptions options;
    options.max_height = 35;
    options.max_width = 61;
    auto session = Session::Create(c.model, options);
    ASSERT_TRUE(session.ok()) << session.message();
    const std::vector<StepLabel> labels = LabelSteps(**session);
    ASSERT_GE(labels.size(), 2u);
    EXPECT_EQ(labels.front().op, c.conversion);
    EXPECT_EQ(labels.front().name, "quantize>conv0");
    for (size_t i = 1; i < labels.size(); ++i) {
      EXPECT_TRUE(labels[i].op.starts_with(c.prefix)) << labels[i].op;
    }
  }
}

}  // namespace
}  // namespace sfrt::profiling
