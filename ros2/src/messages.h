// The ROS 2 messages sfrt reads and writes, and their CDR encoding (issue #39).
//
// Supported: builtin_interfaces/msg/Time, std_msgs/msg/Header, sensor_msgs/msg/{Image,
// CompressedImage, RegionOfInterest, CameraInfo}, diagnostic_msgs/msg/{KeyValue,
// DiagnosticStatus, DiagnosticArray}, field for field as their .msg files in ros2/common_interfaces
// and ros2/rcl_interfaces declare them (ROS 2: Header has no seq; Time is {int32 sec; uint32
// nanosec}; `byte` is uint8).
//
// Encoding (cdr.h has the rules): Encode writes the 4-byte CDR_LE encapsulation header and the
// fields, little-endian, with no end padding: byte for byte what rmw_serialize and
// @foxglove/rosmsg2-serialization's MessageWriter produce. Decode accepts little- and big-endian
// plain CDR and up to 3 bytes of end padding (rmw_cyclonedds pads to a multiple of 4), and refuses
// everything else with a one-line error naming the field and byte offset. Decode checks the wire
// format, not the meaning: it does not check that Image.data holds step * height bytes (ROS does
// not either), nor that encoding names a known pixel format; callers that index data must.
//
// Allocation: Encode replaces *out's contents, computing the exact size first and reserving it
// once, so encoding a message of the same size into the same vector again allocates nothing.
// Decode reuses *out's strings and vectors (nested ones included): decoding a message no larger
// than the last into the same object allocates nothing. DecodeImageView never allocates. A
// decoder never allocates more than a small multiple of its input (cdr.h, "Bounds"). On error,
// *out is valid but its contents unspecified.
//
// Names: NamesOf<T>() gives the ROS 2 type name, the DDS type name and the full ros2msg
// definition text (as rosbag2 writes in MCAP Schema records); all are built once, on first use,
// from one table per message in messages.cc.
//
// Thread-safety: every function is safe to call concurrently on distinct objects; the name
// tables are immutable after their thread-safe first use.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/status.h"

namespace sfrt::ros2::msg {

// builtin_interfaces/msg/Time.
struct Time {
  int32_t sec = 0;
  uint32_t nanosec = 0;  // [0, 1e9) by convention; not checked
  bool operator==(const Time&) const = default;
};

// std_msgs/msg/Header.
struct Header {
  Time stamp;
  std::string frame_id;
  bool operator==(const Header&) const = default;
};

// sensor_msgs/msg/Image.
struct Image {
  Header header;
  uint32_t height = 0;
  uint32_t width = 0;
  std::string encoding;  // e.g. "rgb8", "mono16", "32FC1"
  uint8_t is_bigendian = 0;
  uint32_t step = 0;  // bytes per row
  std::vector<uint8_t> data;
  bool operator==(const Image&) const = default;
};

// std_msgs/msg/Header whose frame_id points into a decoded buffer.
struct HeaderView {
  Time stamp;
  std::string_view frame_id;
};

// sensor_msgs/msg/Image whose strings and data point into the buffer it was decoded from (or,
// to Encode, into the caller's pixels): valid only while that buffer lives.
struct ImageView {
  HeaderView header;
  uint32_t height = 0;
  uint32_t width = 0;
  std::string_view encoding;
  uint8_t is_bigendian = 0;
  uint32_t step = 0;
  std::span<const uint8_t> data;
};

// sensor_msgs/msg/CompressedImage.
struct CompressedImage {
  Header header;
  std::string format;  // e.g. "jpeg", "rgb8; png compressed bgr8"
  std::vector<uint8_t> data;
  bool operator==(const CompressedImage&) const = default;
};

// sensor_msgs/msg/RegionOfInterest.
struct RegionOfInterest {
  uint32_t x_offset = 0;
  uint32_t y_offset = 0;
  uint32_t height = 0;
  uint32_t width = 0;
  bool do_rectify = false;
  bool operator==(const RegionOfInterest&) const = default;
};

// sensor_msgs/msg/CameraInfo.
struct CameraInfo {
  Header header;
  uint32_t height = 0;
  uint32_t width = 0;
  std::string distortion_model;  // e.g. "plumb_bob"
  std::vector<double> d;
  std::array<double, 9> k = {};   // 3x3 row-major
  std::array<double, 9> r = {};   // 3x3 row-major
  std::array<double, 12> p = {};  // 3x4 row-major
  uint32_t binning_x = 0;
  uint32_t binning_y = 0;
  RegionOfInterest roi;
  bool operator==(const CameraInfo&) const = default;
};

// diagnostic_msgs/msg/KeyValue.
struct KeyValue {
  std::string key;
  std::string value;
  bool operator==(const KeyValue&) const = default;
};

// diagnostic_msgs/msg/DiagnosticStatus.
struct DiagnosticStatus {
  // The .msg's constants OK, WARN, ERROR, STALE (`byte`, i.e. uint8).
  static constexpr uint8_t kOk = 0;
  static constexpr uint8_t kWarn = 1;
  static constexpr uint8_t kError = 2;
  static constexpr uint8_t kStale = 3;

