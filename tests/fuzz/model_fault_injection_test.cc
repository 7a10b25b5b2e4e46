// Fault injection on a model file: every bit flipped, every byte overwritten with a few patterns,
// and the file truncated at every length, region by region (file header, vtables, metadata
// tables, metadata strings, layer tables, weights, padding, and in 1.1 files the file checksum
// field itself). Nothing may crash.
// - Schema 1.1 files carry a CRC-32C of the whole file (Model.file_crc32c): every damaged file
//   must be rejected, in every region.
// - Schema 1.0 files (still read) have only the weights' CRC-32C: a damaged file must be rejected
//   or load a model identical to the original (a byte that does not matter, e.g. alignment
//   padding); a model that loads with different content must still plan and run without
//   crashing, and is only allowed where 1.0 does not promise detection (table fields and strings
//   outside the weights: docs/model-format.md).
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "common/model_builders.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/sceneednet_spec.h"
#include "sfrt/model.h"
#include "sfrt/session.h"
#include "sfrt/shapes.h"
#include "sfrt_model_generated.h"

namespace sfrt {
namespace {

namespace fb = ::sfrt::schema;

enum Region {
  kPadding,  // referenced by nothing
  kFileHeader,
  kVtables,
  kMetadataTables,
  kMetadataStrings,
  kLayerTables,
  kWeights,
  kFileChecksum,  // the 4 bytes of Model.file_crc32c (1.1)
  kRegionCount
};
constexpr std::array<const char*, kRegionCount> kRegionNames = {
    "padding",          "file header",  "vtables", "metadata tables",
    "metadata strings", "layer tables", "weights", "file checksum field"};

// Which region each byte of a model file belongs to, from a walk of the FlatBuffers structure.
class RegionMap {
 public:
  explicit RegionMap(const std::vector<uint8_t>& file) : base_(file.data()), map_(file.size()) {
    Mark(base_, 8, kFileHeader);  // root offset + file identifier
    const fb::Model* m = fb::GetModel(base_);
    Table(m, kMetadataTables);
    if (const uint8_t* crc = reinterpret_cast<const flatbuffers::Table*>(m)->GetAddressOf(
            fb::Model::VT_FILE_CRC32C)) {
      Mark(crc, 4, kFileChecksum);
    }
    String(m->name(), kMetadataStrings);
    if (const auto* p = m->producer()) {
      Table(p, kMetadataTables);
      for (const auto* s :
           {p->exporter_version(), p->source_format(), p->source_file(), p->source_sha256()}) {
        String(s, kMetadataStrings);
      }
    }
    if (const auto* in = m->input()) {
      Table(in, kMetadataTables);
      String(in->name(), kMetadataStrings);
      Vector(in->image_order(), 1, kMetadataTables);
      Vector(in->mean(), 4, kMetadataTables);
      Vector(in->std(), 4, kMetadataTables);
    }
    if (const auto* out = m->output()) {
      Table(out, kMetadataTables);
      String(out->name(), kMetadataStrings);
      String(out->units(), kMetadataStrings);
      if (out->channel_names() != nullptr) {
        Vector(out->channel_names(), 4, kMetadataTables);
        for (const auto* s : *out->channel_names()) String(s, kMetadataStrings);
      }
    }
    if (const auto* cam = m->camera()) Table(cam, kMetadataTables);
    Vector(m->layers(), 4, kLayerTables);
    for (const fb::Layer* l : *m->layers()) {
      Table(l, kLayerTables);
      String(l->name(), kLayerTables);
      if (const auto* c = l->op_as_Conv2D()) {
        Table(c, kLayerTables);
        for (const fb::Tensor* t : {c->weights(), c->bias()}) {
          Table(t, kLayerTables);
          Vector(t->shape(), 4, kLayerTables);
          Mark(reinterpret_cast<const uint8_t*>(t->data()), 4, kLayerTables);  // length
          Mark(t->data()->data(), t->data()->size(), kWeights);
        }
      } else if (const auto* u = l->op_as_Upsample()) {
        Table(u, kLayerTables);
      } else if (const auto* cr = l->op_as_Crop()) {
        Table(cr, kLayerTables);
      }
    }
  }

