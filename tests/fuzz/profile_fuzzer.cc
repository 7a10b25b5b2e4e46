// Fuzz target: the deployment-profile parser (sfrt::config::LoadProfileFromString, what
// `sfrt config check` and `sfrt run --config` use): YAML syntax, every section's keys, values and
// combinations, and the file checks the profile triggers (calibration readers, model loader,
// replay globs).
// The input is the profile text. It is named <tmp>/firmware-cfg/profile.yaml, in a private
// temporary directory laid out like the repository around firmware-cfg/, so the shipped profiles
// (the seeds) find their relative files: the two calibration files (one valid Kalibr camchain),
// the demo frames (empty files: only globbed) and the model (an empty file: the loader rejects it,
// the model loader has its own targets).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include "fuzz/scratch_dir.h"
#include "sfrt/config/profile.h"

namespace {

constexpr std::string_view kCamchain = R"(cam0:
  camera_model: pinhole
  intrinsics: [612.0, 612.0, 319.5, 239.5]
  distortion_model: radtan
  distortion_coeffs: [-0.05, 0.01, 0.0, 0.0]
  resolution: [640, 480]
cam1:
  camera_model: pinhole
  intrinsics: [610.0, 610.0, 321.0, 240.5]
  distortion_model: radtan
  distortion_coeffs: [-0.048, 0.012, 0.0, 0.0]
  resolution: [640, 480]
  T_cn_cnm1:
  - [1.0, 0.0, 0.0, -0.06]
  - [0.0, 1.0, 0.0, 0.0]
  - [0.0, 0.0, 1.0, 0.0]
  - [0.0, 0.0, 0.0, 1.0]
)";

// Laid out like the repository around firmware-cfg/ (see the top of this file).
const std::filesystem::path& TempDir() {
  return sfrt::fuzz::ScratchDir("sfrt-fuzz-profile", [](const std::filesystem::path& root) {
    using sfrt::fuzz::WriteFileOrDie;
    WriteFileOrDie(root / "firmware-cfg/calib/usb-stereo-640x480.camchain.yaml", kCamchain);
    WriteFileOrDie(root / "firmware-cfg/calib/sbs-stereo-1280x480.camchain.yaml", kCamchain);
    for (const char* name : {"left0.png", "left1.png", "right0.png", "right1.png"}) {
      WriteFileOrDie(root / "tools/demo/frames" / name, "");
    }
    WriteFileOrDie(root / "tools/demo/sceneednet-w16-demo.sfrt", "");
  });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = (TempDir() / "firmware-cfg/profile.yaml").string();
  const std::string yaml(reinterpret_cast<const char*>(data), size);
  sfrt::config::ValidationReport report;
  auto profile = sfrt::config::LoadProfileFromString(yaml, path, &report);
  if (profile.ok() != report.ok()) {
    std::fprintf(stderr, "LoadProfileFromString status and report disagree\n");
    std::abort();
  }
  for (const auto& d : report.errors) (void)d.ToString();
  if (profile.ok()) (void)sfrt::config::FormatProfileSummary(*profile);
  return 0;
}
