// Fuzz target: the stereo frame reader of file replay (camera/sources OpenPlainSource ->
// FileListSource::Next -> cv::imread, the decoder `sfrt run --replay-left/--replay-right` and,
// through the same cv::imread call, `sfrt infer --left0 ...` use for PNG/PPM frames).
// The input is byte 0, a selector, then the left frame's file content. Selector bits 0-1 pick the
// name's extension (.png .ppm .pgm .jpg; cv::imread picks the decoder from the content, the name
// only has to pass the source's extension filter), bit 2 the bad-frame policy (skip, stop), bit 3
// how the left side is given (its directory, a glob). The right frame is a fixed valid 4x4 PPM,
// so a decodable input of another size takes the size-mismatch path.
// OpenCV and its codec libraries are not instrumented: libFuzzer sees no coverage inside them and
// ASan checks only what they pass through intercepted calls (memcpy, malloc, ...).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include "fuzz/scratch_dir.h"
#include "sfrt/camera/stereo_source.h"

namespace {

const std::filesystem::path& TempDir() {
  // right/0.ppm: the fixed right frame, a valid 4x4 PPM.
  return sfrt::fuzz::ScratchDir("sfrt-fuzz-image", [](const std::filesystem::path& root) {
    std::string ppm = "P6\n4 4\n255\n";
    for (int i = 0; i < 4 * 4 * 3; ++i) ppm.push_back(static_cast<char>(i * 5));
    sfrt::fuzz::WriteFileOrDie(root / "right/0.ppm", ppm);
  });
}

void ReadAll(const std::string& left, const std::string& right,
             sfrt::camera::BadFramePolicy policy) {
  using namespace sfrt::camera;
  SourceOptions options;
  options.on_bad_frame = policy;
  auto source = OpenPlainSource(left, right, options);
  if (!source.ok()) return;
  FramePair pair;
  for (int i = 0; i < 4; ++i) {
    auto fetched = (*source)->Next(&pair);
    if (!fetched.ok() || *fetched == Fetched::kEnd) break;
    if (pair.left.type() != CV_8UC3 || pair.left.size() != pair.right.size()) {
      std::fprintf(stderr, "source handed out a pair that is not two equal-size BGR images\n");
      std::abort();
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* const kExt[] = {".png", ".ppm", ".pgm", ".jpg"};
  const std::filesystem::path& root = TempDir();
  const std::filesystem::path left_dir = root / "left";
  std::error_code ec;
  std::filesystem::remove_all(left_dir, ec);
  std::filesystem::create_directories(left_dir);
  const std::filesystem::path frame = left_dir / (std::string("0") + kExt[data[0] % 4]);
  sfrt::fuzz::WriteFileOrDie(frame,
                             std::string_view(reinterpret_cast<const char*>(data + 1), size - 1));
  const auto policy = (data[0] & 4) != 0 ? sfrt::camera::BadFramePolicy::kStop
                                         : sfrt::camera::BadFramePolicy::kSkip;
  if ((data[0] & 8) != 0) {
    ReadAll((left_dir / "*").string(), (root / "right/*.ppm").string(), policy);
  } else {
    ReadAll(left_dir.string(), (root / "right").string(), policy);
  }
  return 0;
}
