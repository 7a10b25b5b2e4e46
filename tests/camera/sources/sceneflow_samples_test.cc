// The real Scene Flow samples committed in tests/data/sceneflow-samples (Driving and Monkaa,
// frames 0006-0008, cropped to 270x480; see tests/data/README.md). A missing directory is a
// failure, not a skip.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "sfrt/camera/stereo_source.h"

namespace sfrt::camera {
namespace {

const std::string kSamples = SFRT_SCENEFLOW_SAMPLES_DIR;

TEST(SceneFlowSamples, DetectedAndReadAsTwoSequencesOfConsecutivePairs) {
  ASSERT_TRUE(std::filesystem::is_directory(kSamples))
      << kSamples << " is missing: these tests read the Scene Flow samples committed in "
      << "tests/data/sceneflow-samples";
  Result<DatasetInfo> info = DetectDataset(kSamples);
  ASSERT_TRUE(info.ok()) << info.message();
  EXPECT_EQ(info->layout, DatasetLayout::kStereoDirs);
  EXPECT_EQ(info->sequences, (std::vector<std::string>{"images/Driving", "images/Monkaa"}));
  EXPECT_EQ(info->pairs, 6);

  Result<std::unique_ptr<StereoSource>> source = OpenDatasetSource(kSamples);
  ASSERT_TRUE(source.ok()) << source.message();
  PairWindow window(source->get());
  std::vector<std::string> windows;
  while (true) {
    Result<Fetched> got = window.Next();
    ASSERT_TRUE(got.ok()) << got.message();
    if (*got == Fetched::kEnd) break;
    for (const FramePair* p : {&window.previous(), &window.current()}) {
      EXPECT_EQ(p->left.size(), cv::Size(480, 270)) << p->left_path;
      EXPECT_EQ(p->right.size(), cv::Size(480, 270)) << p->right_path;
      EXPECT_EQ(p->left.type(), CV_8UC3);
    }
    // The two views of a real stereo pair differ; frames t and t+1 differ.
    EXPECT_GT(cv::norm(window.current().left, window.current().right, cv::NORM_L1), 0);
    EXPECT_GT(cv::norm(window.previous().left, window.current().left, cv::NORM_L1), 0);
    windows.push_back(window.current().sequence + ":" +
                      std::to_string(window.previous().frame_number) + "-" +
                      std::to_string(window.current().frame_number));
  }
  EXPECT_EQ(windows, (std::vector<std::string>{"images/Driving:6-7", "images/Driving:7-8",
                                               "images/Monkaa:6-7", "images/Monkaa:7-8"}));
  EXPECT_TRUE((*source)->skipped().empty());
}

}  // namespace
}  // namespace sfrt::camera
