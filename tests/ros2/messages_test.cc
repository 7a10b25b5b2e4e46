// The ROS 2 messages and their CDR encoding (ros2/src/messages.h, ros2/src/cdr.h): golden bytes
// written out by hand from the CDR rules, alignment, byte order, end padding, every truncation,
// hostile lengths, the names and ros2msg definitions, and allocation (operator new is counted).
// tests/ros2/cdr_oracle_check.mjs compares the same encoder with an independent one.
#include "messages.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <string>
#include <tuple>
#include <vector>

#include "cdr.h"

namespace {

// Every allocation of this program is counted (the replacements below).
std::atomic<size_t> g_allocations{0};
std::atomic<size_t> g_allocated_bytes{0};

void* CountedAllocate(std::size_t size) {
  ++g_allocations;
  g_allocated_bytes += size;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}

}  // namespace

void* operator new(std::size_t size) { return CountedAllocate(size); }
void* operator new[](std::size_t size) { return CountedAllocate(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace sfrt::ros2 {
namespace {

using msg::CameraInfo;
using msg::CompressedImage;
using msg::DiagnosticArray;
using msg::DiagnosticStatus;
using msg::Header;
using msg::Image;
using msg::ImageView;
using msg::KeyValue;
using msg::RegionOfInterest;
using msg::Time;

using Bytes = std::vector<uint8_t>;

// Allocations made while `f` runs.
template <typename F>
size_t AllocationsDuring(F&& f) {
  const size_t before = g_allocations.load();
  f();
  return g_allocations.load() - before;
}

template <typename F>
size_t BytesAllocatedDuring(F&& f) {
  const size_t before = g_allocated_bytes.load();
  f();
  return g_allocated_bytes.load() - before;
}

// The table of type names (and the field paths errors are written with) is built on first use,
// once per process. ctest runs each test in a process of its own, so build it before any test
// counts allocations, as a program does at start-up, whichever test runs first.
class BuildTheNamesFirst : public ::testing::Environment {
 public:
  void SetUp() override { (void)msg::AllMessageNames(); }
};
[[maybe_unused]] ::testing::Environment* const kBuildTheNamesFirst =
    ::testing::AddGlobalTestEnvironment(new BuildTheNamesFirst);

template <typename T>
Bytes EncodeToBytes(const T& message) {
  Bytes out;
  msg::Encode(message, &out);
  return out;
}

Bytes Repeat(size_t n, uint8_t first) {
  Bytes b(n);
  for (size_t i = 0; i < n; ++i) b[i] = static_cast<uint8_t>(first + 7 * i);
  return b;
}

// ---------------------------------------------------------------------------------------------
// One fully set value of each message, odd lengths everywhere so every alignment rule is used.

template <typename T>
T FullSample();

template <>
Time FullSample<Time>() {
  return {-123456789, 999999999};
}
template <>
Header FullSample<Header>() {
  return {{1700000000, 42}, "camera_left_optical"};  // 19 chars: length 20, aligned next
}
template <>
Image FullSample<Image>() {
  return {{{-1, 5}, "cam"}, 3, 5, "rgb8", 1, 15, Repeat(45, 3)};
}
template <>
CompressedImage FullSample<CompressedImage>() {
  return {{{7, 8}, "c"}, "jpeg", Repeat(13, 200)};
}
template <>
RegionOfInterest FullSample<RegionOfInterest>() {
  return {1, 2, 3, 4, true};
}
template <>
CameraInfo FullSample<CameraInfo>() {
  CameraInfo info;
  info.header = {{10, 20}, "optical"};
  info.height = 480;
  info.width = 640;
  info.distortion_model = "plumb_bob";
  info.d = {-0.25, 0.125, 1e-300, -0.0, 3.5};
  for (size_t i = 0; i < 9; ++i) info.k[i] = 1.5 * static_cast<double>(i) - 2;
  for (size_t i = 0; i < 9; ++i) info.r[i] = i % 4 == 0 ? 1.0 : 0.0;
  for (size_t i = 0; i < 12; ++i) info.p[i] = 1e10 / static_cast<double>(i + 1);
  info.binning_x = 2;
  info.binning_y = 3;
  info.roi = {5, 6, 7, 8, true};
  return info;
}
template <>
KeyValue FullSample<KeyValue>() {
  return {"temperature", "41.5 C"};
}
template <>
DiagnosticStatus FullSample<DiagnosticStatus>() {
  return {DiagnosticStatus::kWarn, "sfrt: flow", "late frames", "hw0", {{"a", ""}, {"", "bc"}}};
}
template <>
DiagnosticArray FullSample<DiagnosticArray>() {
  DiagnosticArray array;
  array.header = {{3, 4}, "base_link"};
  array.status.push_back(FullSample<DiagnosticStatus>());
  array.status.push_back({DiagnosticStatus::kStale, "x", "", "", {}});
  array.status.push_back({DiagnosticStatus::kOk, "", "ok", "id", {{"k", "v"}}});
  return array;
}

template <typename T>
class EveryMessage : public ::testing::Test {};
using MessageTypes = ::testing::Types<Time, Header, Image, CompressedImage, RegionOfInterest,
                                      CameraInfo, KeyValue, DiagnosticStatus, DiagnosticArray>;
TYPED_TEST_SUITE(EveryMessage, MessageTypes);

TYPED_TEST(EveryMessage, AFullySetMessageDecodesToItself) {
  const TypeParam sent = FullSample<TypeParam>();
  TypeParam received;
  ASSERT_TRUE(msg::Decode(EncodeToBytes(sent), &received).ok());
  EXPECT_EQ(received, sent);
}

TYPED_TEST(EveryMessage, ADefaultMessageDecodesToItself) {
  // A non-default object first: decoding must overwrite every field, not only grow them.
  TypeParam received = FullSample<TypeParam>();
  const Status status = msg::Decode(EncodeToBytes(TypeParam{}), &received);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(received, TypeParam{});
}

TYPED_TEST(EveryMessage, EveryTruncationIsRefusedNamingTheType) {
  const Bytes whole = EncodeToBytes(FullSample<TypeParam>());
  const std::string type(msg::NamesOf<TypeParam>().ros2_type);
  TypeParam received;
  for (size_t size = 0; size < whole.size(); ++size) {
    // A copy of exactly `size` bytes, so ASan sees any read past it.
    const Bytes cut(whole.begin(), whole.begin() + static_cast<std::ptrdiff_t>(size));
    const Status status = msg::Decode(cut, &received);
    ASSERT_FALSE(status.ok()) << size << " of " << whole.size() << " bytes were accepted";
    EXPECT_EQ(status.message().rfind(type, 0), 0u) << status.message();
  }
}

TYPED_TEST(EveryMessage, CycloneStyleEndPaddingToFourBytesIsAccepted) {
  const TypeParam sent = FullSample<TypeParam>();
  Bytes padded = EncodeToBytes(sent);
  padded.resize((padded.size() + 3) / 4 * 4);  // rmw_cyclonedds' serdata: zeros up to 4k
  TypeParam received;
  ASSERT_TRUE(msg::Decode(padded, &received).ok());
  EXPECT_EQ(received, sent);
}

TYPED_TEST(EveryMessage, FourTrailingBytesAreRefusedAsNotPadding) {
  Bytes longer = EncodeToBytes(FullSample<TypeParam>());
  const size_t end = longer.size();
  longer.resize(end + 4);
  TypeParam received;
  const Status status = msg::Decode(longer, &received);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.message().find("4 bytes follow the message at offset " + std::to_string(end)),
            std::string::npos)
      << status.message();
}

TYPED_TEST(EveryMessage, EncodingReplacesWhatTheVectorHeld) {
  Bytes out(100, 0xee);
  msg::Encode(FullSample<TypeParam>(), &out);
  EXPECT_EQ(out, EncodeToBytes(FullSample<TypeParam>()));
}

TYPED_TEST(EveryMessage, EncodingTwiceAtOneSizeAllocatesNothing) {
  const TypeParam message = FullSample<TypeParam>();
  Bytes out;
  msg::Encode(message, &out);
  const size_t capacity = out.capacity();
  EXPECT_EQ(AllocationsDuring([&] { msg::Encode(message, &out); }), 0u);
  EXPECT_EQ(out.capacity(), capacity);
  EXPECT_EQ(capacity, out.size()) << "the first encode reserves the exact size";
}

TYPED_TEST(EveryMessage, DecodingTwiceAtOneSizeAllocatesNothing) {
  const Bytes bytes = EncodeToBytes(FullSample<TypeParam>());
  TypeParam received;
  ASSERT_TRUE(msg::Decode(bytes, &received).ok());
  Status status;
  EXPECT_EQ(AllocationsDuring([&] { status = msg::Decode(bytes, &received); }), 0u);
  EXPECT_TRUE(status.ok());
}

// ---------------------------------------------------------------------------------------------
// Golden bytes, derived by hand from the rules in cdr.h.

TEST(Header, EncodesToTheBytesTheCdrRulesGive) {
  const Bytes expected = {
      0x00, 0x01, 0x00, 0x00,  // encapsulation: CDR_LE, options 0
      0x01, 0x00, 0x00, 0x00,  // stamp.sec = 1 (int32, body offset 0)
      0x02, 0x00, 0x00, 0x00,  // stamp.nanosec = 2 (uint32, body offset 4)
      0x04, 0x00, 0x00, 0x00,  // frame_id length 4 = "cam" + NUL (body offset 8)
      'c',  'a',  'm',  0x00,  // frame_id bytes and NUL
  };
  EXPECT_EQ(EncodeToBytes(Header{{1, 2}, "cam"}), expected);
  Header decoded;
  ASSERT_TRUE(msg::Decode(expected, &decoded).ok());
  EXPECT_EQ(decoded, (Header{{1, 2}, "cam"}));
}

// An Image whose frame_id ("ab", length 3) and encoding ("mono8", length 6) leave the next
// uint32 unaligned, so padding is needed twice. Offsets in comments are from the byte after the
// encapsulation header, where CDR alignment counts from.
const Bytes kGoldenImage = {
    0x00, 0x01, 0x00, 0x00,  // encapsulation: CDR_LE
    0x01, 0x00, 0x00, 0x00,  //  0: header.stamp.sec = 1
    0x02, 0x00, 0x00, 0x00,  //  4: header.stamp.nanosec = 2
    0x03, 0x00, 0x00, 0x00,  //  8: header.frame_id length 3
    'a',  'b',  0x00,        // 12: "ab" NUL
    0x00,                    // 15: padding, height is a uint32 and 15 % 4 != 0
    0x02, 0x00, 0x00, 0x00,  // 16: height = 2
    0x03, 0x00, 0x00, 0x00,  // 20: width = 3
    0x06, 0x00, 0x00, 0x00,  // 24: encoding length 6
    'm',  'o',  'n',  'o',   // 28: "mono8"
    '8',  0x00,              // 32: ... NUL
    0x00,                    // 34: is_bigendian = 0 (uint8, no alignment)
    0x00,                    // 35: padding before step
    0x03, 0x00, 0x00, 0x00,  // 36: step = 3
    0x06, 0x00, 0x00, 0x00,  // 40: data count 6
    0x01, 0x02, 0x03, 0x04,  // 44: data
    0x05, 0x06,              // 48: ... end of message, no end padding
};

Image GoldenImage() { return {{{1, 2}, "ab"}, 2, 3, "mono8", 0, 3, {1, 2, 3, 4, 5, 6}}; }

TEST(Image, EncodesToTheBytesTheCdrRulesGive) {
  EXPECT_EQ(EncodeToBytes(GoldenImage()), kGoldenImage);
}

TEST(Image, DecodesTheHandWrittenBytes) {
  Image decoded;
  ASSERT_TRUE(msg::Decode(kGoldenImage, &decoded).ok());
  EXPECT_EQ(decoded, GoldenImage());
}

TEST(Image, BigEndianInputDecodesToTheSameImage) {
  const Bytes big_endian = {
      0x00, 0x00, 0x00, 0x00,                                      // encapsulation: CDR_BE
      0x00, 0x00, 0x00, 0x01,                                      // header.stamp.sec = 1
      0x00, 0x00, 0x00, 0x02,                                      // header.stamp.nanosec = 2
      0x00, 0x00, 0x00, 0x03, 'a',  'b',  0x00,                    // header.frame_id "ab"
      0xaa,                                                        // padding (content not checked)
      0x00, 0x00, 0x00, 0x02,                                      // height = 2
      0x00, 0x00, 0x00, 0x03,                                      // width = 3
      0x00, 0x00, 0x00, 0x06, 'm',  'o',  'n',  'o',  '8',  0x00,  // encoding "mono8"
      0x00, 0x00,                                                  // is_bigendian, padding
      0x00, 0x00, 0x00, 0x03,                                      // step = 3
      0x00, 0x00, 0x00, 0x06, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06,  // data
  };
  Image decoded;
  const Status status = msg::Decode(big_endian, &decoded);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(decoded, GoldenImage());
}

TEST(Image, EncodingAViewGivesTheSameBytesAsTheImage) {
  const Image image = GoldenImage();
  ImageView view;
  view.header = {image.header.stamp, image.header.frame_id};
  view.height = image.height;
  view.width = image.width;
  view.encoding = image.encoding;
  view.is_bigendian = image.is_bigendian;
  view.step = image.step;
  view.data = image.data;
  Bytes out;
  msg::Encode(view, &out);
  EXPECT_EQ(out, kGoldenImage);
}

TEST(Image, AViewDecodesWithoutAllocatingAndPointsIntoTheInput) {
  ImageView view;
  Status status;
  EXPECT_EQ(AllocationsDuring([&] { status = msg::DecodeImageView(kGoldenImage, &view); }), 0u);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(view.data.data(), kGoldenImage.data() + 48);
  EXPECT_EQ(view.data.size(), 6u);
  EXPECT_EQ(view.header.frame_id, "ab");
  EXPECT_EQ(static_cast<const void*>(view.header.frame_id.data()), kGoldenImage.data() + 16);
  EXPECT_EQ(view.encoding, "mono8");
  EXPECT_EQ(view.header.stamp, (Time{1, 2}));
  EXPECT_EQ(std::tie(view.height, view.width, view.is_bigendian, view.step),
            std::make_tuple(2u, 3u, uint8_t{0}, 3u));
}

TEST(Image, ADataCountBeyondTheMessageIsRefusedNamingTheFieldOffsetAndBytesLeft) {
  Bytes bytes = kGoldenImage;
  bytes[44] = bytes[45] = bytes[46] = bytes[47] = 0xff;  // data count 4294967295
  Image decoded;
  const Status status = msg::Decode(bytes, &decoded);
  EXPECT_EQ(status.message(),
            "sensor_msgs/msg/Image.data: sequence of 4294967295 bytes at offset 48, only 6 left");
}

TEST(Image, ADataCountBeyondTheMessageAllocatesNothing) {
  Bytes bytes = kGoldenImage;
  bytes[44] = bytes[45] = bytes[46] = bytes[47] = 0xff;
  Image decoded;
  decoded.data.reserve(6);
  Status status;
  // The error message is the only allocation: the count was checked before data was resized.
  EXPECT_LE(BytesAllocatedDuring([&] { status = msg::Decode(bytes, &decoded); }), 1024u);
  EXPECT_FALSE(status.ok());
  EXPECT_EQ(decoded.data.capacity(), 6u);
}

// ---------------------------------------------------------------------------------------------
// The CDR rules, one at a time.

TEST(Cdr, AStringLengthBeyondTheMessageIsRefusedNamingTheField) {
  Bytes bytes = EncodeToBytes(Header{{1, 2}, "cam"});
  bytes[12] = 0x05;  // frame_id length 5: one more than the 4 bytes left
  Header decoded;
  EXPECT_EQ(msg::Decode(bytes, &decoded).message(),
            "std_msgs/msg/Header.frame_id: string of 5 bytes at offset 16, only 4 left");
}

TEST(Cdr, AFieldAfterAnOddLengthStringIsAlignedToFour) {
  Bytes out;
  CdrWriter writer(&out);
  writer.WriteString("abcd");  // length 5: 4 + 5 = 9 bytes of body
  writer.WriteUint32(0x11223344);
  const Bytes expected = {0x00, 0x01, 0x00, 0x00, 0x05, 0x00, 0x00, 0x00,
                          'a',  'b',  'c',  'd',  0x00, 0x00, 0x00, 0x00,  // 3 bytes padding to 12
                          0x44, 0x33, 0x22, 0x11};
  EXPECT_EQ(out, expected);
  CdrReader reader(out, "test/msg/T");
  std::string text;
  uint32_t value = 0;
  ASSERT_TRUE(reader.ReadEncapsulation().ok());
  ASSERT_TRUE(reader.ReadString("s", &text).ok());
  ASSERT_TRUE(reader.ReadUint32("u", &value).ok());
  EXPECT_EQ(text, "abcd");
  EXPECT_EQ(value, 0x11223344u);
  EXPECT_TRUE(reader.Finish().ok());
}

TEST(Cdr, AFloat64AfterAUint8IsAlignedToEightCountedFromAfterTheHeader) {
  Bytes out;
  CdrWriter writer(&out);
  writer.WriteUint8(7);
  writer.WriteFloat64(1.5);                                                // 0x3ff8000000000000
  const Bytes expected = {0x00, 0x01, 0x00, 0x00,                          // header
                          0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // uint8 + 7 padding
                          0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf8, 0x3f};
  EXPECT_EQ(out, expected);
  CdrSizer sizer;
  sizer.WriteUint8(7);
  sizer.WriteFloat64(1.5);
  EXPECT_EQ(sizer.size(), expected.size());
}

TEST(Cdr, AWriterAppendingToFilledBytesAlignsFromItsOwnHeader) {
  Bytes out = {0xaa, 0xbb, 0xcc};  // not part of the message
  CdrWriter writer(&out);
  writer.WriteUint8(1);
  writer.WriteUint32(2);
  const Bytes expected = {0xaa, 0xbb, 0xcc, 0x00, 0x01, 0x00, 0x00, 0x01,
                          0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00};
  EXPECT_EQ(out, expected);
}

TEST(Cdr, BigEndianFloat64IsReadInItsByteOrder) {
  const Bytes bytes = {0x00, 0x00, 0x00, 0x00,                          // CDR_BE
                       0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // uint8 + padding
                       0x3f, 0xf8, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00};
  CdrReader reader(bytes, "test/msg/T");
  uint8_t small = 0;
  double value = 0;
  ASSERT_TRUE(reader.ReadEncapsulation().ok());
  EXPECT_TRUE(reader.big_endian());
  ASSERT_TRUE(reader.ReadUint8("a", &small).ok());
  ASSERT_TRUE(reader.ReadFloat64("b", &value).ok());
  EXPECT_EQ(small, 7);
  EXPECT_EQ(value, 1.5);
}

TEST(Cdr, BigEndianCameraInfoDecodesItsFloat64Arrays) {
  // Built by swapping each primitive of the little-endian encoding at the (body) offsets the
  // layout gives.
  CameraInfo info;
  info.distortion_model = "pb";  // length 3: d's count at body 32, values at 40
  info.d = {0.5, -2.0};
  info.k[0] = 100.0;
  info.p[11] = -1.0;
  info.roi.do_rectify = true;
  Bytes bytes = EncodeToBytes(info);
  bytes[1] = 0x00;  // CDR_BE
  auto swap = [&](size_t body_offset, size_t size) {
    std::reverse(bytes.begin() + 4 + body_offset, bytes.begin() + 4 + body_offset + size);
  };
  // stamp, frame_id length, height, width, model length, d count; frame_id "" ends at 13
  for (size_t offset : {0, 4, 8, 16, 20, 24, 32}) swap(offset, 4);
  for (size_t i = 0; i < 2 + 9 + 9 + 12; ++i) swap(40 + 8 * i, 8);  // d, k, r, p
  const size_t after = 40 + 8 * 32;
  for (size_t i = 0; i < 6; ++i) swap(after + 4 * i, 4);  // binning_x, binning_y, roi
  CameraInfo decoded;
  const Status status = msg::Decode(bytes, &decoded);
  ASSERT_TRUE(status.ok()) << status.message();
  EXPECT_EQ(decoded, info);
}

TEST(Cdr, EncapsulationsOtherThanPlainCdrAreRefusedByName) {
  Bytes bytes = EncodeToBytes(RegionOfInterest{});
  RegionOfInterest decoded;
  bytes[1] = 0x03;
  EXPECT_EQ(msg::Decode(bytes, &decoded).message(),
            "sensor_msgs/msg/RegionOfInterest: encapsulation 00 03 (PL_CDR_LE) is not supported; "
            "expected plain CDR: 00 01 (little-endian) or 00 00 (big-endian)");
  bytes[1] = 0x07;
  EXPECT_NE(msg::Decode(bytes, &decoded).message().find("(CDR2_LE) is not supported"),
            std::string::npos);
  bytes[0] = 0x01;
  bytes[1] = 0x01;
  EXPECT_NE(msg::Decode(bytes, &decoded).message().find("01 01 (unknown)"), std::string::npos);
  EXPECT_EQ(msg::Decode(Bytes{0x00, 0x01}, &decoded).message(),
            "sensor_msgs/msg/RegionOfInterest: 2 bytes cannot hold the 4-byte CDR encapsulation "
            "header");
}

TEST(Cdr, TheOptionBytesOfTheHeaderAreIgnored) {
  Bytes bytes = EncodeToBytes(FullSample<RegionOfInterest>());
  bytes[2] = 0x12;
  bytes[3] = 0x03;  // as if announcing 3 bytes of padding (RTPS 2.3+); not interpreted
  RegionOfInterest decoded;
  ASSERT_TRUE(msg::Decode(bytes, &decoded).ok());
  EXPECT_EQ(decoded, FullSample<RegionOfInterest>());
}

TEST(Cdr, ATruncatedUint32NamesItsOffsetAndTheBytesLeft) {
  const Bytes bytes = EncodeToBytes(FullSample<RegionOfInterest>());
  RegionOfInterest decoded;
  EXPECT_EQ(msg::Decode(std::span(bytes).first(10), &decoded).message(),
            "sensor_msgs/msg/RegionOfInterest.y_offset: uint32 at offset 8, only 2 left");
}

TEST(Cdr, AStringWithoutItsNulIsRefused) {
  Bytes bytes = EncodeToBytes(Header{{1, 2}, "cam"});
  bytes[19] = 'x';  // the NUL
  Header decoded;
  EXPECT_EQ(msg::Decode(bytes, &decoded).message(),
            "std_msgs/msg/Header.frame_id: string of 4 bytes at offset 16 does not end in NUL");
}

TEST(Cdr, AZeroLengthStringReadsAsEmpty) {
  // Fast-CDR reads length 0 as an empty string (it writes it for a null char*).
  const Bytes bytes = {0x00, 0x01, 0x00, 0x00, 0x05, 0x00, 0x00, 0x00,
                       0x06, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00};
  Header decoded{{0, 0}, "previous"};
  ASSERT_TRUE(msg::Decode(bytes, &decoded).ok());
  EXPECT_EQ(decoded, (Header{{5, 6}, ""}));
}

TEST(Cdr, ANonAsciiStringIsCarriedAsItsUtf8Bytes) {
  const Header sent{{1, 2}, "kamera_\xc3\xa4\xe2\x82\xac"};  // "kamera_ä€"
  Header received;
  ASSERT_TRUE(msg::Decode(EncodeToBytes(sent), &received).ok());
  EXPECT_EQ(received, sent);
}

TEST(Cdr, ABoolOtherThanZeroOrOneIsRefused) {
  Bytes bytes = EncodeToBytes(RegionOfInterest{});
  bytes[20] = 2;  // do_rectify, after four uint32
  RegionOfInterest decoded;
  EXPECT_EQ(msg::Decode(bytes, &decoded).message(),
            "sensor_msgs/msg/RegionOfInterest.do_rectify: bool at offset 20 is 2, not 0 or 1");
}

TEST(Cdr, ErrorsNameNestedFieldsAndSequenceIndices) {
  const DiagnosticArray array = FullSample<DiagnosticArray>();
  Bytes bytes = EncodeToBytes(array);
  // Cut in the middle of the last string: status[2].values[0].value.
  bytes.resize(bytes.size() - 2);
  DiagnosticArray decoded;
  const std::string message = msg::Decode(bytes, &decoded).message();
  EXPECT_EQ(message.rfind("diagnostic_msgs/msg/DiagnosticArray.status[2].values[0].value: ", 0), 0u)
      << message;
  bytes = EncodeToBytes(array);
  bytes.resize(10);
  EXPECT_EQ(msg::Decode(bytes, &decoded).message(),
            "diagnostic_msgs/msg/DiagnosticArray.header.stamp.nanosec: uint32 at offset 8, only 2 "
            "left");
}

TEST(Cdr, AStructSequenceCountBeyondTheMessageIsRefusedBeforeAnyResize) {
  DiagnosticArray array;
  array.header.frame_id = "f";
  Bytes bytes = EncodeToBytes(array);
  ASSERT_EQ(bytes.size(), 4u + 8 + 6 + 2 + 4);  // stamp, "f", padding, status count
  // 1000 statuses of at least 17 bytes each cannot fit in the 400 bytes that follow.
  bytes[20] = 0xe8;
  bytes[21] = 0x03;
  bytes.resize(bytes.size() + 400);
  DiagnosticArray decoded;
  Status status;
  EXPECT_LE(BytesAllocatedDuring([&] { status = msg::Decode(bytes, &decoded); }), 1024u);
  EXPECT_EQ(status.message(),
            "diagnostic_msgs/msg/DiagnosticArray.status: sequence of 1000 elements of at least 17 "
            "bytes at offset 24, only 400 left");
  EXPECT_EQ(decoded.status.capacity(), 0u);
}

TEST(Cdr, AFloat64SequenceCountBeyondTheMessageIsRefused) {
  CameraInfo info;
  Bytes bytes = EncodeToBytes(info);
  // d's count sits after stamp (8), frame_id (5 + 3 padding), height, width, model (5 + 3).
  ASSERT_EQ(bytes[4 + 32], 0x00);
  bytes[4 + 32] = 0xff;
  bytes[4 + 33] = 0xff;
  bytes[4 + 34] = 0xff;
  bytes[4 + 35] = 0x1f;  // 0x1fffffff doubles: more than 2 GiB
  CameraInfo decoded;
  Status status;
  EXPECT_LE(BytesAllocatedDuring([&] { status = msg::Decode(bytes, &decoded); }), 1024u);
  EXPECT_EQ(status.message().rfind("sensor_msgs/msg/CameraInfo.d: sequence of 536870911 float64 "
                                   "at offset 44, only ",
                                   0),
            0u)
      << status.message();
}

TEST(Cdr, DecodingIntoALargerMessageShrinksItsSequences) {
  DiagnosticArray received = FullSample<DiagnosticArray>();
  DiagnosticArray smaller;
  smaller.status.push_back({DiagnosticStatus::kError, "one", "", "", {}});
  ASSERT_TRUE(msg::Decode(EncodeToBytes(smaller), &received).ok());
  EXPECT_EQ(received, smaller);
}

// ---------------------------------------------------------------------------------------------
// Names and definitions.

TEST(Names, RosAndDdsTypeNamesFollowTheRmwConvention) {
  EXPECT_EQ(msg::NamesOf<Image>().ros2_type, "sensor_msgs/msg/Image");
  EXPECT_EQ(msg::NamesOf<Image>().dds_type, "sensor_msgs::msg::dds_::Image_");
  EXPECT_EQ(msg::NamesOf<Time>().dds_type, "builtin_interfaces::msg::dds_::Time_");
  EXPECT_EQ(msg::NamesOf<DiagnosticArray>().ros2_type, "diagnostic_msgs/msg/DiagnosticArray");
  EXPECT_EQ(msg::AllMessageNames().size(), 9u);
  for (const msg::MessageNames& names : msg::AllMessageNames()) {
    EXPECT_EQ(msg::FindMessageNames(names.ros2_type), &names);
  }
  EXPECT_EQ(msg::FindMessageNames("sensor_msgs/Image"), nullptr);
}

const std::string kDelimiter = std::string(80, '=') + "\n";

TEST(Names, TheImageDefinitionHasItsDependenciesDepthFirstAsRosbag2WritesThem) {
  const std::string expected =
      "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
      "uint8 is_bigendian\nuint32 step\nuint8[] data\n"
      "\n" +
      kDelimiter +
      "MSG: std_msgs/Header\n"
      "builtin_interfaces/Time stamp\nstring frame_id\n"
      "\n" +
      kDelimiter +
      "MSG: builtin_interfaces/Time\n"
      "int32 sec\nuint32 nanosec\n";
  EXPECT_EQ(msg::NamesOf<Image>().definition, expected);
}

// Dependencies in std::set order at each level, each once: CameraInfo uses
// sensor_msgs/RegionOfInterest (bare "RegionOfInterest", given its package) and std_msgs/Header.
TEST(Names, DependenciesAreWrittenOnceInSortedOrderAtEachLevel) {
  auto order = [](std::string_view definition) {
    std::vector<std::string> names;
    for (size_t at = definition.find("MSG: "); at != std::string_view::npos;
         at = definition.find("MSG: ", at + 1)) {
      names.emplace_back(definition.substr(at + 5, definition.find('\n', at) - at - 5));
    }
    return names;
  };
  EXPECT_EQ(order(msg::NamesOf<CameraInfo>().definition),
            (std::vector<std::string>{"sensor_msgs/RegionOfInterest", "std_msgs/Header",
                                      "builtin_interfaces/Time"}));
  EXPECT_EQ(
      order(msg::NamesOf<DiagnosticArray>().definition),
      (std::vector<std::string>{"diagnostic_msgs/DiagnosticStatus", "diagnostic_msgs/KeyValue",
                                "std_msgs/Header", "builtin_interfaces/Time"}));
  EXPECT_TRUE(order(msg::NamesOf<Time>().definition).empty());
  EXPECT_NE(msg::NamesOf<DiagnosticStatus>().definition.find("byte OK=0\nbyte WARN=1\n"
                                                             "byte ERROR=2\nbyte STALE=3\n"),
            std::string_view::npos);
}

}  // namespace
}  // namespace sfrt::ros2
