// ReadImageFile / PeekImageHeader (sfrt/camera/image_file.h): the size an image declares is read
// from its header and checked before OpenCV allocates for it.
#include "sfrt/camera/image_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

namespace sfrt::camera {
namespace {

namespace fs = std::filesystem;

std::string Bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void Write(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

class ImageFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sfrt_image_file_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

// Every format the reader takes, written by OpenCV at 37x21: the header gives that size and the
// file decodes to it.
TEST_F(ImageFileTest, EveryFormatItTakesGivesItsSizeFromTheHeaderAndDecodes) {
  cv::Mat img(21, 37, CV_8UC3);
  cv::randu(img, 0, 255);
  const std::vector<std::pair<std::string, std::string>> formats = {
      {".png", "PNG"}, {".jpg", "JPEG"},  {".ppm", "PNM"}, {".pgm", "PNM"},
      {".bmp", "BMP"}, {".webp", "WebP"}, {".tif", "TIFF"}};
  for (const auto& [ext, format] : formats) {
    SCOPED_TRACE(ext);
    const fs::path p = dir_ / ("img" + ext);
    cv::Mat grey;
    cv::extractChannel(img, grey, 0);
    ASSERT_TRUE(cv::imwrite(p.string(), ext == ".pgm" ? grey : img));
    const std::string bytes = Bytes(p);
    Result<ImageHeader> h = PeekImageHeader(bytes, bytes.size());
    ASSERT_TRUE(h.ok()) << h.message();
    EXPECT_EQ(h->format, format);
    EXPECT_EQ(h->width, 37);
    EXPECT_EQ(h->height, 21);
    cv::Mat got;
    EXPECT_EQ(ReadImageFile(p.string(), cv::IMREAD_COLOR, &got), "");
    EXPECT_EQ(got.cols, 37);
    EXPECT_EQ(got.rows, 21);
  }
}

// fuzz_image (libFuzzer out-of-memory: cv::imread asked for 2,560,625,628 bytes): a 25-byte PBM
// header claiming 42242x20206 pixels (with a byte 0xEE where whitespace belongs, which OpenCV
// passes over) is refused before OpenCV sees it; so is the same claim with proper whitespace.
TEST_F(ImageFileTest, FuzzReproducerPbmClaimingGigabytesIsRefusedBeforeDecoding) {
  const fs::path p =
      fs::path(SFRT_SOURCE_DIR) / "tests/fuzz/regression/image/oom-pbm-2-5-gb-in-25-bytes";
  const std::string bytes = Bytes(p);
  // The file is the fuzzer's input: a selector byte, then the frame.
  ASSERT_EQ(bytes.size(), 25u);
  const fs::path frame = dir_ / "frame.png";
  Write(frame, bytes.substr(1));
  cv::Mat got;
  const std::string why = ReadImageFile(frame.string(), cv::IMREAD_COLOR, &got);
  EXPECT_EQ(why, "could not be decoded: it is a PNM (P4) with a damaged header");
  EXPECT_TRUE(got.empty());
  Write(frame, "P4\n42242 20206\n" + std::string(9, '\xff'));
  EXPECT_EQ(ReadImageFile(frame.string(), cv::IMREAD_COLOR, &got),
            "could not be decoded: it is a PNM declaring 42242x20206 pixels, more than the 64 Mpx "
            "(8192x8192) an image may have");
  // Under the limit, a raw bitmap whose data the file cannot hold.
  Write(frame, "P4\n4000 3000\n" + std::string(9, '\xff'));
  EXPECT_EQ(ReadImageFile(frame.string(), cv::IMREAD_COLOR, &got),
            "could not be decoded: it is a PNM (P4) declaring 4000x3000 pixels, 1500000 bytes of "
            "pixel data, in a file of 22 bytes");
}

// A PNG whose IHDR claims 10000x10000 is refused by the pixel limit, naming it.
TEST_F(ImageFileTest, ImageOverTheLimitIsRefusedNamingTheLimit) {
  cv::Mat img(4, 4, CV_8UC3, cv::Scalar(1, 2, 3));
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", img, png));
  std::string bytes(png.begin(), png.end());
  for (int at : {16, 20}) {  // width, height: 10000 big-endian
    bytes[at] = 0;
    bytes[at + 1] = 0;
    bytes[at + 2] = static_cast<char>(10000 >> 8);
    bytes[at + 3] = static_cast<char>(10000 & 0xFF);
  }
  Result<ImageHeader> h = PeekImageHeader(bytes, bytes.size());
  ASSERT_FALSE(h.ok());
  EXPECT_EQ(h.message(),
            "is a PNG declaring 10000x10000 pixels, more than the 64 Mpx (8192x8192) an image "
            "may have");
}

// Content no decoder here reads is refused whatever the name says; a missing file says so.
TEST_F(ImageFileTest, OtherContentAndMissingFilesAreRefusedWithTheReason) {
  Write(dir_ / "text.png", "not an image at all\n");
  cv::Mat got;
  EXPECT_EQ(ReadImageFile((dir_ / "text.png").string(), cv::IMREAD_COLOR, &got),
            "could not be decoded: it is not an image this reader decodes (PNG, JPEG, PNM P1-P6, "
            "BMP, WebP, TIFF)");
  EXPECT_EQ(ReadImageFile((dir_ / "absent.png").string(), cv::IMREAD_COLOR, &got), "missing");
  // A raw PPM whose pixel data is cut short is refused from its header.
  Write(dir_ / "short.ppm", "P6\n# comment\n64 48\n255\n" + std::string(100, '\x7f'));
  EXPECT_EQ(ReadImageFile((dir_ / "short.ppm").string(), cv::IMREAD_COLOR, &got),
            "could not be decoded: it is a PNM (P6) declaring 64x48 pixels, 9216 bytes of pixel "
            "data, in a file of 123 bytes");
}

// What the header says about samples: grey and 16-bit files are told apart without decoding.
TEST_F(ImageFileTest, HeaderTellsGreyAndSixteenBitImagesApartWithoutDecoding) {
  struct Case {
    std::string name;
    cv::Mat image;
    std::string want;
  };
  const std::vector<Case> cases = {
      {"colour.png", cv::Mat(8, 8, CV_8UC3, cv::Scalar(1, 2, 3)), ""},
      {"grey.png", cv::Mat(8, 8, CV_8UC1, cv::Scalar(9)), "grayscale"},
      {"deep.png", cv::Mat(8, 8, CV_16UC3, cv::Scalar(900)), "16-bit"},
      {"grey16.pgm", cv::Mat(8, 8, CV_16UC1, cv::Scalar(900)), "grayscale, 16-bit"},
      {"grey.jpg", cv::Mat(8, 8, CV_8UC1, cv::Scalar(9)), "grayscale"}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    ASSERT_TRUE(cv::imwrite((dir_ / c.name).string(), c.image));
    Result<ImageHeader> h = ReadImageHeader((dir_ / c.name).string());
    ASSERT_TRUE(h.ok()) << h.message();
    EXPECT_EQ(NotEightBitColour(*h), c.want);
  }
}

// fuzz_image (UBSan: signed overflow computing a BMP's pixel data size): a BMP header declaring
// 2147483647 x 2147483647 pixels is refused by the pixel limit before any size arithmetic.
TEST_F(ImageFileTest, BmpDeclaringHugeDimensionsIsRefusedWithoutOverflow) {
  std::string bmp(54, '\0');
  bmp[0] = 'B';
  bmp[1] = 'M';
  auto put = [&bmp](size_t at, uint32_t v, int n) {
    for (int i = 0; i < n; ++i) bmp[at + i] = static_cast<char>((v >> (8 * i)) & 0xFF);
  };
  put(14, 40, 4);          // BITMAPINFOHEADER
  put(18, 0x7FFFFFFF, 4);  // width
  put(22, 0x7FFFFFFF, 4);  // height
  put(28, 64, 2);          // bits per pixel
  Result<ImageHeader> h = PeekImageHeader(bmp, bmp.size());
  ASSERT_FALSE(h.ok());
  EXPECT_EQ(h.message(),
            "is a BMP declaring 2147483647x2147483647 pixels, more than the 64 Mpx (8192x8192) "
            "an image may have");
}

}  // namespace
}  // namespace sfrt::camera
