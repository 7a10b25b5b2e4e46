// Bounded profile input (issue 15, item 9): the size cap before parsing, the cap on printed
// errors, a tab in the indentation, and binary files. Every fixture is generated here.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "fuzz/scratch_dir.h"
#include "sfrt/config/limits.h"
#include "sfrt/config/profile.h"

namespace sfrt::config {
namespace {

namespace fs = std::filesystem;

// A file under the process's scratch directory (removed with it at exit).
std::string WriteFixture(const std::string& name, const std::string& bytes) {
  const fs::path path = fuzz::ScratchDir("sfrt_profile_input") / name;
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

TEST(Limits, TheReadmeTableMatchesTheCode) {
  std::ifstream in(std::string(SFRT_SOURCE_DIR) + "/firmware-cfg/README.md");
  std::stringstream text;
  text << in.rdbuf();
  const std::string doc = text.str();
  const std::string begin =
      "<!-- limits table: generated from firmware-cfg/include/sfrt/config/limits.h";
  const size_t start = doc.find(begin);
  const size_t end = doc.find("<!-- end of limits table -->");
  ASSERT_NE(start, std::string::npos);
  ASSERT_NE(end, std::string::npos);
  std::istringstream table(doc.substr(start, end - start));
  std::vector<std::string> rows;
  std::string line;
  while (std::getline(table, line)) {
    if (line.rfind("| ", 0) == 0 && line.rfind("| limit ", 0) != 0) rows.push_back(line);
  }
  const std::vector<std::string> want = LimitsMarkdownRows();
  EXPECT_EQ(rows, want);
}

TEST(Limits, ThreadsZeroIsOnePerCpuAndTheSameTextEverywhere) {
  EXPECT_GE(ResolveThreads(0), 1);
  EXPECT_EQ(ResolveThreads(3), 3);
  EXPECT_EQ(CheckRange(kThreads, "--threads", 1000),
            "--threads: 1000 is outside the threads limits 0..256 (0: one per CPU)");
  EXPECT_EQ(CheckRange(kThreads, "--threads", 0), "");
  EXPECT_EQ(CheckSize(kInputSide, "--size", 5000, 96),
            "--size: 5000x96 (HxW) is outside the input size limits 16..4096 pixels per side");
  // A profile refuses the same values with the same range.
  ValidationReport report;
  (void)LoadProfileFromString(
      "version: 1\nmodel:\n  file: m.sfrt\n  input_height: 5000\n  input_width: 96\n"
      "stages:\n  infer:\n    threads: 1000\n",
      "limits.yaml", &report);
  bool size = false, threads = false;
  for (const Diagnostic& d : report.errors) {
    if (d.key == "model.input_height") {
      size = true;
      EXPECT_EQ(d.allowed, "integer 16..4096 pixels per side");
    }
    if (d.key == "stages.infer.threads") {
      threads = true;
      EXPECT_EQ(d.allowed, "integer 0..256 (0: one per CPU)");
    }
  }
  EXPECT_TRUE(size && threads);
}

}  // namespace
}  // namespace sfrt::config
