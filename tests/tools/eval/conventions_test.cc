// Tests of eval/conventions.h: the FlyingThings3D papers' masks and share rules on hand-worked
// frames (ground truth as prediction; a known perturbation on known pixels, some beyond the depth
// and some beyond the 2D flow bounds), their exact merging and partial state, and `sfrt eval`'s
// report of them on written trees, with and without the files their masks need.
#include "eval/conventions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "eval/evaluate.h"
#include "sfrt/pipeline/io/pfm.h"
#include "synth/dataset.h"

namespace sfrt::eval {
namespace {

namespace fs = std::filesystem;

constexpr double kInf = std::numeric_limits<double>::infinity();

int Row(const char* key) {
  for (int c = 0; c < kConventionCount; ++c) {
    if (std::string(kConventions[c].key) == key) return c;
  }
  ADD_FAILURE() << "no convention " << key;
  return 0;
}

// One frame: per pixel the truth (x only), the prediction's error along x, and the mask inputs.
struct Pixel {
  float truth;
  float error;
  double depth, next_depth, flow2d;
};

struct Frame {
  std::vector<float> truth, pred;
  std::array<std::vector<double>, kMaskInputs> values;

  explicit Frame(const std::vector<Pixel>& pixels) {
    for (const Pixel& p : pixels) {
      truth.insert(truth.end(), {p.truth, 0.0f, 0.0f});
      pred.insert(pred.end(), {p.truth + p.error, 0.0f, 0.0f});
      values[0].push_back(p.depth);
      values[1].push_back(p.next_depth);
      values[2].push_back(p.flow2d);
    }
  }
  MaskInputs Inputs() const {
    MaskInputs in;
    for (size_t i = 0; i < kMaskInputs; ++i) in.values[i] = values[i].data();
    return in;
  }
  size_t pixels() const { return values[0].size(); }
};

// Kept by every mask: depth 10 at t and t+1, 5 px of 2D flow.
Pixel Near(float truth, float error) { return {truth, error, 10, 10, 5}; }

// The hand-worked frame. |gt| = 1 except p2 (|gt| = 10: its 0.4 error is 4% relative).
//   p   error  depth t / t+1  |2D flow|  kept by
//   0   0      10 / 10        5          all
//   1   0.04   10 / 10        5          all
//   2   0.4    10 / 10        5          all
//   3   0.5    10 / 10        5          all
//   4   0.02   40 / 40        5          raft3d (beyond depth 35)
//   5   0.5    40 / 40        5          raft3d
//   6   0.04   10 / 40        5          flownet3d, camliflow, raft3d (beyond 35 at t+1)
//   7   0.5    10 / 10        300        flownet3d, hplflownet, camliflow (beyond 250 px)
//   8   0.5    10 / 10        300        flownet3d, hplflownet, camliflow
//   9   0      no depth       5          none (disparity 0)
Frame HandWorked() {
  return Frame({Near(1, 0),
                Near(1, 0.04f),
                Near(10, 0.4f),
                Near(1, 0.5f),
                {1, 0.02f, 40, 40, 5},
                {1, 0.5f, 40, 40, 5},
                {1, 0.04f, 10, 40, 5},
                {1, 0.5f, 10, 10, 300},
                {1, 0.5f, 10, 10, 300},
                {1, 0, kInf, kInf, 5}});
}

TEST(Conventions, GroundTruthAsPredictionScoresPerfectlyUnderEveryConvention) {
  Frame f = HandWorked();
  f.truth.insert(f.truth.end(), {0, 0, 0});  // a pixel at rest: EPE 0, relative 0
  f.pred.insert(f.pred.end(), {0, 0, 0});
  for (auto& v : f.values) v.push_back(1);
  ConventionSet set;
  set.Add(f.truth.data(), f.truth.data(), f.Inputs(), f.pixels());
  for (int c = 0; c < kConventionCount; ++c) {
    const ConventionMetrics m = set[c].Metrics();
    const Convention& row = kConventions[c];
    SCOPED_TRACE(row.key);
    EXPECT_TRUE(m.available);
    EXPECT_GT(m.valid_pixels, 0u);
    EXPECT_EQ(m.frames, 1u);
    EXPECT_EQ(m.epe3d, 0.0);
    for (size_t s = 0; s < kConventionShares; ++s) {
      if (row.shares[s].column == nullptr) {
        EXPECT_TRUE(std::isnan(m.shares[s])) << "not reported: null";
      } else {
        EXPECT_EQ(m.shares[s], row.shares[s].compare == Compare::kAbove ? 0.0 : 1.0);
      }
    }
  }
}

TEST(Conventions, KnownPerturbationOnKnownPixelsGivesTheKnownCounts) {
  const Frame f = HandWorked();
  ConventionSet set;
  set.Add(f.pred.data(), f.truth.data(), f.Inputs(), f.pixels());
  struct Expected {
    const char* key;
    uint64_t pixels;
    double epe_sum;
    double acc05, acc10, outliers;  // counts; NaN: not reported
  };
  const double none = std::numeric_limits<double>::quiet_NaN();
  // flownet3d: EPE <= 0.05 or rel <= 5% (p2 by its 4%); hplflownet: p2 passes ACC by 4% and is
  // an outlier by EPE 0.4 > 0.3; camliflow and raft3d: absolute only, so p2 fails both ACC.
  const Expected expected[] = {
      {"flownet3d", 7, 0 + 0.04 + 0.4 + 0.5 + 0.04 + 0.5 + 0.5, 4, 4, none},
      {"hplflownet", 6, 0 + 0.04 + 0.4 + 0.5 + 0.5 + 0.5, 3, 3, 4},
      {"camliflow", 7, 0 + 0.04 + 0.4 + 0.5 + 0.04 + 0.5 + 0.5, 3, 3, none},
      {"raft3d", 7, 0 + 0.04 + 0.4 + 0.5 + 0.02 + 0.5 + 0.04, 4, 4, none},
  };
  for (const Expected& e : expected) {
    SCOPED_TRACE(e.key);
    const ConventionMetrics m = set[Row(e.key)].Metrics();
    const double n = static_cast<double>(e.pixels);
    EXPECT_EQ(m.valid_pixels, e.pixels);
    EXPECT_NEAR(m.epe3d, e.epe_sum / n, 1e-6);
    EXPECT_DOUBLE_EQ(m.shares[0], e.acc05 / n);
    EXPECT_DOUBLE_EQ(m.shares[1], e.acc10 / n);
    if (std::isnan(e.outliers)) {
      EXPECT_TRUE(std::isnan(m.shares[2]));
    } else {
      EXPECT_DOUBLE_EQ(m.shares[2], e.outliers / n);
    }
  }
}

// flownet3d and hplflownet average each frame's means (as their batch-of-one evaluations do);
// camliflow and raft3d pool every kept pixel. A frame the mask keeps nothing of does not count.
TEST(Conventions, PerFrameAndPerPixelAveragingAsEachPaperDoes) {
  const Frame first = HandWorked();
  const Frame second({Near(1, 0.5f)});
  const Frame third({{1, 0, 40, 40, 5}});  // only raft3d keeps it
  ConventionSet set;
  for (const Frame* f : {&first, &second, &third}) {
    set.Add(f->pred.data(), f->truth.data(), f->Inputs(), f->pixels());
  }
  const ConventionMetrics fn3d = set[Row("flownet3d")].Metrics();
  EXPECT_EQ(fn3d.frames, 2u);
  EXPECT_EQ(fn3d.valid_pixels, 8u);
  EXPECT_NEAR(fn3d.epe3d, (1.98 / 7 + 0.5) / 2, 1e-6);
  EXPECT_DOUBLE_EQ(fn3d.shares[0], (4.0 / 7 + 0) / 2);
  const ConventionMetrics caml = set[Row("camliflow")].Metrics();
  EXPECT_NEAR(caml.epe3d, (1.98 + 0.5) / 8, 1e-6);
  EXPECT_DOUBLE_EQ(caml.shares[0], 3.0 / 8);
  const ConventionMetrics raft = set[Row("raft3d")].Metrics();
  EXPECT_EQ(raft.frames, 3u);
  EXPECT_EQ(raft.valid_pixels, 9u);
  EXPECT_NEAR(raft.epe3d, (1.5 + 0.5 + 0) / 9, 1e-6);
  EXPECT_DOUBLE_EQ(raft.shares[1], 5.0 / 9);
}

TEST(Conventions, ShareRulesAsTheAuthorsCodeWritesThem) {
  const Convention& fn3d = kConventions[Row("flownet3d")];
  const Convention& hpl = kConventions[Row("hplflownet")];
  const Convention& raft = kConventions[Row("raft3d")];
  EXPECT_TRUE(fn3d.shares[0].Counts(0.05, 1.0));  // FlowNet3D: error <= 0.05
  EXPECT_FALSE(hpl.shares[0].Counts(0.05, 1.0));  // HPLFlowNet: l2_norm < 0.05
  EXPECT_TRUE(hpl.shares[0].Counts(0.9, 0.04));   // either condition
  EXPECT_FALSE(raft.shares[0].Counts(0.9, 0.0));  // RAFT-3D: EPE3D < 5 cm only
  EXPECT_EQ(hpl.shares[2].Definition(hpl.relative_epsilon),
            "Outliers3D: EPE > 0.3 or EPE/(|gt|+0.0001) > 10%");
  EXPECT_EQ(raft.shares[1].Definition(raft.relative_epsilon), "ACC(10cm): EPE < 0.1");
  EXPECT_EQ(raft.shares[2].Definition(0), "not reported");
  EXPECT_EQ(raft.MaskWords(), "depth at t < 250 and |2D optical flow| < 250 px");
  EXPECT_EQ(hpl.MaskWords(), "depth at t < 35 and depth at t+1 < 35");
}

TEST(Conventions, SplitMergedAndThroughPartialStateEqualsTheWhole) {
  const Frame a = HandWorked();
  const Frame b({Near(1, 0.5f), Near(2, 0.01f)});
  ConventionSet whole, first, second;
  whole.Add(a.pred.data(), a.truth.data(), a.Inputs(), a.pixels());
  whole.Add(b.pred.data(), b.truth.data(), b.Inputs(), b.pixels());
  first.Add(a.pred.data(), a.truth.data(), a.Inputs(), a.pixels());
  second.Add(b.pred.data(), b.truth.data(), b.Inputs(), b.pixels());
  Result<ConventionSet> restored =
      ConventionSet::FromState(nlohmann::json::parse(second.State().dump()));
  ASSERT_TRUE(restored.ok()) << restored.message();
  first.Merge(*restored);
  EXPECT_EQ(first.State(), whole.State());
  ConventionAccumulator unavailable(Row("raft3d"));
  unavailable.MarkUnavailable("no optical_flow/0000/into_future/left/x.pfm");
  Result<ConventionAccumulator> back =
      ConventionAccumulator::FromState(unavailable.State(), Row("raft3d"));
  ASSERT_TRUE(back.ok()) << back.message();
  EXPECT_FALSE(back->Metrics().available);
  EXPECT_EQ(back->Metrics().unavailable, "no optical_flow/0000/into_future/left/x.pfm");
  EXPECT_FALSE(ConventionSet::FromState(nlohmann::json::object()).ok());
}

TEST(Conventions, AMissingInputMakesItsConventionsUnavailableForGood) {
  const Frame f = HandWorked();
  MaskInputs no_flow = f.Inputs();
  no_flow.values[2] = nullptr;
  no_flow.missing[2] = "no optical_flow/0000/into_future/left/OpticalFlowIntoFuture_0001_L.pfm";
  ConventionSet set;
  set.Add(f.pred.data(), f.truth.data(), f.Inputs(), f.pixels());
  set.Add(f.pred.data(), f.truth.data(), no_flow, f.pixels());
  set.Add(f.pred.data(), f.truth.data(), f.Inputs(), f.pixels());
  const ConventionMetrics raft = set[Row("raft3d")].Metrics();
  EXPECT_FALSE(raft.available);
  EXPECT_EQ(raft.unavailable, "its mask needs the |2D optical flow|: " + no_flow.missing[2]);
  EXPECT_TRUE(set[Row("hplflownet")].Metrics().available);
  EXPECT_EQ(set[Row("hplflownet")].Metrics().frames, 3u);
}

synth::DatasetOptions TreeOptions(uint64_t seed) {
  synth::DatasetOptions o;
  o.scene.camera = synth::Camera{1050.0 * 160 / 960, 1.0, 79.5, 47.5, 160, 96};
  o.scene.frames = 3;
  o.scene.objects = 4;
  o.sequences = 2;
  o.seed = seed;
  return o;
}

class Tree {
 public:
  explicit Tree(uint64_t seed) {
    const testing::TestInfo* info = testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() / ("sfrt_conventions_" + std::string(info->name()));
    fs::remove_all(path_);
    EXPECT_TRUE(synth::WriteDataset(TreeOptions(seed), path_.string()).ok());
  }
  ~Tree() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string str() const { return path_.string(); }
  fs::path path() const { return path_; }

