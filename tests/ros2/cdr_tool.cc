// cdr_tool: sfrt's ROS 2 message codec (ros2/src/messages.h) on the command line, for
// cdr_oracle_check.mjs to compare with @foxglove/rosmsg2-serialization. Test-only.
//
//   cdr_tool types                  one line per type: "<ROS 2 type> <DDS type>"
//   cdr_tool definition TYPE        the ros2msg definition text of TYPE
//   cdr_tool encode TYPE < json     the CDR bytes of the message in the JSON
//   cdr_tool decode TYPE < bytes    the message as JSON
//
// TYPE is a ROS 2 type name ("sensor_msgs/msg/Image"). The JSON has the .msg field names; uint8[]
// and float64 arrays are JSON arrays of numbers. Every field must be present (a missing one is an
// error, not a default, so a misspelt name cannot pass unnoticed). Exit status: 0 done, 1 the
// input was refused (the reason on stderr), 2 usage.
#include <cstdio>
#include <iostream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "messages.h"

namespace sfrt::ros2::msg {

using nlohmann::json;

// nlohmann's to_json/from_json, found by ADL: one pair per message, fields in .msg order.

void to_json(json& j, const Time& m) { j = {{"sec", m.sec}, {"nanosec", m.nanosec}}; }
void from_json(const json& j, Time& m) {
  j.at("sec").get_to(m.sec);
  j.at("nanosec").get_to(m.nanosec);
}

void to_json(json& j, const Header& m) { j = {{"stamp", m.stamp}, {"frame_id", m.frame_id}}; }
void from_json(const json& j, Header& m) {
  j.at("stamp").get_to(m.stamp);
  j.at("frame_id").get_to(m.frame_id);
}

void to_json(json& j, const Image& m) {
  j = {{"header", m.header},
       {"height", m.height},
       {"width", m.width},
       {"encoding", m.encoding},
       {"is_bigendian", m.is_bigendian},
       {"step", m.step},
       {"data", m.data}};
}
void from_json(const json& j, Image& m) {
  j.at("header").get_to(m.header);
  j.at("height").get_to(m.height);
  j.at("width").get_to(m.width);
  j.at("encoding").get_to(m.encoding);
  j.at("is_bigendian").get_to(m.is_bigendian);
  j.at("step").get_to(m.step);
  j.at("data").get_to(m.data);
}

void to_json(json& j, const CompressedImage& m) {
  j = {{"header", m.header}, {"format", m.format}, {"data", m.data}};
}
void from_json(const json& j, CompressedImage& m) {
  j.at("header").get_to(m.header);
  j.at("format").get_to(m.format);
  j.at("data").get_to(m.data);
}

void to_json(json& j, const RegionOfInterest& m) {
  j = {{"x_offset", m.x_offset},
       {"y_offset", m.y_offset},
       {"height", m.height},
       {"width", m.width},
       {"do_rectify", m.do_rectify}};
}
void from_json(const json& j, RegionOfInterest& m) {
  j.at("x_offset").get_to(m.x_offset);
  j.at("y_offset").get_to(m.y_offset);
  j.at("height").get_to(m.height);
  j.at("width").get_to(m.width);
  j.at("do_rectify").get_to(m.do_rectify);
}

void to_json(json& j, const CameraInfo& m) {
  j = {{"header", m.header},
       {"height", m.height},
       {"width", m.width},
       {"distortion_model", m.distortion_model},
       {"d", m.d},
       {"k", m.k},
       {"r", m.r},
       {"p", m.p},
       {"binning_x", m.binning_x},
       {"binning_y", m.binning_y},
       {"roi", m.roi}};
}
void from_json(const json& j, CameraInfo& m) {
  j.at("header").get_to(m.header);
  j.at("height").get_to(m.height);
  j.at("width").get_to(m.width);
  j.at("distortion_model").get_to(m.distortion_model);
  j.at("d").get_to(m.d);
  j.at("k").get_to(m.k);
  j.at("r").get_to(m.r);
  j.at("p").get_to(m.p);
  j.at("binning_x").get_to(m.binning_x);
  j.at("binning_y").get_to(m.binning_y);
  j.at("roi").get_to(m.roi);
}

void to_json(json& j, const KeyValue& m) { j = {{"key", m.key}, {"value", m.value}}; }
void from_json(const json& j, KeyValue& m) {
  j.at("key").get_to(m.key);
  j.at("value").get_to(m.value);
}

void to_json(json& j, const DiagnosticStatus& m) {
  j = {{"level", m.level},
       {"name", m.name},
       {"message", m.message},
       {"hardware_id", m.hardware_id},
       {"values", m.values}};
}
void from_json(const json& j, DiagnosticStatus& m) {
  j.at("level").get_to(m.level);
  j.at("name").get_to(m.name);
  j.at("message").get_to(m.message);
  j.at("hardware_id").get_to(m.hardware_id);
  j.at("values").get_to(m.values);
}

void to_json(json& j, const DiagnosticArray& m) {
  j = {{"header", m.header}, {"status", m.status}};
}
void from_json(const json& j, DiagnosticArray& m) {
  j.at("header").get_to(m.header);
  j.at("status").get_to(m.status);
}

}  // namespace sfrt::ros2::msg