  Region at(size_t i) const { return map_[i]; }

 private:
  void Mark(const void* p, size_t n, Region r) {
    const size_t at = static_cast<const uint8_t*>(p) - base_;
    for (size_t i = at; i < at + n && i < map_.size(); ++i) map_[i] = r;
  }
  template <typename T>
  void Table(const T* t, Region r) {
    const auto* table = reinterpret_cast<const flatbuffers::Table*>(t);
    const uint8_t* vt = table->GetVTable();
    Mark(vt, flatbuffers::ReadScalar<uint16_t>(vt), kVtables);
    Mark(table, flatbuffers::ReadScalar<uint16_t>(vt + 2), r);
  }
  void String(const flatbuffers::String* s, Region r) {
    if (s != nullptr) Mark(reinterpret_cast<const uint8_t*>(s), 4 + s->size() + 1, r);
  }
  template <typename V>
  void Vector(const V* v, size_t elem, Region r) {
    if (v != nullptr) Mark(reinterpret_cast<const uint8_t*>(v), 4 + v->size() * elem, r);
  }

  const uint8_t* base_;
  std::vector<Region> map_;
};

// Everything a loaded model means, as text (weights as raw bytes), to compare two loads.
std::string Describe(const Model& model) {
  std::ostringstream s;
  const ModelMetadata& m = model.metadata();
  s << m.name << '|' << m.schema_major << '.' << m.schema_minor << '|' << m.exporter_version << '|'
    << m.source_format << '|' << m.source_file << '|' << m.source_sha256 << '|' << m.weights_crc32c
    << '|' << m.file_crc32c.value_or(0) << '|' << m.file_crc32c.has_value() << '|'
    << static_cast<int>(m.weight_type) << '\n';
  const InputDesc& in = m.input;
  s << in.name << '|' << in.channels << '|' << in.color_order << '|' << in.scale << '|'
    << in.traced_height << 'x' << in.traced_width;
  for (const auto& o : in.image_order) s << '|' << o;
  for (int c = 0; c < 3; ++c) s << '|' << in.mean[c] << '/' << in.std[c];
  s << '\n' << m.output.name << '|' << m.output.channels << '|' << m.output.units;
  for (const auto& n : m.output.channel_names) s << '|' << n;
  s << '\n'
    << m.camera.focal_px << '|' << m.camera.baseline << '|' << m.camera.cx << '|' << m.camera.cy
    << '\n';
  for (const LayerDesc& l : model.layers()) {
    s << l.name << '|' << static_cast<int>(l.kind) << '|';
    if (l.kind == LayerKind::kConv2D) {
      const ConvParams& c = l.conv;
      s << c.in_channels << ',' << c.out_channels << ',' << c.kernel_h << ',' << c.kernel_w << ','
        << c.stride_h << ',' << c.stride_w << ',' << static_cast<int>(c.padding_rule) << ','
        << c.pads.top << ',' << c.pads.left << ',' << c.pads.bottom << ',' << c.pads.right << ','
        << static_cast<int>(c.activation) << ',' << c.leaky_slope << ',';
      const size_t count =
          static_cast<size_t>(c.kernel_h) * c.kernel_w * c.in_channels * c.out_channels;
      s.write(reinterpret_cast<const char*>(c.weights), count * sizeof(float));
      s.write(reinterpret_cast<const char*>(c.bias), c.out_channels * sizeof(float));
    } else if (l.kind == LayerKind::kUpsample) {
      s << l.upsample.factor_h << ',' << l.upsample.factor_w;
    } else {
      const CropParams& c = l.crop;
      s << static_cast<int>(c.rule) << ',' << c.amounts.top << ',' << c.amounts.left << ','
        << c.amounts.bottom << ',' << c.amounts.right << ',' << c.excess_rows_from_top << ','
        << c.excess_cols_from_left;
    }
    s << '\n';
  }
  return s.str();
}

struct Tally {
  size_t bytes = 0;
  size_t cases = 0;
  size_t rejected = 0;
  size_t loaded_identical = 0;
  size_t loaded_changed = 0;
  size_t changed_ran = 0;                 // of loaded_changed: a Session was planned and ran
  std::map<std::string, size_t> reasons;  // rejection message kind -> count
};

// Loads `bytes`; a model that loads with a different meaning must plan and run at a small size.
void Classify(const std::vector<uint8_t>& bytes, size_t size, const std::string& original,
              Tally* t) {
  ++t->cases;
  auto model = Model::LoadBuffer(bytes.data(), size, BufferOwnership::kCopy, {}, "damaged");
  if (!model.ok()) {
    ++t->rejected;
    const std::string& msg = model.message();
    const char* kind = msg.find("file checksum") != std::string::npos            ? "file-crc"
                       : msg.find("checksum") != std::string::npos               ? "checksum"
                       : msg.find("FlatBuffers") != std::string::npos            ? "verifier"
                       : msg.find("header does not verify") != std::string::npos ? "verifier"
                       : msg.find("identifier") != std::string::npos             ? "identifier"
                       : msg.find("schema version") != std::string::npos         ? "version"
                       : msg.find("too small") != std::string::npos              ? "size"
                                                                                 : "semantic";
    ++t->reasons[kind];
    return;
  }
  if (Describe(**model) == original) {
    ++t->loaded_identical;
    return;
  }
  ++t->loaded_changed;
  SessionOptions options;
  options.max_height = 16;
  options.max_width = 16;
  auto session = Session::Create(*model, options);
  if (!session.ok()) return;
  auto shape = (*session)->OutputShape(16, 16);
  if (!shape.ok()) return;
  std::vector<float> input(16 * 16 * static_cast<size_t>((*model)->metadata().input.channels));
  std::vector<float> output(shape->elements());
  if ((*session)->Run(input, 16, 16, output).ok()) ++t->changed_ran;
}

std::string Report(const std::string& fault, const std::array<Tally, kRegionCount>& tallies) {
  std::ostringstream s;
  s << fault << ":\n";
  for (int r = 0; r < kRegionCount; ++r) {
    const Tally& t = tallies[r];
    if (t.bytes == 0) continue;
    s << "  " << kRegionNames[r] << ": " << t.bytes << " bytes, " << t.cases << " cases, "
      << t.rejected << " rejected (";
    for (const auto& [k, n] : t.reasons) s << k << ' ' << n << ' ';
    s << "), " << t.loaded_identical << " loaded identical, " << t.loaded_changed
      << " loaded changed (" << t.changed_ran << " of them ran)\n";
  }
  return s.str();
}

class ModelFaultInjection : public ::testing::Test {
 protected:
  // Writes SceneEDNet w64 in schema 1.`minor`.
  void Prepare(int minor) {
    exporter::SerializeOptions options;
    options.schema_minor = minor;
    auto bytes = exporter::SerializeModel(exporter::SceneEdNetSpec(64, 7), options);
    ASSERT_TRUE(bytes.ok()) << bytes.message();
    file_ = std::move(*bytes);
    auto model = Model::LoadBuffer(file_.data(), file_.size(), BufferOwnership::kCopy);
    ASSERT_TRUE(model.ok()) << model.message();
    ASSERT_EQ((*model)->metadata().schema_minor, minor);
    ASSERT_EQ((*model)->metadata().file_crc32c.has_value(), minor >= 1);
    original_ = Describe(**model);
    regions_ = std::make_unique<RegionMap>(file_);
    label_ = std::to_string(file_.size()) + "-byte SceneEDNet w64 file, schema 1." +
             std::to_string(minor);
  }

