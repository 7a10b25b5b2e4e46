// Helpers shared by the tests that feed crafted Keras HDF5 files to the importer.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <utility>

#include "sfrt/exporter/keras_importer.h"

namespace sfrt::exporter::testing {

inline const std::string kKerasCorpus =
    std::string(SFRT_SOURCE_DIR) + "/tests/fuzz/regression/keras_import/";

inline std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in) << path << " is missing";
  return std::string(std::istreambuf_iterator<char>(in), {});
}

inline void WriteFile(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

// Imports `bytes` from memory and through a file; both must fail with one line that starts with
// the file's name (the label in memory, the path on disk). `check` inspects each message further.
inline void ExpectRejectedBothWays(const std::string& bytes, const std::string& name,
                                   const std::function<void(const std::string&)>& check) {
  SCOPED_TRACE(name);
  const std::string label = "crafted/" + name;
  auto in_memory = ImportKerasH5FromMemory(bytes, label);
  ASSERT_FALSE(in_memory.ok());
  const std::string path = ::testing::TempDir() + "/" + name;
  WriteFile(path, bytes);
  auto from_file = ImportKerasH5(path);
  std::filesystem::remove(path);
  ASSERT_FALSE(from_file.ok());
  for (const auto& [message, prefix] : {std::pair{in_memory.message(), label + ": "},
                                        std::pair{from_file.message(), path + ": "}}) {
    EXPECT_EQ(message.rfind(prefix, 0), 0u) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    check(message);
  }
}

}  // namespace sfrt::exporter::testing