  uint8_t level = kOk;  // any byte is carried; only the four above have a meaning
  std::string name;
  std::string message;
  std::string hardware_id;
  std::vector<KeyValue> values;
  bool operator==(const DiagnosticStatus&) const = default;
};

// diagnostic_msgs/msg/DiagnosticArray.
struct DiagnosticArray {
  Header header;
  std::vector<DiagnosticStatus> status;
  bool operator==(const DiagnosticArray&) const = default;
};

void Encode(const Time& message, std::vector<uint8_t>* out);
void Encode(const Header& message, std::vector<uint8_t>* out);
void Encode(const Image& message, std::vector<uint8_t>* out);
void Encode(const ImageView& message, std::vector<uint8_t>* out);  // same bytes as an Image
void Encode(const CompressedImage& message, std::vector<uint8_t>* out);
void Encode(const RegionOfInterest& message, std::vector<uint8_t>* out);
void Encode(const CameraInfo& message, std::vector<uint8_t>* out);
void Encode(const KeyValue& message, std::vector<uint8_t>* out);
void Encode(const DiagnosticStatus& message, std::vector<uint8_t>* out);
void Encode(const DiagnosticArray& message, std::vector<uint8_t>* out);

Status Decode(std::span<const uint8_t> bytes, Time* out);
Status Decode(std::span<const uint8_t> bytes, Header* out);
Status Decode(std::span<const uint8_t> bytes, Image* out);
Status Decode(std::span<const uint8_t> bytes, CompressedImage* out);
Status Decode(std::span<const uint8_t> bytes, RegionOfInterest* out);
Status Decode(std::span<const uint8_t> bytes, CameraInfo* out);
Status Decode(std::span<const uint8_t> bytes, KeyValue* out);
Status Decode(std::span<const uint8_t> bytes, DiagnosticStatus* out);
Status Decode(std::span<const uint8_t> bytes, DiagnosticArray* out);

// Decodes a sensor_msgs/msg/Image without copying: out's strings and data point into `bytes`.
Status DecodeImageView(std::span<const uint8_t> bytes, ImageView* out);

// How one message type is named where ROS 2 meets the outside world.
struct MessageNames {
  std::string_view ros2_type;   // "sensor_msgs/msg/Image": rosbag2 topic type, MCAP Schema name
  std::string_view dds_type;    // "sensor_msgs::msg::dds_::Image_": the DDS type on the wire
  std::string_view definition;  // MCAP Schema data for encoding "ros2msg" (rosbag2's format:
                                // the .msg, then each dependency after a line of 80 '=' and
                                // "MSG: pkg/Type"; comments dropped)
};

// The names of T, one of the message structs above (ImageView: use Image).
template <typename T>
const MessageNames& NamesOf();

// Every supported type, in a fixed order (dependencies first).
std::span<const MessageNames> AllMessageNames();
// The names whose ros2_type is `ros2_type`, or nullptr.
const MessageNames* FindMessageNames(std::string_view ros2_type);

}  // namespace sfrt::ros2::msg