namespace {

namespace msg = sfrt::ros2::msg;

std::vector<uint8_t> ReadStdin() {
  std::cin >> std::noskipws;
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(std::cin),
                              std::istreambuf_iterator<char>());
}

template <typename T>
int EncodeJson() {
  T message;
  try {
    nlohmann::json::parse(std::cin).get_to(message);
  } catch (const nlohmann::json::exception& e) {
    std::fprintf(stderr, "cdr_tool encode: %s\n", e.what());
    return 1;
  }
  std::vector<uint8_t> bytes;
  msg::Encode(message, &bytes);
  std::fwrite(bytes.data(), 1, bytes.size(), stdout);
  return 0;
}

template <typename T>
int DecodeJson() {
  const std::vector<uint8_t> bytes = ReadStdin();
  T message;
  if (sfrt::Status status = msg::Decode(bytes, &message); !status.ok()) {
    std::fprintf(stderr, "cdr_tool decode: %s\n", status.message().c_str());
    return 1;
  }
  std::cout << nlohmann::json(message).dump() << "\n";
  return 0;
}

struct Codec {
  const msg::MessageNames& names;
  int (*encode)();
  int (*decode)();
};

template <typename T>
Codec CodecOf() {
  return {msg::NamesOf<T>(), &EncodeJson<T>, &DecodeJson<T>};
}

const Codec* FindCodec(std::string_view type) {
  static const Codec kCodecs[] = {
      CodecOf<msg::Time>(),
      CodecOf<msg::Header>(),
      CodecOf<msg::Image>(),
      CodecOf<msg::CompressedImage>(),
      CodecOf<msg::RegionOfInterest>(),
      CodecOf<msg::CameraInfo>(),
      CodecOf<msg::KeyValue>(),
      CodecOf<msg::DiagnosticStatus>(),
      CodecOf<msg::DiagnosticArray>(),
  };
  for (const Codec& codec : kCodecs) {
    if (codec.names.ros2_type == type) return &codec;
  }
  return nullptr;
}

int Usage() {
  std::fprintf(stderr,
               "usage: cdr_tool types | definition TYPE | encode TYPE < json | decode TYPE < "
               "bytes\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 2 && std::string_view(argv[1]) == "types") {
    for (const msg::MessageNames& names : msg::AllMessageNames()) {
      std::printf("%.*s %.*s\n", static_cast<int>(names.ros2_type.size()), names.ros2_type.data(),
                  static_cast<int>(names.dds_type.size()), names.dds_type.data());
    }
    return 0;
  }
  if (argc != 3) return Usage();
  const std::string_view command = argv[1];
  const Codec* codec = FindCodec(argv[2]);
  if (codec == nullptr) {
    std::fprintf(stderr, "cdr_tool: unknown type %s (cdr_tool types lists them)\n", argv[2]);
    return 2;
  }
  if (command == "definition") {
    std::fwrite(codec->names.definition.data(), 1, codec->names.definition.size(), stdout);
    return 0;
  }
  if (command == "encode") return codec->encode();
  if (command == "decode") return codec->decode();
  return Usage();
}
