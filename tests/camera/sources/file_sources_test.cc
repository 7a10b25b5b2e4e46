// Dataset layout detection, pairing, ordering and bad-frame policy of the file sources.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "camera/sources/test_util.h"
#include "sfrt/camera/stereo_source.h"

namespace sfrt::camera {
namespace {

using testing::kLeftTag;
using testing::kRightTag;
using testing::TaggedImage;
using testing::TempDir;
using testing::WritePng;
using testing::WriteText;

std::string Num4(int n) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%04d", n);
  return buf;
}

// <dir>/{left,right}/NNNN.png for the given frame numbers; the pixels encode side and number.
void WriteStereoDir(const std::string& dir, const std::vector<int>& frames, int tag_offset = 0) {
  for (int f : frames) {
    WritePng(dir + "/left/" + Num4(f) + ".png", TaggedImage(kLeftTag + tag_offset, f));
    WritePng(dir + "/right/" + Num4(f) + ".png", TaggedImage(kRightTag + tag_offset, f));
  }
}

struct Read {
  std::vector<FramePair> pairs;
  Status error;
};

Read ReadAll(StereoSource* source) {
  Read r;
  while (true) {
    FramePair pair;
    Result<Fetched> got = source->Next(&pair);
    if (!got.ok()) {
      r.error = got.status();
      return r;
    }
    if (*got == Fetched::kEnd) return r;
    r.pairs.push_back(pair);
  }
}

// The image's B and G channels (tag, number), read from its top-left pixel.
std::pair<int, int> TagOf(const cv::Mat& image) {
  const cv::Vec3b p = image.at<cv::Vec3b>(0, 0);
  return {p[0], p[1]};
}

TEST(DatasetSource, SceneFlowLayoutDetectedAndCleanPassPreferred) {
  TempDir tmp;
  WriteStereoDir(tmp / "frames_cleanpass/TRAIN/A/0000", {6, 7, 8});
  WriteStereoDir(tmp / "frames_finalpass/TRAIN/A/0000", {6, 7, 8}, /*tag_offset=*/1);
  WriteText(tmp / "disparity/TRAIN/A/0000/left/0006.pfm", "Pf\n1 1\n-1\n0000");

  Result<DatasetInfo> info = DetectDataset(tmp.path().string());
  ASSERT_TRUE(info.ok()) << info.message();
  EXPECT_EQ(info->layout, DatasetLayout::kSceneFlow);
  EXPECT_EQ(info->pass, "cleanpass");
  ASSERT_EQ(info->sequences, std::vector<std::string>{"frames_cleanpass/TRAIN/A/0000"});
  EXPECT_EQ(info->pairs, 3);

  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp.path().string());
  ASSERT_TRUE(source.ok()) << source.message();
  Read r = ReadAll(source->get());
  ASSERT_TRUE(r.error.ok()) << r.error.message();
  ASSERT_EQ(r.pairs.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const FramePair& p = r.pairs[i];
    EXPECT_EQ(p.index, static_cast<int64_t>(i));
    EXPECT_EQ(p.frame_number, static_cast<int64_t>(6 + i));
    EXPECT_EQ(p.sequence, "frames_cleanpass/TRAIN/A/0000");
    EXPECT_EQ(p.left_path, tmp / ("frames_cleanpass/TRAIN/A/0000/left/" + Num4(6 + i) + ".png"));
    EXPECT_EQ(p.right_path, tmp / ("frames_cleanpass/TRAIN/A/0000/right/" + Num4(6 + i) + ".png"));
    EXPECT_EQ(TagOf(p.left), std::make_pair(kLeftTag, static_cast<int>(6 + i)));
    EXPECT_EQ(TagOf(p.right), std::make_pair(kRightTag, static_cast<int>(6 + i)));
    EXPECT_EQ(p.left.type(), CV_8UC3);
    EXPECT_FALSE(p.timestamp_s.has_value());
  }
}

TEST(DatasetSource, SceneFlowFinalPassOnRequest) {
  TempDir tmp;
  WriteStereoDir(tmp / "frames_cleanpass/TEST/B/0003", {6, 7});
  WriteStereoDir(tmp / "frames_finalpass/TEST/B/0003", {6, 7}, /*tag_offset=*/1);
  DatasetOptions options;
  options.pass = "final";
  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp.path().string(), options);
  ASSERT_TRUE(source.ok()) << source.message();
  Read r = ReadAll(source->get());
  ASSERT_TRUE(r.error.ok()) << r.error.message();
  ASSERT_EQ(r.pairs.size(), 2u);
  EXPECT_EQ(TagOf(r.pairs[0].left).first, kLeftTag + 1);
  EXPECT_NE(r.pairs[0].left_path.find("frames_finalpass"), std::string::npos);

  options.pass = "medium";
  Result<DatasetInfo> bad = DetectDataset(tmp.path().string(), options);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.message().find("'medium'"), std::string::npos) << bad.message();
}

