#include "sfrt/pipeline/io/npy.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace sfrt::io {
namespace {

namespace fs = std::filesystem;

class NpyTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(::testing::TempDir()) /
           (std::string("sfrt_npy_") + info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

// Builds .npy bytes with a hand-written header (version 1.0 unless told otherwise).
std::string MakeNpy(const std::string& dict, const std::vector<float>& data, int major = 1,
                    int minor = 0) {
  std::string header = dict;
  const size_t prefix = major == 1 ? 10 : 12;
  while ((prefix + header.size() + 1) % 64 != 0) header.push_back(' ');
  header.push_back('\n');
  std::string out = "\x93NUMPY";
  out.push_back(static_cast<char>(major));
  out.push_back(static_cast<char>(minor));
  for (size_t i = 0; i < prefix - 8; ++i) {
    out.push_back(static_cast<char>((header.size() >> (8 * i)) & 0xff));
  }
  out += header;
  out.append(reinterpret_cast<const char*>(data.data()), data.size() * sizeof(float));
  return out;
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST_F(NpyTest, RoundTripsThreeDimensionsBitExactly) {
  const std::vector<int64_t> shape = {2, 3, 4};
  std::vector<float> data(24);
  for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<float>(i) * 0.25f - 3.0f;
  data[5] = std::numeric_limits<float>::quiet_NaN();
  data[6] = -std::numeric_limits<float>::infinity();
  data[7] = std::numeric_limits<float>::denorm_min();
  ASSERT_TRUE(WriteNpy(Path("a.npy"), shape, data).ok());

  Result<NpyArray> read = ReadNpy(Path("a.npy"));
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(read->shape, shape);
  EXPECT_EQ(read->ShapeString(), "(2, 3, 4)");
  ASSERT_EQ(read->data.size(), data.size());
  EXPECT_EQ(std::memcmp(read->data.data(), data.data(), data.size() * sizeof(float)), 0);
}

TEST_F(NpyTest, WritesVersion1HeaderAlignedTo64Bytes) {
  const std::vector<int64_t> shape = {5};
  const std::vector<float> data = {1, 2, 3, 4, 5};
  ASSERT_TRUE(WriteNpy(Path("v.npy"), shape, data).ok());
  const std::string bytes = ReadBytes(Path("v.npy"));
  ASSERT_GE(bytes.size(), 10u);
  EXPECT_EQ(bytes.substr(0, 6), "\x93NUMPY");
  EXPECT_EQ(bytes[6], 1);
  EXPECT_EQ(bytes[7], 0);
  const size_t header_len =
      static_cast<unsigned char>(bytes[8]) | (static_cast<unsigned char>(bytes[9]) << 8);
  EXPECT_EQ((10 + header_len) % 64, 0u);
  EXPECT_EQ(bytes[10 + header_len - 1], '\n');
  const std::string header = bytes.substr(10, header_len);
  EXPECT_NE(header.find("'descr': '<f4'"), std::string::npos) << header;
  EXPECT_NE(header.find("'fortran_order': False"), std::string::npos) << header;
  EXPECT_NE(header.find("'shape': (5,)"), std::string::npos) << header;
  EXPECT_EQ(bytes.size(), 10 + header_len + 5 * sizeof(float));
}

TEST_F(NpyTest, ZeroDimensionalAndEmptyArrays) {
  {
    const std::vector<int64_t> shape = {};
    const std::vector<float> data = {42.0f};
    ASSERT_TRUE(WriteNpy(Path("scalar.npy"), shape, data).ok());
    Result<NpyArray> read = ReadNpy(Path("scalar.npy"));
    ASSERT_TRUE(read.ok()) << read.message();
    EXPECT_TRUE(read->shape.empty());
    EXPECT_EQ(read->ShapeString(), "()");
    ASSERT_EQ(read->data.size(), 1u);
    EXPECT_EQ(read->data[0], 42.0f);
  }
  {
    const std::vector<int64_t> shape = {0, 3};
    ASSERT_TRUE(WriteNpy(Path("empty.npy"), shape, std::vector<float>{}).ok());
    Result<NpyArray> read = ReadNpy(Path("empty.npy"));
    ASSERT_TRUE(read.ok()) << read.message();
    EXPECT_EQ(read->shape, shape);
    EXPECT_TRUE(read->data.empty());
  }
}

TEST_F(NpyTest, ParsesVersion2AndNumpyStyleVariations) {
  const std::vector<float> data = {1.5f, -2.5f};
  Result<NpyArray> v2 = ParseNpy(
      MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (1, 2), }", data, 2), "v2.npy");
  ASSERT_TRUE(v2.ok()) << v2.message();
  EXPECT_EQ(v2->shape, (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(v2->data, data);

  // Double quotes, other key order, no trailing comma, Python 2 long suffix.
  Result<NpyArray> varied = ParseNpy(
      MakeNpy("{\"shape\": (2L,),\"fortran_order\":False,  \"descr\":\"<f4\"}", data), "q.npy");
  ASSERT_TRUE(varied.ok()) << varied.message();
  EXPECT_EQ(varied->shape, (std::vector<int64_t>{2}));
}

// Expects parsing `bytes` to fail with a message containing every one of `parts`.
void ExpectRejected(const std::string& bytes, const std::vector<std::string>& parts) {
  Result<NpyArray> r = ParseNpy(bytes, "input.npy");
  ASSERT_FALSE(r.ok());
  for (const std::string& part : parts) {
    EXPECT_NE(r.message().find(part), std::string::npos)
        << "message '" << r.message() << "' lacks '" << part << "'";
  }
  EXPECT_EQ(r.message().find('\n'), std::string::npos) << "message must be one line";
}

TEST(NpyReject, FortranOrder) {
  ExpectRejected(
      MakeNpy("{'descr': '<f4', 'fortran_order': True, 'shape': (2, 2), }", std::vector<float>(4)),
      {"input.npy", "fortran_order"});
}

TEST(NpyReject, OtherDtypes) {
  ExpectRejected(
      MakeNpy("{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }", std::vector<float>(4)),
      {"input.npy", "descr", "'<f8'", "<f4"});
  ExpectRejected(
      MakeNpy("{'descr': '>f4', 'fortran_order': False, 'shape': (2,), }", std::vector<float>(2)),
      {"input.npy", "descr", "'>f4'", "big-endian"});
  ExpectRejected(
      MakeNpy("{'descr': '|u1', 'fortran_order': False, 'shape': (8,), }", std::vector<float>(2)),
      {"input.npy", "'|u1'"});
}

TEST(NpyReject, BadMagicAndVersion) {
  ExpectRejected("PK\x03\x04 not numpy at all", {"input.npy", "not a .npy file"});
  ExpectRejected(MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (1,), }",
                         std::vector<float>(1), 3, 0),
                 {"input.npy", "version 3.0", "1.0, 2.0"});
}

TEST(NpyReject, BadHeaderFields) {
  const std::vector<float> two(2);
  ExpectRejected(MakeNpy("{'descr': '<f4', 'fortran_order': False, }", two),
                 {"input.npy", "'shape'"});
  ExpectRejected(MakeNpy("{'descr': '<f4', 'shape': (2,), }", two),
                 {"input.npy", "'fortran_order'"});
  ExpectRejected(MakeNpy("{'fortran_order': False, 'shape': (2,), }", two),
                 {"input.npy", "'descr'"});
  ExpectRejected(
      MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (2,), 'extra': 1, }", two),
      {"input.npy", "unexpected field 'extra'"});
  ExpectRejected(MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (2, x), }", two),
                 {"input.npy", "'shape'"});
  ExpectRejected(MakeNpy("{'descr': '<f4', 'fortran_order': Maybe, 'shape': (2,), }", two),
                 {"input.npy", "'fortran_order'", "True or False"});
  ExpectRejected(MakeNpy("['descr', '<f4']", two), {"input.npy", "not a Python dict"});
  ExpectRejected(MakeNpy("{'descr': '<f4', 'descr': '<f4', 'fortran_order': False, "
                         "'shape': (2,), }",
                         two),
                 {"input.npy", "duplicate field 'descr'"});
}

TEST(NpyReject, DataSizeMismatch) {
  ExpectRejected(MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (3, 4), }",
                         std::vector<float>(11)),
                 {"input.npy", "(3, 4)", "48 bytes", "44", "truncated"});
  ExpectRejected(
      MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }", std::vector<float>(3)),
      {"input.npy", "(2,)", "8 bytes", "12"});
  std::string short_header =
      MakeNpy("{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }", std::vector<float>(2));
  ExpectRejected(short_header.substr(0, 30), {"input.npy", "truncated .npy header"});
}

