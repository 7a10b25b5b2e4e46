// Fuzz target: the deployment-profile parser (sfrt::config::LoadProfileFromString, what
// `sfrt config check` and `sfrt run --config` use): YAML syntax, every section's keys, values and
// combinations, and the file checks the profile triggers (calibration readers, model loader,
// replay globs).
// The input is the profile text. It is named <tmp>/firmware-cfg/profile.yaml, in a private
// temporary directory laid out like the repository around firmware-cfg/, so the shipped profiles
// (the seeds) find their relative files: the two calibration files (one valid Kalibr camchain),
// the demo frames (empty files: only globbed) and the model (an empty file: the loader rejects it,
// the model loader has its own targets).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include "config/profile.h"

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

void WriteFile(const std::filesystem::path& path, std::string_view content) {
  std::filesystem::create_directories(path.parent_path());
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr || std::fwrite(content.data(), 1, content.size(), f) != content.size() ||
      std::fclose(f) != 0) {
    std::perror(path.c_str());
    std::abort();
  }
}

const std::filesystem::path& TempDir() {
  static const std::filesystem::path dir = [] {
    std::string tmpl =
        (std::filesystem::temp_directory_path() / "sfrt-fuzz-profile-XXXXXX").string();
    if (::mkdtemp(tmpl.data()) == nullptr) {
      std::perror("mkdtemp");
      std::abort();
    }
    const std::filesystem::path root(tmpl);
    WriteFile(root / "firmware-cfg/calib/usb-stereo-640x480.camchain.yaml", kCamchain);
    WriteFile(root / "firmware-cfg/calib/sbs-stereo-1280x480.camchain.yaml", kCamchain);
    for (const char* name : {"left0.png", "left1.png", "right0.png", "right1.png"}) {
      WriteFile(root / "tools/demo/frames" / name, "");
    }
    WriteFile(root / "tools/demo/sceneednet-w16-demo.sfrt", "");
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(TempDir(), ec);
    });
    return root;
  }();
  return dir;
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