TEST(DatasetSource, FlatSamplesLayoutHasOneSequencePerDirectory) {
  TempDir tmp;  // like tests/data/sceneflow-samples
  WriteStereoDir(tmp / "images/Monkaa", {6, 7, 8});
  WriteStereoDir(tmp / "images/Driving", {6, 7, 8});
  WriteText(tmp / "disparity/Driving/left/0006.pfm", "Pf\n1 1\n-1\n0000");
  Result<DatasetInfo> info = DetectDataset(tmp.path().string());
  ASSERT_TRUE(info.ok()) << info.message();
  EXPECT_EQ(info->layout, DatasetLayout::kStereoDirs);
  EXPECT_EQ(info->sequences, (std::vector<std::string>{"images/Driving", "images/Monkaa"}));
  EXPECT_EQ(info->pairs, 6);

  // The sequence directory itself also works as a root.
  Result<DatasetInfo> one = DetectDataset(tmp / "images/Monkaa");
  ASSERT_TRUE(one.ok()) << one.message();
  EXPECT_EQ(one->sequences, std::vector<std::string>{"Monkaa"});
  EXPECT_EQ(one->pairs, 3);
}

TEST(DatasetSource, FramesAreSortedByNameWhateverTheCreationOrder) {
  TempDir tmp;
  WriteStereoDir(tmp / "seq", {12, 3, 10, 9, 11});
  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp / "seq");
  ASSERT_TRUE(source.ok()) << source.message();
  Read r = ReadAll(source->get());
  ASSERT_TRUE(r.error.ok()) << r.error.message();
  std::vector<int64_t> numbers;
  for (const FramePair& p : r.pairs) numbers.push_back(p.frame_number);
  EXPECT_EQ(numbers, (std::vector<int64_t>{3, 9, 10, 11, 12}));
}

TEST(DatasetSource, UnknownLayoutIsAnErrorNamingTheRoot) {
  TempDir tmp;
  WritePng(tmp / "just/some/0001.png", TaggedImage(1, 1));
  Result<DatasetInfo> info = DetectDataset(tmp.path().string());
  ASSERT_FALSE(info.ok());
  EXPECT_NE(info.message().find(tmp.path().string()), std::string::npos) << info.message();
  EXPECT_NE(info.message().find("no known layout"), std::string::npos) << info.message();

  Result<DatasetInfo> missing = DetectDataset(tmp / "nope");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find(tmp / "nope"), std::string::npos) << missing.message();
}

TEST(DatasetSource, KittiPairsTenAndElevenPerScene) {
  TempDir tmp;
  for (const char* scene : {"000001", "000000"}) {
    for (int frame : {11, 10}) {
      const std::string name = std::string(scene) + "_" + std::to_string(frame) + ".png";
      WritePng(tmp / ("training/image_2/" + name), TaggedImage(kLeftTag, frame));
      WritePng(tmp / ("training/image_3/" + name), TaggedImage(kRightTag, frame));
    }
  }
  WritePng(tmp / "training/disp_occ_0/000000_10.png", TaggedImage(0, 0));
  Result<DatasetInfo> info = DetectDataset(tmp.path().string());
  ASSERT_TRUE(info.ok()) << info.message();
  EXPECT_EQ(info->layout, DatasetLayout::kKitti);
  EXPECT_EQ(info->sequences, (std::vector<std::string>{"training/000000", "training/000001"}));

  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp.path().string());
  ASSERT_TRUE(source.ok()) << source.message();
  PairWindow window(source->get());
  std::vector<std::string> seen;
  while (true) {
    Result<Fetched> got = window.Next();
    ASSERT_TRUE(got.ok()) << got.message();
    if (*got == Fetched::kEnd) break;
    EXPECT_EQ(window.previous().frame_number, 10);
    EXPECT_EQ(window.current().frame_number, 11);
    EXPECT_EQ(window.previous().sequence, window.current().sequence);
    EXPECT_EQ(TagOf(window.current().right), std::make_pair(kRightTag, 11));
    EXPECT_EQ(window.current().right_path,
              tmp / ("training/image_3/" + window.current().sequence.substr(9) + "_11.png"));
    seen.push_back(window.current().sequence);
  }
  EXPECT_EQ(seen, (std::vector<std::string>{"training/000000", "training/000001"}));
}