  std::array<Tally, kRegionCount> BitFlips() const {
    std::array<Tally, kRegionCount> t{};
    std::vector<uint8_t> damaged = file_;
    for (size_t i = 0; i < file_.size(); ++i) {
      Tally& tally = t[regions_->at(i)];
      ++tally.bytes;
      for (int bit = 0; bit < 8; ++bit) {
        damaged[i] = static_cast<uint8_t>(file_[i] ^ (1u << bit));
        Classify(damaged, damaged.size(), original_, &tally);
      }
      damaged[i] = file_[i];
    }
    return t;
  }

  std::array<Tally, kRegionCount> BytePatterns() const {
    std::array<Tally, kRegionCount> t{};
    std::vector<uint8_t> damaged = file_;
    for (size_t i = 0; i < file_.size(); ++i) {
      Tally& tally = t[regions_->at(i)];
      ++tally.bytes;
      for (uint8_t pattern : {0x00, 0xFF, 0x7F, 0x80}) {
        if (pattern == file_[i]) continue;
        damaged[i] = pattern;
        Classify(damaged, damaged.size(), original_, &tally);
      }
      damaged[i] = file_[i];
    }
    return t;
  }

  // Truncating at length n loses byte n first; tallied by that byte's region.
  std::array<Tally, kRegionCount> Truncations() const {
    std::array<Tally, kRegionCount> t{};
    for (size_t n = 0; n < file_.size(); ++n) {
      Tally& tally = t[regions_->at(n)];
      ++tally.bytes;
      Classify(file_, n, original_, &tally);
    }
    return t;
  }

