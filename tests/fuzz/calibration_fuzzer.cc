// Fuzz target: the stereo calibration readers (ROS camera_info pair, Kalibr camchain, OpenCV
// FileStorage YAML, one or two files, the refusal of OpenCV XML, and the content-sniffing
// ReadStereoCalibration).
// The readers take paths, so the input is written to files in a private temporary directory.
// Input layout: byte 0 picks the reader (value % 7, below); the rest is the file content, split
// into two files at the first "\n---8<---\n" for the two-file readers (without the marker, both
// files get the whole content).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz/scratch_dir.h"
#include "sfrt/camera/calibration.h"

namespace {

constexpr std::string_view kSplit = "\n---8<---\n";

// Writes `content` to `name` in the scratch directory; returns its path.
std::string WriteFile(const std::string& name, std::string_view content) {
  const std::filesystem::path path = sfrt::fuzz::ScratchDir("sfrt-fuzz-calib") / name;
  sfrt::fuzz::WriteFileOrDie(path, content);
  return path.string();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const int mode = data[0] % 7;
  const std::string_view body(reinterpret_cast<const char*>(data + 1), size - 1);
  std::string_view first = body, second = body;
  if (const size_t at = body.find(kSplit); at != std::string_view::npos) {
    first = body.substr(0, at);
    second = body.substr(at + kSplit.size());
  }
  using namespace sfrt::camera;
  switch (mode) {
    case 0:  // ROS camera_info pair
      (void)ReadRosCameraInfoPair(WriteFile("left.yaml", first), WriteFile("right.yaml", second));
      break;
    case 1:  // Kalibr camchain
      (void)ReadKalibrCamchain(WriteFile("camchain.yaml", body));
      break;
    case 2:  // OpenCV FileStorage, one YAML file
      (void)ReadOpenCvCalibration({WriteFile("stereo.yml", body)});
      break;
    case 3:  // OpenCV FileStorage, one XML file (refused before any parser sees it)
      (void)ReadOpenCvCalibration({WriteFile("stereo.xml", body)});
      break;
    case 4:  // OpenCV FileStorage, intrinsics + extrinsics
      (void)ReadOpenCvCalibration(
          {WriteFile("intrinsics.yml", first), WriteFile("extrinsics.yml", second)});
      break;
    case 5:  // content sniffing, one file
      (void)ReadStereoCalibration({WriteFile("calib.yaml", body)});
      break;
    default:  // content sniffing, two files
      (void)ReadStereoCalibration({WriteFile("a.yaml", first), WriteFile("b.yaml", second)});
      break;
  }
  return 0;
}
