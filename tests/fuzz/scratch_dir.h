// Files for fuzz targets (and tests) whose parsers take paths (calibration, image, profile): the
// process's private scratch directory and an abort-on-failure writer. A fuzz target cannot
// report errors, so both abort with the reason (perror) where they cannot do their job.
#pragma once

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

namespace sfrt::fuzz {

// Writes `content` to `path`, creating its parent directories.
inline void WriteFileOrDie(const std::filesystem::path& path, std::string_view content) {
  std::error_code ec;
  std::filesystem::create_directories(path.parent_path(), ec);  // fopen reports what failed
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr || std::fwrite(content.data(), 1, content.size(), f) != content.size() ||
      std::fclose(f) != 0) {
    std::perror(path.c_str());
    std::abort();
  }
}

// The process's scratch directory, <temp>/<prefix>-XXXXXX (mkdtemp: private, mode 0700):
// made on the first call, which also runs `populate` on it, and removed with its contents at
// exit. Later calls return the same directory (their arguments are not used): one per target.
inline const std::filesystem::path& ScratchDir(
    const char* prefix, void (*populate)(const std::filesystem::path& dir) = nullptr) {
  // Never destroyed: the exit handler, registered before this initialisation completes, would
  // run after the destructor of a static path object.
  static const std::filesystem::path* const dir = [&] {
    std::string tmpl =
        (std::filesystem::temp_directory_path() / (std::string(prefix) + "-XXXXXX")).string();
    if (::mkdtemp(tmpl.data()) == nullptr) {
      std::perror("mkdtemp");
      std::abort();
    }
    const auto* root = new std::filesystem::path(tmpl);
    if (populate != nullptr) populate(*root);
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(ScratchDir(""), ec);
    });
    return root;
  }();
  return *dir;
}

}  // namespace sfrt::fuzz