  // 1.0 promises detection of any damage to the weights (CRC-32C) and to the file header;
  // elsewhere a change may go unnoticed only in a field the format does not protect.
  static void ExpectSchema10PromisesKept(const std::array<Tally, kRegionCount>& t) {
    EXPECT_EQ(t[kWeights].loaded_changed + t[kWeights].loaded_identical, 0u)
        << "damaged weights loaded";
    EXPECT_EQ(t[kFileHeader].loaded_changed, 0u) << "a damaged file header loaded changed";
    EXPECT_EQ(t[kPadding].loaded_changed, 0u) << "a padding byte changed the model";
  }

  // 1.1 promises detection of any damage anywhere.
  static void ExpectEveryCaseRejected(const std::array<Tally, kRegionCount>& t,
                                      const std::string& report) {
    size_t cases = 0;
    for (int r = 0; r < kRegionCount; ++r) {
      cases += t[r].cases;
      EXPECT_EQ(t[r].rejected, t[r].cases) << kRegionNames[r] << "\n" << report;
      EXPECT_EQ(t[r].loaded_identical + t[r].loaded_changed, 0u) << kRegionNames[r];
    }
    EXPECT_GT(cases, 0u);
    for (int r : {kPadding, kMetadataTables, kMetadataStrings, kLayerTables, kWeights}) {
      EXPECT_GT(t[r].bytes, 0u) << "no " << kRegionNames[r] << " bytes to damage";
    }
  }

