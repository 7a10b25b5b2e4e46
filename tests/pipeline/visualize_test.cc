// The visualisation's legend layout (no overlaps at any size), its colour scales and the
// --vis-scale syntax.
#include "sfrt/pipeline/visualize.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

namespace sfrt::pipeline {
namespace {

struct Size {
  int height;
  int width;
};
// The default model's size, the README's run sizes, and tiny panels narrower than the text.
const std::vector<Size> kSizes = {{96, 128}, {270, 480}, {540, 960}, {4, 4}, {16, 24}};

VisScale Fixed(double v) { return {VisScale::Mode::kFixed, v}; }

// Every legend element lies in the strip below the panels, inside the canvas, and no two overlap.
void ExpectLegendFits(const LegendLayout& l, Size s) {
  SCOPED_TRACE(std::to_string(s.height) + "x" + std::to_string(s.width));
  const cv::Rect canvas({0, 0}, l.canvas);
  EXPECT_GE(l.canvas.width, 3 * s.width);
  EXPECT_EQ(l.z.x + l.z.width, 3 * s.width);
  EXPECT_EQ(l.strip.y, s.height);
  std::vector<std::pair<std::string, cv::Rect>> items = {{"wheel", l.wheel}, {"bar", l.bar}};
  for (const auto& t : l.texts) items.emplace_back("'" + t.text + "'", t.box);
  for (size_t i = 0; i < items.size(); ++i) {
    const auto& [name, r] = items[i];
    EXPECT_FALSE(r.empty()) << name;
    EXPECT_EQ(r & l.strip, r) << name << " leaves the legend strip";
    EXPECT_EQ(r & canvas, r) << name << " leaves the canvas";
    EXPECT_GE(r.x, 1) << name << " touches the left edge";
    EXPECT_LE(r.x + r.width, l.canvas.width - 1) << name << " touches the right edge";
    EXPECT_LE(r.y + r.height, l.canvas.height - 1) << name << " touches the bottom edge";
    for (size_t j = i + 1; j < items.size(); ++j) {
      EXPECT_TRUE((r & items[j].second).empty()) << name << " overlaps " << items[j].first;
    }
  }
}

TEST(Visualizer, LegendTextBoxesNeverOverlapEachOtherOrTheEdgesAtAnySize) {
  for (const VisScale& scale : {VisScale{}, Fixed(0.15)}) {
    for (const std::string& units : {std::string(), std::string("metres"),
                                     std::string("training-camera scene units (baseline = 1)")}) {
      for (Size s : kSizes) {
        const double widest = 8.88e+88;
        ExpectLegendFits(ComputeLegendLayout(s.height, s.width, "000123 (48x64)",
                                             MakeLegendText(scale, units, widest, widest)),
                         s);
      }
    }
  }
}

TEST(Visualizer, RendersAt96x128And270x480And540x960WithTheLaidOutLegend) {
  for (Size s : {Size{96, 128}, Size{270, 480}, Size{540, 960}}) {
    cv::Mat left(s.height, s.width, CV_8UC3, cv::Scalar(40, 80, 120));
    std::vector<float> flow(static_cast<size_t>(s.height) * s.width * 3, 0.0f);
    for (size_t i = 0; i < flow.size(); i += 3) {
      flow[i] = 0.1f;
      flow[i + 2] = -0.14f;
    }
    Visualizer vis({VisScale{}, "metres"});
    cv::Mat canvas;
    vis.Render(left, flow.data(), 3, "000000", &canvas);
    ASSERT_EQ(canvas.size(), vis.layout().canvas);
    ExpectLegendFits(vis.layout(), s);
    EXPECT_EQ(canvas.at<cv::Vec3b>(0, 0), cv::Vec3b(40, 80, 120));
    // The strip outside every legend element stays black: nothing is drawn over the boxes' edges.
    const LegendLayout& l = vis.layout();
    EXPECT_EQ(canvas.at<cv::Vec3b>(l.canvas.height - 1, l.canvas.width - 1), cv::Vec3b(0, 0, 0));
  }
}

TEST(Visualizer, LegendSaysUnitsTheMeaningOfPlusZAndTheScale) {
  const LegendText fixed = MakeLegendText(Fixed(0.15), "metres", 0.15, 0.15);
  std::string all;
  for (const auto& line : fixed.xy_lines) all += line + "|";
  for (const auto& line : fixed.z_lines) all += line + "|";
  EXPECT_NE(all.find("+Z = away from camera"), std::string::npos) << all;
  EXPECT_NE(all.find("metres"), std::string::npos) << all;
  EXPECT_NE(all.find("full colour at |d| 0.15"), std::string::npos) << all;
  const LegendText automatic = MakeLegendText(VisScale{}, "", 0.123, 0.5);
  all.clear();
  for (const auto& line : automatic.xy_lines) all += line + "|";
  for (const auto& line : automatic.z_lines) all += line + "|";
  EXPECT_NE(all.find("model units"), std::string::npos) << all;
  EXPECT_NE(all.find("|d| max 0.123 (auto)"), std::string::npos) << all;
  EXPECT_NE(all.find("|Z| max 0.5 (auto)"), std::string::npos) << all;
  // The wheel's axes are labelled.
  const LegendLayout l = ComputeLegendLayout(96, 128, "t", fixed);
  std::vector<std::string> texts;
  for (const auto& t : l.texts) texts.push_back(t.text);
  EXPECT_NE(std::find(texts.begin(), texts.end(), "+X"), texts.end());
  EXPECT_NE(std::find(texts.begin(), texts.end(), "+Y"), texts.end());
}

// Frame 1 holds a fast pixel beside a slow one; frame 2 only the slow one. With a fixed scale
// the slow pixel has one colour in both frames; with auto it brightens when the fast one goes.
TEST(Visualizer, VisScaleFixedKeepsTheSameColourForTheSameFlowAcrossFrames) {
  cv::Mat left(2, 2, CV_8UC3, cv::Scalar(0, 0, 0));
  std::vector<float> frame1(2 * 2 * 3, 0.0f), frame2(2 * 2 * 3, 0.0f);
  for (auto* f : {&frame1, &frame2}) {
    (*f)[0] = 0.05f;  // pixel (0,0): slow, in X and Z
    (*f)[2] = 0.05f;
  }
  frame1[3] = 1.0f;  // pixel (0,1) in frame 1 only: fast
  frame1[5] = -1.0f;
  auto colours = [&](const VisScale& scale) {
    Visualizer vis({scale, "metres"});
    cv::Mat a, b;
    vis.Render(left, frame1.data(), 3, "1", &a);
    const std::pair<cv::Vec3b, cv::Vec3b> first = {a.at<cv::Vec3b>(0, 2), a.at<cv::Vec3b>(0, 4)};
    vis.Render(left, frame2.data(), 3, "2", &b);
    const std::pair<cv::Vec3b, cv::Vec3b> second = {b.at<cv::Vec3b>(0, 2), b.at<cv::Vec3b>(0, 4)};
    return std::pair{first, second};
  };
  const auto [fixed1, fixed2] = colours(Fixed(0.15));
  EXPECT_EQ(fixed1.first, fixed2.first);    // X/Y panel
  EXPECT_EQ(fixed1.second, fixed2.second);  // Z panel
  EXPECT_EQ(fixed1.second, DivergingColor(0.05 / 0.15));
  const auto [auto1, auto2] = colours(VisScale{});
  EXPECT_NE(auto1.first, auto2.first);
  EXPECT_NE(auto1.second, auto2.second);
}

TEST(Visualizer, VisScaleParsesAutoAndFixedValueAndRejectsTheRest) {
  auto a = ParseVisScale("auto");
  ASSERT_TRUE(a.ok()) << a.message();
  EXPECT_EQ(a->mode, VisScale::Mode::kAuto);
  auto f = ParseVisScale("fixed:0.25");
  ASSERT_TRUE(f.ok()) << f.message();
  EXPECT_EQ(f->mode, VisScale::Mode::kFixed);
  EXPECT_DOUBLE_EQ(f->value, 0.25);
  for (const char* bad : {"", "Auto", "fixed", "fixed:", "fixed:0", "fixed:-1", "fixed:abc",
                          "fixed:0.1x", "fixed:nan", "fixed:inf", "0.15"}) {
    auto r = ParseVisScale(bad);
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_NE(r.message().find("--vis-scale '" + std::string(bad) + "'"), std::string::npos)
        << r.message();
    EXPECT_NE(r.message().find("'auto', 'first' or 'fixed:VALUE'"), std::string::npos)
        << r.message();
  }
  auto first = ParseVisScale("first");
  ASSERT_TRUE(first.ok()) << first.message();
  EXPECT_EQ(first->mode, VisScale::Mode::kFirst);
}

// An output that is not 3-D flow (5 channels) is not labelled as flow in the legend.
TEST(Visualizer, ALegendOfAnOutputOtherThanThreeChannelsDoesNotCallItFlow) {
  const LegendText five = MakeLegendText(VisScale{}, "unknown", 1.0, 1.0, 5);
  EXPECT_EQ(five.z_lines.back(), "channels 0-2 of 5 drawn: not 3-D flow");
  const LegendText three = MakeLegendText(VisScale{}, "metres", 1.0, 1.0, 3);
  EXPECT_EQ(three.z_lines.back(), "flow in metres, t to t+1");
}

// kFirst: the scales come from the first frame (its 99th percentile, so one fast pixel among
// slow ones does not set them) and stay for the run: the slow flow keeps its colour when the
// next frame moves faster, and is drawn well above black.
TEST(Visualizer, VisScaleFirstTakesTheFirstFramesScaleAndKeepsIt) {
  const int h = 10, w = 20;
  cv::Mat left(h, w, CV_8UC3, cv::Scalar(0, 0, 0));
  std::vector<float> slow(h * w * 3, 0.0f), fast(h * w * 3, 0.0f);
  for (int i = 0; i < h * w; ++i) {
    slow[3 * i] = 0.02f;  // about the default model's motion per frame, in metres
    slow[3 * i + 2] = 0.02f;
    fast[3 * i] = 0.2f;
    fast[3 * i + 2] = 0.2f;
  }
  slow[0] = 5.0f;  // one outlier in the first frame
  Visualizer vis({VisScale{VisScale::Mode::kFirst, 0}, "metres"});
  cv::Mat a, b;
  vis.Render(left, slow.data(), 3, "1", &a);
  EXPECT_NEAR(vis.last_xy_scale(), 0.02, 1e-6);
  EXPECT_NEAR(vis.last_z_scale(), 0.02, 1e-6);
  const cv::Vec3b slow_xy = a.at<cv::Vec3b>(5, w + 5);
  EXPECT_GT(std::max({slow_xy[0], slow_xy[1], slow_xy[2]}), 200);  // full colour, not black
  EXPECT_EQ(a.at<cv::Vec3b>(5, 2 * w + 5), DivergingColor(1.0));
  vis.Render(left, fast.data(), 3, "2", &b);
  EXPECT_NEAR(vis.last_xy_scale(), 0.02, 1e-6);  // kept, not the second frame's
  vis.Render(left, slow.data(), 3, "3", &b);
  EXPECT_EQ(b.at<cv::Vec3b>(5, w + 5), slow_xy);
}

}  // namespace
}  // namespace sfrt::pipeline