 private:
  fs::path path_;
};

Result<EvalReport> Baselines(const std::string& root) {
  EvalOptions options;
  options.dataset = root;
  options.classical = false;
  return RunEvaluation(options);
}

TEST(Conventions, MaskInputsAreDepthFromDisparityAndTheFlowsMagnitude) {
  Tree tree(31);
  const FrameRef f{"0001", "0000", "0001"};
  const auto& c = TreeOptions(31).scene.camera;
  Result<FrameMasks> masks = LoadMaskInputs(tree.str(), f, c.focal, c.baseline, 96, 160);
  ASSERT_TRUE(masks.ok()) << masks.message();
  const fs::path root = tree.path();
  Result<io::PfmImage> d = io::ReadPfm((root / "disparity/0001/left/0000.pfm").string());
  Result<io::PfmImage> dc =
      io::ReadPfm((root / "disparity_change/0001/into_future/left/0000.pfm").string());
  Result<io::PfmImage> uv = io::ReadPfm(
      (root / "optical_flow/0001/into_future/left/OpticalFlowIntoFuture_0000_L.pfm").string());
  ASSERT_TRUE(d.ok() && dc.ok() && uv.ok());
  for (size_t p : {0u, 777u, 96u * 160u - 1}) {
    EXPECT_DOUBLE_EQ(masks->values[0][p], c.focal * c.baseline / d->data[p]);
    EXPECT_DOUBLE_EQ(masks->values[1][p],
                     c.focal * c.baseline / (static_cast<double>(d->data[p]) + dc->data[p]));
    EXPECT_DOUBLE_EQ(masks->values[2][p],
                     std::hypot(static_cast<double>(uv->data[3 * p]), uv->data[3 * p + 1]));
  }
}

TEST(Conventions, ReportedPerMethodInTheJsonWithTheirDefinitions) {
  Tree tree(32);
  Result<EvalReport> report = Baselines(tree.str());
  ASSERT_TRUE(report.ok()) << report.message();
  const nlohmann::json j = nlohmann::json::parse(FormatJson(*report));
  ASSERT_TRUE(j["zero_flow"].contains("conventions"));
  for (const Convention& c : kConventions) {
    SCOPED_TRACE(c.key);
    const nlohmann::json& row = j["zero_flow"]["conventions"][c.key];
    EXPECT_EQ(row["name"], c.name);
    EXPECT_EQ(row["mask"], c.MaskWords());
    EXPECT_EQ(row["available"], true);
    EXPECT_GT(row["valid_pixels"].get<uint64_t>(), 0u);
    for (const char* key : {"epe3d", "acc05", "acc10", "outliers", "frames"}) {
      EXPECT_TRUE(row.contains(key)) << key;
    }
    EXPECT_EQ(j["definitions"]["conventions"][c.key], c.Definition());
  }
  // A synthetic room: every depth is within 35 and every flow within 250 px, so each mask keeps
  // every pixel with ground truth, and zero flow's EPE3D is the pooled one (camliflow, raft3d).
  EXPECT_EQ(j["zero_flow"]["conventions"]["raft3d"]["valid_pixels"],
            j["zero_flow"]["valid_pixels"]);
  EXPECT_NEAR(j["zero_flow"]["conventions"]["raft3d"]["epe3d"].get<double>(),
              j["zero_flow"]["epe3d"].get<double>(), 1e-8);
  EXPECT_TRUE(j["zero_flow"]["conventions"]["raft3d"]["outliers"].is_null());
  const std::string table = FormatTable(*report);
  EXPECT_NE(table.find("FlyingThings3D conventions"), std::string::npos) << table;
  EXPECT_NE(table.find("hplflownet zero_flow"), std::string::npos) << table;
}

TEST(Conventions, ADatasetWithoutDisparityReportsThemUnavailableNamingTheFile) {
  Tree tree(33);
  fs::remove_all(tree.path() / "disparity");  // scene_flow/ still gives the ground truth
  fs::remove_all(tree.path() / "optical_flow" / "0000");
  Result<EvalReport> report = Baselines(tree.str());
  ASSERT_TRUE(report.ok()) << report.message();
  for (int c = 0; c < kConventionCount; ++c) {
    const ConventionMetrics m = report->conventions[1][c].Metrics();
    SCOPED_TRACE(kConventions[c].key);
    EXPECT_FALSE(m.available);
    EXPECT_EQ(m.unavailable.rfind("its mask needs the ", 0), 0u) << m.unavailable;
  }
  // Each names the first file it lacks: RAFT-3D's the depth (checked before the 2D flow).
  EXPECT_EQ(report->conventions[1][Row("raft3d")].Metrics().unavailable,
            "its mask needs the depth at t: no disparity/0000/left/0000.pfm");
  EXPECT_EQ(report->conventions[1][Row("hplflownet")].Metrics().unavailable,
            "its mask needs the depth at t: no disparity/0000/left/0000.pfm");
  const nlohmann::json j = nlohmann::json::parse(FormatJson(*report));
  const nlohmann::json& row = j["zero_flow"]["conventions"]["camliflow"];
  EXPECT_EQ(row["available"], false);
  EXPECT_EQ(row["reason"], "its mask needs the depth at t: no disparity/0000/left/0000.pfm");
  EXPECT_TRUE(row["epe3d"].is_null());
  EXPECT_TRUE(row["acc05"].is_null());
  EXPECT_NE(FormatTable(*report).find("raft3d     unavailable: its mask needs the depth at t"),
            std::string::npos)
      << FormatTable(*report);
  // The metrics over every pixel are there as before.
  EXPECT_GT(report->overall[1].Metrics().valid_pixels, 0u);
}

TEST(Conventions, ADatasetWithoutOpticalFlowLosesOnlyRaft3d) {
  Tree tree(34);
  fs::remove_all(tree.path() / "optical_flow" / "0001");
  Result<EvalReport> report = Baselines(tree.str());
  ASSERT_TRUE(report.ok()) << report.message();
  EXPECT_EQ(report->conventions[1][Row("raft3d")].Metrics().unavailable,
            "its mask needs the |2D optical flow|: no "
            "optical_flow/0001/into_future/left/OpticalFlowIntoFuture_0000_L.pfm");
  for (const char* key : {"flownet3d", "hplflownet", "camliflow"}) {
    EXPECT_TRUE(report->conventions[1][Row(key)].Metrics().available) << key;
  }
}

}  // namespace
}  // namespace sfrt::eval