  std::vector<uint8_t> file_;
  std::string original_;
  std::string label_;
  std::unique_ptr<RegionMap> regions_;
};

TEST_F(ModelFaultInjection, Schema11EveryBitFlipIsRejected) {
  ASSERT_NO_FATAL_FAILURE(Prepare(1));
  auto t = BitFlips();
  const std::string report = Report("bit flips in a " + label_, t);
  std::printf("%s", report.c_str());
  ExpectEveryCaseRejected(t, report);
  EXPECT_EQ(t[kLayerTables].reasons["file-crc"], t[kLayerTables].cases) << report;
  EXPECT_EQ(t[kWeights].reasons["file-crc"], t[kWeights].cases) << report;
  EXPECT_EQ(t[kPadding].reasons["file-crc"], t[kPadding].cases) << report;
}

TEST_F(ModelFaultInjection, Schema11EveryBytePatternIsRejected) {
  ASSERT_NO_FATAL_FAILURE(Prepare(1));
  auto t = BytePatterns();
  const std::string report = Report("bytes set to 00/FF/7F/80 in a " + label_, t);
  std::printf("%s", report.c_str());
  ExpectEveryCaseRejected(t, report);
}

TEST_F(ModelFaultInjection, Schema11EveryTruncationIsRejected) {
  ASSERT_NO_FATAL_FAILURE(Prepare(1));
  auto t = Truncations();
  const std::string report = Report("truncation at every length of a " + label_, t);
  std::printf("%s", report.c_str());
  ExpectEveryCaseRejected(t, report);
}

TEST_F(ModelFaultInjection, Schema11BytesAppendedAfterTheFileAreRejected) {
  ASSERT_NO_FATAL_FAILURE(Prepare(1));
  std::vector<uint8_t> longer = file_;
  longer.resize(file_.size() + 64, 0);
  auto model =
      Model::LoadBuffer(longer.data(), longer.size(), BufferOwnership::kCopy, {}, "m.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("file checksum mismatch"), std::string::npos) << model.message();
}

TEST_F(ModelFaultInjection, Schema11MismatchNamesTheFileAndBothChecksums) {
  ASSERT_NO_FATAL_FAILURE(Prepare(1));
  auto good = Model::LoadBuffer(file_.data(), file_.size(), BufferOwnership::kCopy);
  ASSERT_TRUE(good.ok()) << good.message();
  const uint32_t recorded = *(*good)->metadata().file_crc32c;
  // Damage the model's name, which no other check looks at.
  std::vector<uint8_t> damaged = file_;
  const auto* name = fb::GetModel(damaged.data())->name();
  ASSERT_NE(name, nullptr);
  damaged[static_cast<size_t>(reinterpret_cast<const uint8_t*>(name->c_str()) - damaged.data())] ^=
      0x01;
  const auto path = std::filesystem::temp_directory_path() /
                    ("sfrt_fault_" + std::to_string(::getpid()) + "_name.sfrt");
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(damaged.data()),
             static_cast<std::streamsize>(damaged.size()));
  auto model = Model::LoadFile(path.string());
  std::filesystem::remove(path);
  ASSERT_FALSE(model.ok());
  char recorded_hex[16];
  std::snprintf(recorded_hex, sizeof(recorded_hex), "0x%08x", recorded);
  const std::string& m = model.message();
  EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  EXPECT_EQ(
      m.rfind(path.string() + ": file checksum mismatch: the file records CRC-32C " + recorded_hex +
                  " but its " + std::to_string(damaged.size()) + " bytes give 0x",
              0),
      0u)
      << m;
  // Without verification the damaged name loads: the checksum, not another check, caught it.
  auto unchecked = Model::LoadBuffer(damaged.data(), damaged.size(), BufferOwnership::kCopy,
                                     LoadOptions{.verify_checksum = false});
  EXPECT_TRUE(unchecked.ok()) << unchecked.message();
}

TEST_F(ModelFaultInjection, Schema11FileWithoutItsChecksumFieldIsRejected) {
  // A 1.0 layout relabelled 1.1: what a 1.1 file whose vtable lost the field looks like.
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  std::vector<uint8_t> relabelled = file_;
  fb::GetMutableModel(relabelled.data())->mutable_version()->mutate_minor(1);
  auto model =
      Model::LoadBuffer(relabelled.data(), relabelled.size(), BufferOwnership::kCopy, {}, "m.sfrt");
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.message().find("m.sfrt: model file has schema version 1.1 but no file checksum"),
            std::string::npos)
      << model.message();
}

TEST_F(ModelFaultInjection, Schema10FileLoadsWithItsWeightsChecksumOnly) {
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  auto model = Model::LoadBuffer(file_.data(), file_.size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_EQ((*model)->metadata().schema_minor, 0);
  EXPECT_FALSE((*model)->metadata().file_crc32c.has_value());
  // The same model in 1.1 has the same layers and weights.
  auto v11 = testing::LoadOrDie(exporter::SceneEdNetSpec(64, 7));
  ASSERT_NE(v11, nullptr);
  EXPECT_EQ((*model)->metadata().weights_crc32c, v11->metadata().weights_crc32c);
  EXPECT_EQ((*model)->parameter_count(), v11->parameter_count());
}

TEST(ModelFileDamage, CommittedSchema10DemoModelStillLoads) {
  // The demo model as it was committed before schema 1.1 (tools/demo/ now holds a 1.2 re-stamp).
  const std::string path =
      std::string(SFRT_SOURCE_DIR) + "/tests/data/models/sceneednet-w16-demo-schema-1.0.sfrt";
  auto model = Model::LoadFile(path);
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_EQ((*model)->metadata().schema_major, 1);
  EXPECT_EQ((*model)->metadata().schema_minor, 0);
  EXPECT_FALSE((*model)->metadata().file_crc32c.has_value());
}

TEST_F(ModelFaultInjection, Schema10EveryBitFlipIsRejectedOrHarmless) {
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  auto t = BitFlips();
  const std::string report = Report("bit flips in a " + label_, t);
  std::printf("%s", report.c_str());
  ExpectSchema10PromisesKept(t);
  EXPECT_EQ(t[kWeights].rejected, t[kWeights].reasons["checksum"]) << report;
}

TEST_F(ModelFaultInjection, Schema10EveryBytePatternIsRejectedOrHarmless) {
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  auto t = BytePatterns();
  const std::string report = Report("bytes set to 00/FF/7F/80 in a " + label_, t);
  std::printf("%s", report.c_str());
  ExpectSchema10PromisesKept(t);
}

TEST_F(ModelFaultInjection, Schema10EveryTruncationIsRejected) {
  ASSERT_NO_FATAL_FAILURE(Prepare(0));
  auto t = Truncations();
  const std::string report = Report("truncation at every length of a " + label_, t);
  std::printf("%s", report.c_str());
  for (int r = 0; r < kRegionCount; ++r) {
    // Only trailing bytes nothing refers to may be cut off and still load the same model.
    EXPECT_EQ(t[r].loaded_changed, 0u) << kRegionNames[r] << "\n" << report;
    if (r != kPadding) {
      EXPECT_EQ(t[r].loaded_identical, 0u) << kRegionNames[r] << "\n" << report;
    }
  }
}

// ---- Limits (docs/reliability.md, "Limits"): what happens at each, without overflow.

TEST(ModelLimits, FileAboveTheTwoGiBFormatLimitIsRejectedNamingTheLimit) {
  // A sparse file one byte over FlatBuffers' limit (2^31 - 1 bytes): nothing is read from it.
  const auto path = std::filesystem::temp_directory_path() /
                    ("sfrt_limits_" + std::to_string(::getpid()) + "_big.sfrt");
  {
    std::ofstream out(path, std::ios::binary);
    out.write("\0\0\0\0SFRT", 8);
  }
  std::filesystem::resize_file(path, FLATBUFFERS_MAX_BUFFER_SIZE + 1);
  auto model = Model::LoadFile(path.string());
  std::filesystem::remove(path);
  ASSERT_FALSE(model.ok());
  EXPECT_EQ(model.message(), path.string() + ": file is " +
                                 std::to_string(FLATBUFFERS_MAX_BUFFER_SIZE + 1) +
                                 " bytes, above the 2 GiB format limit");
}

TEST(ModelLimits, InputSideAboveTheLimitIsRejectedWithoutOverflow) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(64, 7));
  ASSERT_NE(model, nullptr);
  for (const auto& [h, w] : {std::pair{kMaxTensorSide + 1, 16}, std::pair{16, kMaxTensorSide + 1},
                             std::pair{std::numeric_limits<int>::max(), 16}}) {
    SessionOptions options;
    options.max_height = h;
    options.max_width = w;
    auto session = Session::Create(model, options);
    ASSERT_FALSE(session.ok()) << h << "x" << w;
    EXPECT_NE(session.message().find("exceeds the largest supported side, 1048576"),
              std::string::npos)
        << session.message();
  }
}

