#include "sfrt/pipeline/io/pfm.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace sfrt::io {
namespace {

namespace fs = std::filesystem;

class PfmTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(::testing::TempDir()) /
           (std::string("sfrt_pfm_") + info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

std::vector<float> Ramp(size_t n) {
  std::vector<float> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = static_cast<float>(i) * 0.5f - 7.0f;
  return v;
}

std::string FloatBytes(const std::vector<float>& v, bool big_endian = false) {
  std::string out(v.size() * 4, '\0');
  std::memcpy(out.data(), v.data(), out.size());
  if (big_endian) {
    for (size_t i = 0; i < out.size(); i += 4) {
      std::swap(out[i], out[i + 3]);
      std::swap(out[i + 1], out[i + 2]);
    }
  }
  return out;
}

// Rows of an HWC image in bottom-to-top order, as a PFM stores them.
std::vector<float> FlipRows(const std::vector<float>& image, int height, int row_floats) {
  std::vector<float> out;
  for (int y = height - 1; y >= 0; --y) {
    out.insert(out.end(), image.begin() + y * row_floats, image.begin() + (y + 1) * row_floats);
  }
  return out;
}

TEST_F(PfmTest, WritesThreeChannelLittleEndianBottomToTop) {
  const int h = 2, w = 4;
  const std::vector<float> image = Ramp(h * w * 3);
  ASSERT_TRUE(WritePfm(Path("flow.pfm"), image, h, w).ok());

  std::ifstream in(Path("flow.pfm"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string header = "PF\n4 2\n-1.0\n";
  ASSERT_EQ(bytes.size(), header.size() + image.size() * 4);
  EXPECT_EQ(bytes.substr(0, header.size()), header);
  EXPECT_EQ(bytes.substr(header.size()), FloatBytes(FlipRows(image, h, w * 3)));

  Result<PfmImage> read = ReadPfm(Path("flow.pfm"));
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(read->height, h);
  EXPECT_EQ(read->width, w);
  EXPECT_EQ(read->channels, 3);
  EXPECT_EQ(read->data, image);
}

TEST_F(PfmTest, RoundTripsOneChannel) {
  const int h = 3, w = 5;
  const std::vector<float> image = Ramp(h * w);
  ASSERT_TRUE(WritePfm(Path("disp.pfm"), image, h, w, 1).ok());
  Result<PfmImage> read = ReadPfm(Path("disp.pfm"));
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(read->channels, 1);
  EXPECT_EQ(read->height, h);
  EXPECT_EQ(read->width, w);
  EXPECT_EQ(read->data, image);
}

// The Scene Flow datasets end every header line with a space: "Pf \n960 540 \n-1.0\n".
TEST(PfmParse, SceneFlowHeaderWithTrailingSpaces) {
  const int h = 540, w = 960;
  const std::vector<float> image = Ramp(static_cast<size_t>(h) * w);
  const std::string bytes = "Pf \n960 540 \n-1.0\n" + FloatBytes(FlipRows(image, h, w));
  Result<PfmImage> read = ParsePfm(bytes, "0006.pfm");
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(read->channels, 1);
  EXPECT_EQ(read->height, h);
  EXPECT_EQ(read->width, w);
  EXPECT_EQ(read->data, image);

  // Spaces after the scale and Windows line ends are tolerated as well.
  const std::vector<float> small = Ramp(6);
  Result<PfmImage> crlf = ParsePfm("PF\r\n2  1\r\n-1.0 \r\n" + FloatBytes(small), "crlf.pfm");
  ASSERT_TRUE(crlf.ok()) << crlf.message();
  EXPECT_EQ(crlf->data, small);
}

TEST(PfmParse, BigEndianWhenScaleIsPositive) {
  const int h = 2, w = 3;
  const std::vector<float> image = Ramp(h * w * 3);
  const std::string bytes = "PF\n3 2\n1.0\n" + FloatBytes(FlipRows(image, h, w * 3), true);
  Result<PfmImage> read = ParsePfm(bytes, "be.pfm");
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(read->data, image);
}

TEST(PfmParse, DataStartingWithWhitespaceBytesIsNotSkipped) {
  // 0x0a202020 as a float: the first data bytes look like "\n   " and must stay data.
  std::vector<float> image(1);
  const char raw[4] = {'\n', ' ', ' ', ' '};
  std::memcpy(image.data(), raw, 4);
  Result<PfmImage> read = ParsePfm("Pf\n1 1\n-1.0\n" + FloatBytes(image), "ws.pfm");
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(std::memcmp(read->data.data(), raw, 4), 0);
}

void ExpectRejected(const std::string& bytes, const std::vector<std::string>& parts) {
  Result<PfmImage> r = ParsePfm(bytes, "bad.pfm");
  ASSERT_FALSE(r.ok());
  for (const std::string& part : parts) {
    EXPECT_NE(r.message().find(part), std::string::npos)
        << "message '" << r.message() << "' lacks '" << part << "'";
  }
  EXPECT_EQ(r.message().find('\n'), std::string::npos) << "message must be one line";
}

TEST(PfmParse, RejectsBadHeaders) {
  const std::string data = FloatBytes(Ramp(6));
  ExpectRejected("P6\n2 1\n255\n" + data, {"bad.pfm", "identifier", "'P6'"});
  ExpectRejected("PF\nabc 1\n-1.0\n" + data, {"bad.pfm", "width", "'abc'"});
  ExpectRejected("PF\n2 -1\n-1.0\n" + data, {"bad.pfm", "height", "'-1'"});
  ExpectRejected("PF\n2 0\n-1.0\n" + data, {"bad.pfm", "height"});
  ExpectRejected("PF\n2 1\n0\n" + data, {"bad.pfm", "scale", "'0'"});
  ExpectRejected("PF\n2 1\nbig\n" + data, {"bad.pfm", "scale", "'big'"});
  ExpectRejected("PF\n2 1\n-1.0", {"bad.pfm", "newline"});
  ExpectRejected("", {"bad.pfm", "identifier"});
}

TEST(PfmParse, RejectsWrongDataSize) {
  ExpectRejected("PF\n2 1\n-1.0\n" + FloatBytes(Ramp(5)),
                 {"bad.pfm", "2x1", "3 channel", "24 bytes", "20", "truncated"});
  ExpectRejected("Pf\n2 1\n-1.0\n" + FloatBytes(Ramp(3)), {"bad.pfm", "8 bytes", "12"});
}

TEST_F(PfmTest, WriteRejectsBadArguments) {
  Status two_channels = WritePfm(Path("a.pfm"), Ramp(8), 2, 2, 2);
  ASSERT_FALSE(two_channels.ok());
  EXPECT_NE(two_channels.message().find("1 or 3 channels"), std::string::npos);
  Status wrong_count = WritePfm(Path("b.pfm"), Ramp(5), 1, 2, 3);
  ASSERT_FALSE(wrong_count.ok());
  EXPECT_NE(wrong_count.message().find("b.pfm"), std::string::npos) << wrong_count.message();
  EXPECT_FALSE(fs::exists(Path("a.pfm")));
  EXPECT_FALSE(fs::exists(Path("b.pfm")));
}

TEST_F(PfmTest, ReadErrorsNameTheFile) {
  Result<PfmImage> missing = ReadPfm(Path("missing.pfm"));
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find("missing.pfm"), std::string::npos) << missing.message();
}

TEST_F(PfmTest, FailedWriteLeavesExistingFileUntouched) {
  const std::vector<float> image = Ramp(3);
  ASSERT_TRUE(WritePfm(Path("keep.pfm"), image, 1, 1).ok());
  // Writing into a directory that does not exist fails before touching anything else.
  Status s = WritePfm(Path("missing_dir/keep.pfm"), image, 1, 1);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("missing_dir/keep.pfm"), std::string::npos) << s.message();
  Result<PfmImage> read = ReadPfm(Path("keep.pfm"));
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(read->data, image);
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) {
    ++files;
    EXPECT_EQ(entry.path().filename(), "keep.pfm");
  }
  EXPECT_EQ(files, 1);
}

}  // namespace
}  // namespace sfrt::io