TEST(PairWindow, NeverCrossesSequences) {
  TempDir tmp;
  WriteStereoDir(tmp / "frames_cleanpass/TRAIN/A/0000", {6, 7, 8});
  WriteStereoDir(tmp / "frames_cleanpass/TRAIN/A/0001", {6, 7, 8});
  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp.path().string());
  ASSERT_TRUE(source.ok()) << source.message();
  PairWindow window(source->get());
  std::vector<std::string> windows;
  while (true) {
    Result<Fetched> got = window.Next();
    ASSERT_TRUE(got.ok()) << got.message();
    if (*got == Fetched::kEnd) break;
    windows.push_back(window.previous().sequence.substr(25) + ":" +
                      std::to_string(window.previous().frame_number) + "-" +
                      std::to_string(window.current().frame_number));
    // The slots hold distinct images: previous is frame t, current t+1.
    EXPECT_EQ(TagOf(window.previous().left).second + 1, TagOf(window.current().left).second);
  }
  EXPECT_EQ(windows, (std::vector<std::string>{"0000:6-7", "0000:7-8", "0001:6-7", "0001:7-8"}));
}

void CorruptFrameFixture(const TempDir& tmp) {
  WriteStereoDir(tmp / "seq", {6, 7, 8, 9});
  // A PNG signature followed by garbage: the file exists but does not decode.
  WriteText(tmp / "seq/left/0007.png", std::string("\x89PNG\r\n\x1a\n", 8) + "not really a png");
}

TEST(BadFrames, CorruptPngStopsWithItsPath) {
  TempDir tmp;
  CorruptFrameFixture(tmp);
  DatasetOptions options;
  options.on_bad_frame = BadFramePolicy::kStop;
  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp / "seq", options);
  ASSERT_TRUE(source.ok()) << source.message();
  Read r = ReadAll(source->get());
  ASSERT_FALSE(r.error.ok());
  EXPECT_EQ(r.pairs.size(), 1u);
  EXPECT_NE(r.error.message().find(tmp / "seq/left/0007.png"), std::string::npos)
      << r.error.message();
  EXPECT_NE(r.error.message().find("could not be decoded"), std::string::npos) << r.error.message();
  // Stopped for good.
  FramePair pair;
  Result<Fetched> again = (*source)->Next(&pair);
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.message(), r.error.message());
}

TEST(BadFrames, CorruptPngSkippedAndReportedWithItsPath) {
  TempDir tmp;
  CorruptFrameFixture(tmp);
  DatasetOptions options;
  options.on_bad_frame = BadFramePolicy::kSkip;
  std::vector<BadFrame> reported;
  options.on_bad_frame_callback = [&](const BadFrame& bad) { reported.push_back(bad); };
  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp / "seq", options);
  ASSERT_TRUE(source.ok()) << source.message();
  PairWindow window(source->get());
  std::vector<std::pair<int64_t, int64_t>> windows;
  while (true) {
    Result<Fetched> got = window.Next();
    ASSERT_TRUE(got.ok()) << got.message();
    if (*got == Fetched::kEnd) break;
    windows.emplace_back(window.previous().frame_number, window.current().frame_number);
  }
  // 6 | 7 bad | 8 9: the only consecutive window left is (8, 9).
  EXPECT_EQ(windows, (std::vector<std::pair<int64_t, int64_t>>{{8, 9}}));
  ASSERT_EQ(reported.size(), 1u);
  EXPECT_EQ(reported[0].path, tmp / "seq/left/0007.png");
  EXPECT_EQ(reported[0].index, 1);
  ASSERT_EQ((*source)->skipped().size(), 1u);
  EXPECT_EQ((*source)->skipped()[0].path, tmp / "seq/left/0007.png");
}

TEST(BadFrames, MissingRightFrameIsNamedByItsExpectedPath) {
  TempDir tmp;
  WriteStereoDir(tmp / "seq", {6, 7, 8});
  std::filesystem::remove(tmp / "seq/right/0007.png");
  for (BadFramePolicy policy : {BadFramePolicy::kStop, BadFramePolicy::kSkip}) {
    DatasetOptions options;
    options.on_bad_frame = policy;
    Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp / "seq", options);
    ASSERT_TRUE(source.ok()) << source.message();
    Read r = ReadAll(source->get());
    if (policy == BadFramePolicy::kStop) {
      ASSERT_FALSE(r.error.ok());
      EXPECT_NE(r.error.message().find(tmp / "seq/right/0007.png"), std::string::npos)
          << r.error.message();
      EXPECT_NE(r.error.message().find("missing"), std::string::npos) << r.error.message();
      EXPECT_EQ(r.pairs.size(), 1u);
    } else {
      ASSERT_TRUE(r.error.ok()) << r.error.message();
      ASSERT_EQ(r.pairs.size(), 2u);
      EXPECT_EQ(r.pairs[1].frame_number, 8);
      ASSERT_EQ((*source)->skipped().size(), 1u);
      EXPECT_EQ((*source)->skipped()[0].path, tmp / "seq/right/0007.png");
    }
  }
}