TEST(ModelLimits, UpsamplingPastTheLimitIsRejectedNamingTheLayer) {
  exporter::ModelSpec spec = exporter::SceneEdNetSpec(64, 7);
  for (int k = 0; k < 4; ++k) {
    spec.layers.insert(spec.layers.begin(),
                       exporter::UpsampleSpec{"up" + std::to_string(k), 64, 64, {}});
  }
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  SessionOptions options;
  options.max_height = 16;
  options.max_width = 16;
  auto session = Session::Create(model, options);
  ASSERT_FALSE(session.ok());
  // 16 -> 1024 -> 65536 -> 4194304: the third upsampling is over 2^20.
  EXPECT_NE(session.message().find("layer 2 'up1': upsampling 65536x65536 by 64x64 exceeds the "
                                   "largest supported side, 1048576"),
            std::string::npos)
      << session.message();
}

TEST(ModelLimits, HugeExplicitCropIsRejectedWithoutOverflow) {
  exporter::ModelSpec spec = exporter::SceneEdNetSpec(64, 7);
  exporter::CropSpec crop;
  crop.name = "greedy";
  crop.rule = CropRule::kExplicit;
  const int big = std::numeric_limits<int>::max();
  crop.amounts = {big, big, big, big};
  spec.layers.push_back(crop);
  auto model = testing::LoadOrDie(spec);
  ASSERT_NE(model, nullptr);
  SessionOptions options;
  options.max_height = 32;
  options.max_width = 32;
  auto session = Session::Create(model, options);
  ASSERT_FALSE(session.ok());
  EXPECT_NE(session.message().find("'greedy': removes everything of a 32x32 input"),
            std::string::npos)
      << session.message();
}

