// The window rule every source follows (window_chain.h), and PairWindow applying it to files.
#include "sfrt/camera/window_chain.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "camera/sources/test_util.h"
#include "sfrt/camera/stereo_source.h"

namespace sfrt::camera {
namespace {

constexpr int64_t kMs = 1'000'000;

std::vector<ChainLink> OfferAll(WindowChain* chain, const std::vector<int64_t>& stamps) {
  std::vector<ChainLink> links;
  for (int64_t s : stamps) links.push_back(chain->Offer(s));
  return links;
}

TEST(WindowChain, SteadyStampsFormAWindowPerPairAfterTheFirst) {
  WindowChain chain;
  EXPECT_EQ(OfferAll(&chain, {0, 33 * kMs, 66 * kMs, 100 * kMs}),
            (std::vector<ChainLink>{ChainLink::kFirst, ChainLink::kWindow, ChainLink::kWindow,
                                    ChainLink::kWindow}));
  EXPECT_EQ(chain.counts().windows, 3);
  EXPECT_EQ(chain.counts().breaks(), 0);
  EXPECT_EQ(chain.interval(), 33 * kMs);  // the median of 33, 33, 34
}

TEST(WindowChain, AStampGapBeyondOneAndAHalfIntervalsOpensNoWindow) {
  WindowChain chain;
  // 100 ms steps, then one of 200 ms (a frame missing from the stream), then 100 ms again.
  EXPECT_EQ(OfferAll(&chain, {0, 100, 200, 400, 500}),
            (std::vector<ChainLink>{ChainLink::kFirst, ChainLink::kWindow, ChainLink::kWindow,
                                    ChainLink::kGap, ChainLink::kWindow}));
  EXPECT_EQ(chain.counts().skipped_for_gap, 1);
  // 1.5 intervals exactly is still a window; just beyond is not.
  WindowChain edge;
  EXPECT_EQ(OfferAll(&edge, {0, 100, 200, 350, 501}),
            (std::vector<ChainLink>{ChainLink::kFirst, ChainLink::kWindow, ChainLink::kWindow,
                                    ChainLink::kWindow, ChainLink::kGap}));
}

TEST(WindowChain, ANominalIntervalJudgesTheFirstStep) {
  WindowChain chain(100);
  EXPECT_EQ(OfferAll(&chain, {0, 200, 300}),
            (std::vector<ChainLink>{ChainLink::kFirst, ChainLink::kGap, ChainLink::kWindow}));
}

TEST(WindowChain, AStampThatGoesBackRestartsTheStream) {
  WindowChain chain;
  // A bag played twice: the second play's stamps start again at 0.
  EXPECT_EQ(
      OfferAll(&chain, {1000, 1100, 1200, 0, 100, 100}),
      (std::vector<ChainLink>{ChainLink::kFirst, ChainLink::kWindow, ChainLink::kWindow,
                              ChainLink::kBackwards, ChainLink::kWindow, ChainLink::kBackwards}));
  EXPECT_EQ(chain.counts().stream_restarts, 2);
  EXPECT_EQ(chain.counts().windows, 3);
}

TEST(WindowChain, ALostFrameBreaksTheChainOnce) {
  WindowChain chain;
  EXPECT_EQ(chain.Offer(0), ChainLink::kFirst);
  EXPECT_EQ(chain.Offer(10), ChainLink::kWindow);
  chain.Lose();
  EXPECT_EQ(chain.Offer(30), ChainLink::kLost);
  EXPECT_EQ(chain.Offer(40), ChainLink::kWindow);
  EXPECT_EQ(chain.counts().broken_by_loss, 1);
  // The step across the loss is not learnt as the stream's interval.
  EXPECT_EQ(chain.interval(), 10);
}

TEST(WindowChain, ALastingChangeOfRateIsLearnt) {
  WindowChain chain;
  std::vector<int64_t> stamps;
  for (int i = 0; i < 10; ++i) stamps.push_back(i * 10);        // 10 per frame
  for (int i = 1; i <= 20; ++i) stamps.push_back(90 + i * 30);  // then 30 per frame
  const std::vector<ChainLink> links = OfferAll(&chain, stamps);
  EXPECT_EQ(links.back(), ChainLink::kWindow);
  EXPECT_GT(chain.counts().skipped_for_gap, 0);
  EXPECT_EQ(chain.interval(), 30);
}

TEST(WindowChain, RestartForgetsTheLastPairAndCountsNothing) {
  WindowChain chain;
  (void)OfferAll(&chain, {0, 10, 20});
  chain.Restart();
  EXPECT_EQ(chain.Offer(5), ChainLink::kFirst);
  EXPECT_EQ(chain.Offer(500), ChainLink::kWindow);  // no interval known after the restart
  EXPECT_EQ(chain.counts().breaks(), 0);
}

// ---- PairWindow on files: the same rule.

using testing::kLeftTag;
using testing::kRightTag;
using testing::TaggedImage;
using testing::TempDir;
using testing::WritePng;

void WriteFrames(const std::string& dir, const std::vector<int>& frames) {
  for (int f : frames) {
    char name[16];
    std::snprintf(name, sizeof(name), "%04d.png", f);
    WritePng(dir + "/left/" + name, TaggedImage(kLeftTag, f));
    WritePng(dir + "/right/" + name, TaggedImage(kRightTag, f));
  }
}

std::vector<std::pair<int64_t, int64_t>> Windows(PairWindow* window) {
  std::vector<std::pair<int64_t, int64_t>> out;
  while (true) {
    Result<Fetched> got = window->Next();
    EXPECT_TRUE(got.ok()) << got.message();
    if (!got.ok() || *got == Fetched::kEnd) return out;
    out.emplace_back(window->previous().frame_number, window->current().frame_number);
  }
}

TEST(PairWindow, AFileMissingFromANumberedSequenceIsAGapNoWindowSpans) {
  TempDir tmp;
  WriteFrames(tmp / "seq", {6, 7, 8, 10, 11});  // 0009 is missing from both sides
  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp / "seq");
  ASSERT_TRUE(source.ok()) << source.message();
  PairWindow window(source->get());
  EXPECT_EQ(Windows(&window), (std::vector<std::pair<int64_t, int64_t>>{{6, 7}, {7, 8}, {10, 11}}));
  EXPECT_EQ(window.counts().skipped_for_gap, 1);
  EXPECT_EQ(window.counts().windows, 3);
}

TEST(PairWindow, EvenlySpacedFrameNumbersAreOneStream) {
  TempDir tmp;
  WriteFrames(tmp / "seq", {0, 5, 10, 15});  // every fifth frame kept: still consecutive
  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp / "seq");
  ASSERT_TRUE(source.ok()) << source.message();
  PairWindow window(source->get());
  EXPECT_EQ(Windows(&window),
            (std::vector<std::pair<int64_t, int64_t>>{{0, 5}, {5, 10}, {10, 15}}));
  EXPECT_EQ(window.counts().breaks(), 0);
}

}  // namespace
}  // namespace sfrt::camera
