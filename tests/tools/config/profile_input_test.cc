// Bounded profile input (issue 15, item 9): the size cap before parsing, the cap on printed
// errors, a tab in the indentation, and binary files. Every fixture is generated here.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "config/limits.h"
#include "config/profile.h"

namespace sfrt::config {
namespace {

namespace fs = std::filesystem;

// A file under a fresh per-process directory in the system temporary directory.
std::string WriteFixture(const std::string& name, const std::string& bytes) {
  const fs::path dir =
      fs::temp_directory_path() / ("sfrt_profile_input_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path path = dir / name;
  std::ofstream(path, std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return path.string();
}

TEST(ProfileInput, ProfileOverOneMegabyteIsRefusedWithItsSize) {
  // Valid YAML, so a refusal can only come from the size: 1.5 MiB of comment lines.
  std::string yaml = "version: 1\n";
  while (yaml.size() < kMaxProfileBytes * 3 / 2) yaml += "# " + std::string(78, 'x') + "\n";
  const std::string path = WriteFixture("big.yaml", yaml);
  ValidationReport report;
  Result<DeploymentProfile> p = LoadProfile(path, &report);
  ASSERT_FALSE(p.ok());
  ASSERT_EQ(report.errors.size(), 1u);
  EXPECT_EQ(report.errors[0].ToString(), path + ": the profile is " + std::to_string(yaml.size()) +
                                             " bytes; the limit is 1048576 bytes (1 MiB); "
                                             "nothing was parsed");
  // The in-memory variant has the same cap.
  ValidationReport mem;
  EXPECT_FALSE(LoadProfileFromString(yaml, "mem.yaml", &mem).ok());
  ASSERT_EQ(mem.errors.size(), 1u);
  EXPECT_NE(mem.errors[0].problem.find(std::to_string(yaml.size()) + " bytes"), std::string::npos);
}

TEST(ProfileInput, ProfileJustUnderTheCapIsParsed) {
  std::string yaml = "version: 1\n";
  while (yaml.size() + 81 < kMaxProfileBytes) yaml += "# " + std::string(78, 'x') + "\n";
  ValidationReport report;
  (void)LoadProfile(WriteFixture("under.yaml", yaml), &report);
  for (const Diagnostic& d : report.errors) {
    EXPECT_EQ(d.problem.find("limit"), std::string::npos) << d.ToString();
  }
}

TEST(ProfileInput, ProfileErrorsAreCappedAtFiftyWithACount) {
  std::string yaml = "version: 1\n";
  for (int i = 0; i < 120; ++i) yaml += "unknown_key_" + std::to_string(i) + ": 1\n";
  ValidationReport report;
  ASSERT_FALSE(LoadProfileFromString(yaml, "many.yaml", &report).ok());
  ASSERT_GT(report.errors.size(), kMaxPrintedErrors);
  std::ostringstream out;
  PrintErrors(report.errors, out);
  std::istringstream lines(out.str());
  std::string line;
  int count = 0;
  std::string last;
  while (std::getline(lines, line)) {
    ++count;
    last = line;
  }
  EXPECT_EQ(count, 51);
  const size_t more = report.errors.size() - 50;
  EXPECT_EQ(last, "... and " + std::to_string(more) + " more errors (the first 50 are shown)");
  std::ostringstream few;
  PrintErrors({report.errors[0], report.errors[1]}, few);
  EXPECT_EQ(few.str().find("more error"), std::string::npos);
}

TEST(ProfileInput, ProfileWithATabInIndentationSaysTab) {
  const std::string yaml = "version: 1\nmodel:\n  file: m.sfrt\n\tinput_height: 96\n";
  ValidationReport report;
  ASSERT_FALSE(LoadProfileFromString(yaml, "tab.yaml", &report).ok());
  ASSERT_EQ(report.errors.size(), 1u);
  EXPECT_EQ(report.errors[0].ToString(),
            "tab.yaml:4:1: a tab in the indentation; YAML indents with spaces only");
  ValidationReport after_spaces;
  ASSERT_FALSE(
      LoadProfileFromString("version: 1\nmodel:\n  \tfile: m.sfrt\n", "t2.yaml", &after_spaces)
          .ok());
  ASSERT_EQ(after_spaces.errors.size(), 1u);
  EXPECT_EQ(after_spaces.errors[0].ToString(),
            "t2.yaml:3:3: a tab in the indentation; YAML indents with spaces only");
}

TEST(ProfileInput, BinaryProfileIsCalledBinaryNotEmpty) {
  const std::string nul("\0\0\0\x01\x02", 5);
  ValidationReport report;
  const std::string path = WriteFixture("nul.yaml", nul);
  ASSERT_FALSE(LoadProfile(path, &report).ok());
  ASSERT_EQ(report.errors.size(), 1u);
  EXPECT_EQ(report.errors[0].ToString(),
            path + ": a binary file, not a YAML profile (a NUL byte at line 1, column 1)");
  ValidationReport utf8;
  ASSERT_FALSE(LoadProfileFromString("version: 1\nname: \xff\xfe\n", "u.yaml", &utf8).ok());
  ASSERT_EQ(utf8.errors.size(), 1u);
  EXPECT_EQ(utf8.errors[0].ToString(),
            "u.yaml: a binary file, not a YAML profile (invalid UTF-8 at line 2, column 7)");
  // Valid UTF-8 beyond ASCII is text.
  ValidationReport text;
  (void)LoadProfileFromString("version: 1\nname: caf\xc3\xa9\n", "ok.yaml", &text);
  for (const Diagnostic& d : text.errors) {
    EXPECT_EQ(d.problem.find("binary"), std::string::npos) << d.ToString();
  }
}

}  // namespace
}  // namespace sfrt::config