TEST(BadFrames, LeftRightSizeMismatchIsABadFrame) {
  TempDir tmp;
  WriteStereoDir(tmp / "seq", {1, 2});
  WritePng(tmp / "seq/right/0002.png", TaggedImage(kRightTag, 2, cv::Size(9, 6)));
  DatasetOptions options;
  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(tmp / "seq", options);
  ASSERT_TRUE(source.ok()) << source.message();
  Read r = ReadAll(source->get());
  ASSERT_FALSE(r.error.ok());
  EXPECT_NE(r.error.message().find(tmp / "seq/right/0002.png"), std::string::npos)
      << r.error.message();
  EXPECT_NE(r.error.message().find("6x9 (HxW)"), std::string::npos) << r.error.message();
}

TEST(BadFrames, PolicyParses) {
  EXPECT_EQ(*ParseBadFramePolicy("skip"), BadFramePolicy::kSkip);
  EXPECT_EQ(*ParseBadFramePolicy("stop"), BadFramePolicy::kStop);
  Result<BadFramePolicy> bad = ParseBadFramePolicy("ignore");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.message().find("'ignore'"), std::string::npos);
}

TEST(PlainSource, DirectoriesPairBySortedPosition) {
  TempDir tmp;
  for (int i : {2, 0, 1}) {
    WritePng(tmp / ("cam_l/l_" + std::to_string(i) + ".png"), TaggedImage(kLeftTag, i));
    WritePng(tmp / ("cam_r/r_" + std::to_string(i) + ".png"), TaggedImage(kRightTag, i));
  }
  WriteText(tmp / "cam_l/notes.txt", "not an image");
  Result<std::unique_ptr<StereoSource>> source = OpenPlainSource(tmp / "cam_l", tmp / "cam_r");
  ASSERT_TRUE(source.ok()) << source.message();
  EXPECT_EQ((*source)->size(), 3);
  Read r = ReadAll(source->get());
  ASSERT_TRUE(r.error.ok()) << r.error.message();
  ASSERT_EQ(r.pairs.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(TagOf(r.pairs[i].left), std::make_pair(kLeftTag, i));
    EXPECT_EQ(TagOf(r.pairs[i].right), std::make_pair(kRightTag, i));
    EXPECT_EQ(r.pairs[i].frame_number, i);
    EXPECT_EQ(r.pairs[i].sequence, "");
  }
}

TEST(PlainSource, GlobPatternsSelectAndSortFiles) {
  TempDir tmp;
  for (int i : {3, 1, 2}) {
    WritePng(tmp / ("all/left_" + std::to_string(i) + ".png"), TaggedImage(kLeftTag, i));
    WritePng(tmp / ("all/right_" + std::to_string(i) + ".png"), TaggedImage(kRightTag, i));
  }
  Result<std::unique_ptr<StereoSource>> source =
      OpenPlainSource(tmp / "all/left_*.png", tmp / "all/right_*.png");
  ASSERT_TRUE(source.ok()) << source.message();
  Read r = ReadAll(source->get());
  ASSERT_TRUE(r.error.ok()) << r.error.message();
  ASSERT_EQ(r.pairs.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(TagOf(r.pairs[i].left), std::make_pair(kLeftTag, i + 1));
    EXPECT_EQ(TagOf(r.pairs[i].right), std::make_pair(kRightTag, i + 1));
  }
  Result<std::unique_ptr<StereoSource>> none = OpenPlainSource(tmp / "all/x_*.png", tmp / "all");
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.message().find("x_*.png"), std::string::npos) << none.message();
}

TEST(PlainSource, UnequalCountsReportTheUnpairedFrame) {
  TempDir tmp;
  for (int i = 0; i < 3; ++i) {
    WritePng(tmp / ("l/" + std::to_string(i) + ".png"), TaggedImage(kLeftTag, i));
    if (i < 2) WritePng(tmp / ("r/" + std::to_string(i) + ".png"), TaggedImage(kRightTag, i));
  }
  Result<std::unique_ptr<StereoSource>> source = OpenPlainSource(tmp / "l", tmp / "r");
  ASSERT_TRUE(source.ok()) << source.message();
  Read r = ReadAll(source->get());
  EXPECT_EQ(r.pairs.size(), 2u);
  ASSERT_FALSE(r.error.ok());
  EXPECT_NE(r.error.message().find(tmp / "l/2.png"), std::string::npos) << r.error.message();
  EXPECT_NE(r.error.message().find("no right frame"), std::string::npos) << r.error.message();
}

}  // namespace
}  // namespace sfrt::camera