TEST_F(NpyTest, ReadErrorsNameTheFile) {
  Result<NpyArray> missing = ReadNpy(Path("missing.npy"));
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find("missing.npy"), std::string::npos) << missing.message();
}

TEST_F(NpyTest, WriteRejectsWrongElementCount) {
  const std::vector<int64_t> shape = {2, 2};
  Status s = WriteNpy(Path("bad.npy"), shape, std::vector<float>(3));
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("bad.npy"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("4 elements"), std::string::npos) << s.message();
  EXPECT_FALSE(fs::exists(Path("bad.npy")));
}

TEST_F(NpyTest, WritesAtomicallyAndLeavesNoTemporaryFiles) {
  const std::vector<int64_t> shape = {2};
  ASSERT_TRUE(WriteNpy(Path("x.npy"), shape, std::vector<float>{1, 2}).ok());
  ASSERT_TRUE(WriteNpy(Path("x.npy"), shape, std::vector<float>{3, 4}).ok());  // replaces
  Result<NpyArray> read = ReadNpy(Path("x.npy"));
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(read->data, (std::vector<float>{3, 4}));
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) {
    ++files;
    EXPECT_EQ(entry.path().filename(), "x.npy");
  }
  EXPECT_EQ(files, 1);

  // A directory that does not exist: the error names the file and nothing is created.
  const std::string nowhere = Path("no/such/dir/y.npy");
  Status s = WriteNpy(nowhere, shape, std::vector<float>{1, 2});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find(nowhere), std::string::npos) << s.message();
  EXPECT_FALSE(fs::exists(nowhere));
}

}  // namespace
}  // namespace sfrt::io
