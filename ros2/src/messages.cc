#include "messages.h"

#include <cstdio>
#include <cstdlib>
#include <set>

#include "cdr.h"

// Returns the Status of `expr` when it is an error. Local to this file: the decoders are long
// runs of reads, each of which may fail.
#define SFRT_ROS2_TRY(expr)                               \
  do {                                                    \
    if (::sfrt::Status status_ = (expr); !status_.ok()) { \
      return status_;                                     \
    }                                                     \
  } while (false)

namespace sfrt::ros2::msg {
namespace {

// ---------------------------------------------------------------------------------------------
// The one table per message: its package, name and .msg text. Everything else about its names
// (ROS 2 and DDS type names, the full ros2msg definition with dependencies) is derived from it.
//
// The texts are the field and constant lines of the .msg files in ros2/common_interfaces
// (sensor_msgs, std_msgs, diagnostic_msgs) and ros2/rcl_interfaces (builtin_interfaces), in their
// order and spelling, with comments and blank lines dropped (rosbag2's
// docs/message_definition_encoding.md allows writers to strip comments).

struct MessageSpec {
  std::string_view package;
  std::string_view name;
  std::string_view fields;
};

enum SpecIndex : size_t {
  kTimeSpec,
  kHeaderSpec,
  kImageSpec,
  kCompressedImageSpec,
  kRegionOfInterestSpec,
  kCameraInfoSpec,
  kKeyValueSpec,
  kDiagnosticStatusSpec,
  kDiagnosticArraySpec,
  kSpecCount,
};

constexpr std::array<MessageSpec, kSpecCount> kSpecs = {{
    {"builtin_interfaces", "Time",
     "int32 sec\n"
     "uint32 nanosec\n"},
    {"std_msgs", "Header",
     "builtin_interfaces/Time stamp\n"
     "string frame_id\n"},
    {"sensor_msgs", "Image",
     "std_msgs/Header header\n"
     "uint32 height\n"
     "uint32 width\n"
     "string encoding\n"
     "uint8 is_bigendian\n"
     "uint32 step\n"
     "uint8[] data\n"},
    {"sensor_msgs", "CompressedImage",
     "std_msgs/Header header\n"
     "string format\n"
     "uint8[] data\n"},
    {"sensor_msgs", "RegionOfInterest",
     "uint32 x_offset\n"
     "uint32 y_offset\n"
     "uint32 height\n"
     "uint32 width\n"
     "bool do_rectify\n"},
    {"sensor_msgs", "CameraInfo",
     "std_msgs/Header header\n"
     "uint32 height\n"
     "uint32 width\n"
     "string distortion_model\n"
     "float64[] d\n"
     "float64[9] k\n"
     "float64[9] r\n"
     "float64[12] p\n"
     "uint32 binning_x\n"
     "uint32 binning_y\n"
     "RegionOfInterest roi\n"},
    {"diagnostic_msgs", "KeyValue",
     "string key\n"
     "string value\n"},
    {"diagnostic_msgs", "DiagnosticStatus",
     "byte OK=0\n"
     "byte WARN=1\n"
     "byte ERROR=2\n"
     "byte STALE=3\n"
     "byte level\n"
     "string name\n"
     "string message\n"
     "string hardware_id\n"
     "KeyValue[] values\n"},
    {"diagnostic_msgs", "DiagnosticArray",
     "std_msgs/Header header\n"
     "DiagnosticStatus[] status\n"},
}};

// ---------------------------------------------------------------------------------------------
// The full ros2msg definition, as rosbag2_cpp's LocalMessageDefinitionSource::get_full_text
// builds it: the type's text, then for each dependency not yet written (in std::set order,
// depth first) "\n", 80 '=', "\nMSG: ", the dependency as the field spells it ("std_msgs/Header";
// a bare "RegionOfInterest" gets the package of the type using it), "\n", its text.

constexpr std::string_view kPrimitiveTypes[] = {"bool",   "byte",  "char",   "float32", "float64",
                                                "int8",   "uint8", "int16",  "uint16",  "int32",
                                                "uint32", "int64", "uint64", "string"};

bool IsPrimitive(std::string_view type) {
  for (std::string_view primitive : kPrimitiveTypes) {
    if (type == primitive) return true;
  }
  return false;
}

// The message types the fields of `spec` use, as rosbag2's parse_msg_dependencies names them.
std::set<std::string> DependenciesOf(const MessageSpec& spec) {
  std::set<std::string> dependencies;
  std::string_view rest = spec.fields;
  while (!rest.empty()) {
    const size_t end = rest.find('\n');
    const std::string_view line = rest.substr(0, end);
    rest = end == std::string_view::npos ? std::string_view() : rest.substr(end + 1);
    std::string_view type = line.substr(0, line.find_first_of(" ["));
    if (type.empty() || IsPrimitive(type)) continue;
    dependencies.insert(type.find('/') == std::string_view::npos
                            ? std::string(spec.package) + "/" + std::string(type)
                            : std::string(type));
  }
  return dependencies;
}

// The spec named "pkg/Name" or "pkg/msg/Name".
const MessageSpec& FindSpec(std::string_view dependency) {
  const std::string_view package = dependency.substr(0, dependency.find('/'));
  const std::string_view name = dependency.substr(dependency.rfind('/') + 1);
  for (const MessageSpec& spec : kSpecs) {
    if (spec.package == package && spec.name == name) return spec;
  }
  // Only a mistake in kSpecs gets here (every test that touches a name fails); not input.
  std::fprintf(stderr, "sfrt::ros2::msg: no message spec for dependency %.*s\n",
               static_cast<int>(dependency.size()), dependency.data());
  std::abort();
}

void AppendDefinition(const MessageSpec& spec, std::set<std::string>* written, std::string* out) {
  *out += spec.fields;
  for (const std::string& dependency : DependenciesOf(spec)) {
    if (!written->insert(dependency).second) continue;
    *out += "\n" + std::string(80, '=') + "\nMSG: " + dependency + "\n";
    AppendDefinition(FindSpec(dependency), written, out);
  }
}

// Every name of every spec, built once; the views in `names` point into the strings beside them,
// so a Registry is neither copied nor moved.
struct Registry {
  Registry();
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  std::array<std::string, kSpecCount> ros2_types;
  std::array<std::string, kSpecCount> dds_types;
  std::array<std::string, kSpecCount> definitions;
  std::array<MessageNames, kSpecCount> names;
};

Registry::Registry() {
  for (size_t i = 0; i < kSpecCount; ++i) {
    const MessageSpec& spec = kSpecs[i];
    const std::string package(spec.package);
    const std::string name(spec.name);
    ros2_types[i] = package + "/msg/" + name;
    // rmw_fastrtps' _create_type_name: "<namespace>::dds_::<Name>_", namespace "<pkg>::msg".
    dds_types[i] = package + "::msg::dds_::" + name + "_";
    std::set<std::string> written;
    AppendDefinition(spec, &written, &definitions[i]);
    names[i] = {ros2_types[i], dds_types[i], definitions[i]};
  }
}

const Registry& GetRegistry() {
  static const Registry registry;  // thread-safe first use
  return registry;
}

// ---------------------------------------------------------------------------------------------
// Encoding: one Put per message, written against the Sink interface that CdrSizer (to reserve
// the exact size) and CdrWriter share.

template <typename Sink>
void Put(const Time& m, Sink& s) {
  s.WriteInt32(m.sec);
  s.WriteUint32(m.nanosec);
}

template <typename HeaderLike, typename Sink>
void PutHeader(const HeaderLike& m, Sink& s) {
  Put(m.stamp, s);
  s.WriteString(m.frame_id);
}

template <typename Sink>
void Put(const Header& m, Sink& s) {
  PutHeader(m, s);
}

template <typename ImageLike, typename Sink>
void PutImage(const ImageLike& m, Sink& s) {
  PutHeader(m.header, s);
  s.WriteUint32(m.height);
  s.WriteUint32(m.width);
  s.WriteString(m.encoding);
  s.WriteUint8(m.is_bigendian);
  s.WriteUint32(m.step);
  s.WriteByteSequence(m.data);
}

template <typename Sink>
void Put(const Image& m, Sink& s) {
  PutImage(m, s);
}

template <typename Sink>
void Put(const ImageView& m, Sink& s) {
  PutImage(m, s);
}

template <typename Sink>
void Put(const CompressedImage& m, Sink& s) {
  PutHeader(m.header, s);
  s.WriteString(m.format);
  s.WriteByteSequence(m.data);
}

template <typename Sink>
void Put(const RegionOfInterest& m, Sink& s) {
  s.WriteUint32(m.x_offset);
  s.WriteUint32(m.y_offset);
  s.WriteUint32(m.height);
  s.WriteUint32(m.width);
  s.WriteBool(m.do_rectify);
}

template <typename Sink>
void Put(const CameraInfo& m, Sink& s) {
  PutHeader(m.header, s);
  s.WriteUint32(m.height);
  s.WriteUint32(m.width);
  s.WriteString(m.distortion_model);
  s.WriteFloat64Sequence(m.d);
  s.WriteFloat64Array(m.k);
  s.WriteFloat64Array(m.r);
  s.WriteFloat64Array(m.p);
  s.WriteUint32(m.binning_x);
  s.WriteUint32(m.binning_y);
  Put(m.roi, s);
}

template <typename Sink>
void Put(const KeyValue& m, Sink& s) {
  s.WriteString(m.key);
  s.WriteString(m.value);
}

template <typename Sink>
void Put(const DiagnosticStatus& m, Sink& s) {
  s.WriteUint8(m.level);
  s.WriteString(m.name);
  s.WriteString(m.message);
  s.WriteString(m.hardware_id);
  s.WriteSequenceLength(m.values.size());
  for (const KeyValue& value : m.values) Put(value, s);
}

template <typename Sink>
void Put(const DiagnosticArray& m, Sink& s) {
  PutHeader(m.header, s);
  s.WriteSequenceLength(m.status.size());
  for (const DiagnosticStatus& status : m.status) Put(status, s);
}

template <typename T>
void EncodeMessage(const T& message, std::vector<uint8_t>* out) {
  CdrSizer sizer;
  Put(message, sizer);
  out->clear();
  out->reserve(sizer.size());  // the one allocation, none when *out is already large enough
  CdrWriter writer(out);
  Put(message, writer);
}

// ---------------------------------------------------------------------------------------------
// Decoding: one Get per message, each read naming its field for error messages.

// Lower bounds of the encoded size of one sequence element, which cap how many elements a
// sequence count may declare (CdrReader::ReadSequenceLength): a string takes at least its 4-byte
// length (a length of 0 is accepted), a sequence its 4-byte count.
constexpr size_t kMinKeyValueBytes = 4 + 4;
constexpr size_t kMinDiagnosticStatusBytes = 1 + 4 + 4 + 4 + 4;

Status Get(CdrReader& r, Time* m);
Status Get(CdrReader& r, Header* m);
Status Get(CdrReader& r, HeaderView* m);
Status Get(CdrReader& r, RegionOfInterest* m);
Status Get(CdrReader& r, KeyValue* m);
Status Get(CdrReader& r, DiagnosticStatus* m);

// Reads a nested struct, its field name in error paths.
template <typename T>
Status GetNested(CdrReader& r, std::string_view field, T* m) {
  CdrReader::Scope scope(r, field);
  return Get(r, m);
}

// Reads a sequence of structs into *v, reusing its elements.
template <typename T>
Status GetSequence(CdrReader& r, std::string_view field, size_t min_element_bytes,
                   std::vector<T>* v) {
  uint32_t count = 0;
  SFRT_ROS2_TRY(r.ReadSequenceLength(field, min_element_bytes, &count));
  v->resize(count);  // bounded by the bytes left: ReadSequenceLength checked
  for (uint32_t i = 0; i < count; ++i) {
    CdrReader::Scope scope(r, field, i);
    SFRT_ROS2_TRY(Get(r, &(*v)[i]));
  }
  return Status::Ok();
}

// Owning and viewing variants of strings and byte sequences, so that one GetImage serves both.
Status ReadText(CdrReader& r, std::string_view field, std::string* v) {
  return r.ReadString(field, v);
}
Status ReadText(CdrReader& r, std::string_view field, std::string_view* v) {
  return r.ReadStringView(field, v);
}
Status ReadBytes(CdrReader& r, std::string_view field, std::vector<uint8_t>* v) {
  return r.ReadByteSequence(field, v);
}
Status ReadBytes(CdrReader& r, std::string_view field, std::span<const uint8_t>* v) {
  return r.ReadByteSequenceView(field, v);
}

Status Get(CdrReader& r, Time* m) {
  SFRT_ROS2_TRY(r.ReadInt32("sec", &m->sec));
  return r.ReadUint32("nanosec", &m->nanosec);
}

template <typename HeaderLike>
Status GetHeader(CdrReader& r, HeaderLike* m) {
  SFRT_ROS2_TRY(GetNested(r, "stamp", &m->stamp));
  return ReadText(r, "frame_id", &m->frame_id);
}

Status Get(CdrReader& r, Header* m) { return GetHeader(r, m); }
Status Get(CdrReader& r, HeaderView* m) { return GetHeader(r, m); }

template <typename ImageLike>
Status GetImage(CdrReader& r, ImageLike* m) {
  SFRT_ROS2_TRY(GetNested(r, "header", &m->header));
  SFRT_ROS2_TRY(r.ReadUint32("height", &m->height));
  SFRT_ROS2_TRY(r.ReadUint32("width", &m->width));
  SFRT_ROS2_TRY(ReadText(r, "encoding", &m->encoding));
  SFRT_ROS2_TRY(r.ReadUint8("is_bigendian", &m->is_bigendian));
  SFRT_ROS2_TRY(r.ReadUint32("step", &m->step));
  return ReadBytes(r, "data", &m->data);
}

Status Get(CdrReader& r, Image* m) { return GetImage(r, m); }
Status Get(CdrReader& r, ImageView* m) { return GetImage(r, m); }

Status Get(CdrReader& r, CompressedImage* m) {
  SFRT_ROS2_TRY(GetNested(r, "header", &m->header));
  SFRT_ROS2_TRY(r.ReadString("format", &m->format));
  return r.ReadByteSequence("data", &m->data);
}

Status Get(CdrReader& r, RegionOfInterest* m) {
  SFRT_ROS2_TRY(r.ReadUint32("x_offset", &m->x_offset));
  SFRT_ROS2_TRY(r.ReadUint32("y_offset", &m->y_offset));
  SFRT_ROS2_TRY(r.ReadUint32("height", &m->height));
  SFRT_ROS2_TRY(r.ReadUint32("width", &m->width));
  return r.ReadBool("do_rectify", &m->do_rectify);
}

Status Get(CdrReader& r, CameraInfo* m) {
  SFRT_ROS2_TRY(GetNested(r, "header", &m->header));
  SFRT_ROS2_TRY(r.ReadUint32("height", &m->height));
  SFRT_ROS2_TRY(r.ReadUint32("width", &m->width));
  SFRT_ROS2_TRY(r.ReadString("distortion_model", &m->distortion_model));
  SFRT_ROS2_TRY(r.ReadFloat64Sequence("d", &m->d));
  SFRT_ROS2_TRY(r.ReadFloat64Array("k", m->k));
  SFRT_ROS2_TRY(r.ReadFloat64Array("r", m->r));
  SFRT_ROS2_TRY(r.ReadFloat64Array("p", m->p));
  SFRT_ROS2_TRY(r.ReadUint32("binning_x", &m->binning_x));
  SFRT_ROS2_TRY(r.ReadUint32("binning_y", &m->binning_y));
  return GetNested(r, "roi", &m->roi);
}

Status Get(CdrReader& r, KeyValue* m) {
  SFRT_ROS2_TRY(r.ReadString("key", &m->key));
  return r.ReadString("value", &m->value);
}

Status Get(CdrReader& r, DiagnosticStatus* m) {
  SFRT_ROS2_TRY(r.ReadUint8("level", &m->level));
  SFRT_ROS2_TRY(r.ReadString("name", &m->name));
  SFRT_ROS2_TRY(r.ReadString("message", &m->message));
  SFRT_ROS2_TRY(r.ReadString("hardware_id", &m->hardware_id));
  return GetSequence(r, "values", kMinKeyValueBytes, &m->values);
}

Status Get(CdrReader& r, DiagnosticArray* m) {
  SFRT_ROS2_TRY(GetNested(r, "header", &m->header));
  return GetSequence(r, "status", kMinDiagnosticStatusBytes, &m->status);
}

// Header, fields, then at most the end padding: the whole input is one message.
template <typename T>
Status DecodeMessage(std::span<const uint8_t> bytes, std::string_view type_name, T* out) {
  CdrReader reader(bytes, type_name);
  SFRT_ROS2_TRY(reader.ReadEncapsulation());
  SFRT_ROS2_TRY(Get(reader, out));
  return reader.Finish();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Public entry points.

template <>
const MessageNames& NamesOf<Time>() {
  return GetRegistry().names[kTimeSpec];
}
template <>
const MessageNames& NamesOf<Header>() {
  return GetRegistry().names[kHeaderSpec];
}
template <>
const MessageNames& NamesOf<Image>() {
  return GetRegistry().names[kImageSpec];
}
template <>
const MessageNames& NamesOf<CompressedImage>() {
  return GetRegistry().names[kCompressedImageSpec];
}
template <>
const MessageNames& NamesOf<RegionOfInterest>() {
  return GetRegistry().names[kRegionOfInterestSpec];
}
template <>
const MessageNames& NamesOf<CameraInfo>() {
  return GetRegistry().names[kCameraInfoSpec];
}
template <>
const MessageNames& NamesOf<KeyValue>() {
  return GetRegistry().names[kKeyValueSpec];
}
template <>
const MessageNames& NamesOf<DiagnosticStatus>() {
  return GetRegistry().names[kDiagnosticStatusSpec];
}
template <>
const MessageNames& NamesOf<DiagnosticArray>() {
  return GetRegistry().names[kDiagnosticArraySpec];
}

std::span<const MessageNames> AllMessageNames() { return GetRegistry().names; }

const MessageNames* FindMessageNames(std::string_view ros2_type) {
  for (const MessageNames& names : GetRegistry().names) {
    if (names.ros2_type == ros2_type) return &names;
  }
  return nullptr;
}

void Encode(const Time& message, std::vector<uint8_t>* out) { EncodeMessage(message, out); }
void Encode(const Header& message, std::vector<uint8_t>* out) { EncodeMessage(message, out); }
void Encode(const Image& message, std::vector<uint8_t>* out) { EncodeMessage(message, out); }
void Encode(const ImageView& message, std::vector<uint8_t>* out) { EncodeMessage(message, out); }
void Encode(const CompressedImage& message, std::vector<uint8_t>* out) {
  EncodeMessage(message, out);
}
void Encode(const RegionOfInterest& message, std::vector<uint8_t>* out) {
  EncodeMessage(message, out);
}
void Encode(const CameraInfo& message, std::vector<uint8_t>* out) { EncodeMessage(message, out); }
void Encode(const KeyValue& message, std::vector<uint8_t>* out) { EncodeMessage(message, out); }
void Encode(const DiagnosticStatus& message, std::vector<uint8_t>* out) {
  EncodeMessage(message, out);
}
void Encode(const DiagnosticArray& message, std::vector<uint8_t>* out) {
  EncodeMessage(message, out);
}

Status Decode(std::span<const uint8_t> bytes, Time* out) {
  return DecodeMessage(bytes, NamesOf<Time>().ros2_type, out);
}
Status Decode(std::span<const uint8_t> bytes, Header* out) {
  return DecodeMessage(bytes, NamesOf<Header>().ros2_type, out);
}
Status Decode(std::span<const uint8_t> bytes, Image* out) {
  return DecodeMessage(bytes, NamesOf<Image>().ros2_type, out);
}
Status Decode(std::span<const uint8_t> bytes, CompressedImage* out) {
  return DecodeMessage(bytes, NamesOf<CompressedImage>().ros2_type, out);
}
Status Decode(std::span<const uint8_t> bytes, RegionOfInterest* out) {
  return DecodeMessage(bytes, NamesOf<RegionOfInterest>().ros2_type, out);
}
Status Decode(std::span<const uint8_t> bytes, CameraInfo* out) {
  return DecodeMessage(bytes, NamesOf<CameraInfo>().ros2_type, out);
}
Status Decode(std::span<const uint8_t> bytes, KeyValue* out) {
  return DecodeMessage(bytes, NamesOf<KeyValue>().ros2_type, out);
}
Status Decode(std::span<const uint8_t> bytes, DiagnosticStatus* out) {
  return DecodeMessage(bytes, NamesOf<DiagnosticStatus>().ros2_type, out);
}
Status Decode(std::span<const uint8_t> bytes, DiagnosticArray* out) {
  return DecodeMessage(bytes, NamesOf<DiagnosticArray>().ros2_type, out);
}
Status DecodeImageView(std::span<const uint8_t> bytes, ImageView* out) {
  return DecodeMessage(bytes, NamesOf<Image>().ros2_type, out);
}

}  // namespace sfrt::ros2::msg

#undef SFRT_ROS2_TRY