#if !defined(__SANITIZE_ADDRESS__)
// Not under ASan, which aborts on an allocation this large instead of returning null.
TEST(ModelLimits, ArenaThatCannotBeAllocatedIsAnErrorNamingItsSize) {
  auto model = testing::LoadOrDie(exporter::SceneEdNetSpec(64, 7));
  ASSERT_NE(model, nullptr);
  SessionOptions options;
  options.max_height = kMaxTensorSide;  // a few TiB of arena at the largest side
  options.max_width = kMaxTensorSide;
  auto session = Session::Create(model, options);
  ASSERT_FALSE(session.ok());
  EXPECT_NE(session.message().find("-byte arena for 1048576x1048576 inputs"), std::string::npos)
      << session.message();
}
#endif

// Found by fuzz_model_session (regression/model_session/crash-union-type-without-table.sfrt):
// the FlatBuffers verifier accepts a layer whose op_type is set but whose op table is absent, and
// the loader dereferenced the missing table.
TEST(ModelFileDamage, LayerWithOpTypeButNoOpTableIsRejected) {
  for (fb::LayerOp type : {fb::LayerOp::Conv2D, fb::LayerOp::Upsample, fb::LayerOp::Crop}) {
    flatbuffers::FlatBufferBuilder b;
    const auto name = b.CreateString("l0");
    fb::LayerBuilder layer(b);
    layer.add_name(name);
    layer.add_op_type(type);
    const auto layer_offset = layer.Finish();
    const auto layers = b.CreateVector(std::vector{layer_offset});
    fb::InputDescBuilder input(b);
    input.add_channels(12);
    const auto input_offset = input.Finish();
    const fb::Version version(kSchemaVersionMajor, kSchemaVersionMinor);
    fb::ModelBuilder model(b);
    model.add_version(&version);
    model.add_input(input_offset);
    model.add_layers(layers);
    model.add_file_crc32c(0xFFFFFFFFu);  // a crafted file carries a valid file checksum
    b.Finish(model.Finish(), fb::ModelIdentifier());
    std::vector<uint8_t> file(b.GetBufferPointer(), b.GetBufferPointer() + b.GetSize());
    ASSERT_TRUE(exporter::UpdateFileChecksum(file).ok());
    auto loaded =
        Model::LoadBuffer(file.data(), file.size(), BufferOwnership::kCopy, {}, "no-op-table.sfrt");
    ASSERT_FALSE(loaded.ok()) << static_cast<int>(type);
    EXPECT_NE(loaded.message().find("layer 0 'l0': op type " +
                                    std::to_string(static_cast<int>(type)) + " has no op table"),
              std::string::npos)
        << loaded.message();
  }
}

}  // namespace
}  // namespace sfrt
