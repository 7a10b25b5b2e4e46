// Fault injection on a model file: every bit flipped, every byte overwritten with a few patterns,
// and the file truncated at every length, region by region (file header, vtables, metadata
// tables, metadata strings, layer tables, weights, padding). Each damaged file must be rejected
// with a Status (checksum, verifier or semantic checks) or load a model identical to the
// original (a byte that does not matter, e.g. alignment padding); a model that loads with
// different content must still plan and run without crashing, and is only allowed where the
// format does not promise detection (table fields and strings outside the weights, which the
// CRC-32C does not cover: docs/model-format.md). Nothing may crash.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "common/sceneednet_spec.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/model.h"
#include "sfrt/session.h"
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
  kRegionCount
};
constexpr std::array<const char*, kRegionCount> kRegionNames = {
    "padding",          "file header",  "vtables", "metadata tables",
    "metadata strings", "layer tables", "weights"};

// Which region each byte of a model file belongs to, from a walk of the FlatBuffers structure.
class RegionMap {
 public:
  explicit RegionMap(const std::vector<uint8_t>& file) : base_(file.data()), map_(file.size()) {
    Mark(base_, 8, kFileHeader);  // root offset + file identifier
    const fb::Model* m = fb::GetModel(base_);
    Table(m, kMetadataTables);
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
    << '|' << static_cast<int>(m.weight_type) << '\n';
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
    const char* kind = msg.find("checksum") != std::string::npos                 ? "checksum"
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
  void SetUp() override {
    auto bytes = exporter::SerializeModel(testing::SceneEdNetSpec(64, 7));
    ASSERT_TRUE(bytes.ok()) << bytes.message();
    file_ = std::move(*bytes);
    auto model = Model::LoadBuffer(file_.data(), file_.size(), BufferOwnership::kCopy);
    ASSERT_TRUE(model.ok()) << model.message();
    original_ = Describe(**model);
    regions_ = std::make_unique<RegionMap>(file_);
  }

  // The format promises detection of any damage to the weights (CRC-32C) and to the file
  // header; elsewhere a change may go unnoticed only in a field the format does not protect.
  void ExpectPromisesKept(const std::array<Tally, kRegionCount>& t) const {
    EXPECT_EQ(t[kWeights].loaded_changed + t[kWeights].loaded_identical, 0u)
        << "damaged weights loaded";
    EXPECT_EQ(t[kFileHeader].loaded_changed, 0u) << "a damaged file header loaded changed";
    EXPECT_EQ(t[kPadding].loaded_changed, 0u) << "a padding byte changed the model";
  }

  std::vector<uint8_t> file_;
  std::string original_;
  std::unique_ptr<RegionMap> regions_;
};

TEST_F(ModelFaultInjection, EveryBitFlipIsRejectedOrHarmless) {
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
  const std::string report =
      Report("bit flips in a " + std::to_string(file_.size()) + "-byte SceneEDNet w64 file", t);
  std::printf("%s", report.c_str());
  ExpectPromisesKept(t);
  EXPECT_EQ(t[kWeights].rejected, t[kWeights].reasons["checksum"]) << report;
}

TEST_F(ModelFaultInjection, EveryBytePatternIsRejectedOrHarmless) {
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
  const std::string report =
      Report("bytes set to 00/FF/7F/80 in a " + std::to_string(file_.size()) + "-byte file", t);
  std::printf("%s", report.c_str());
  ExpectPromisesKept(t);
}

TEST_F(ModelFaultInjection, EveryTruncationIsRejected) {
  std::array<Tally, kRegionCount> t{};
  // Truncating at length n loses byte n first; tally by that byte's region.
  for (size_t n = 0; n < file_.size(); ++n) {
    Tally& tally = t[regions_->at(n)];
    ++tally.bytes;
    Classify(file_, n, original_, &tally);
  }
  const std::string report =
      Report("truncation at every length of a " + std::to_string(file_.size()) + "-byte file", t);
  std::printf("%s", report.c_str());
  for (int r = 0; r < kRegionCount; ++r) {
    // Only trailing bytes nothing refers to may be cut off and still load the same model.
    EXPECT_EQ(t[r].loaded_changed, 0u) << kRegionNames[r] << "\n" << report;
    if (r != kPadding) {
      EXPECT_EQ(t[r].loaded_identical, 0u) << kRegionNames[r] << "\n" << report;
    }
  }
}

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
    b.Finish(model.Finish(), fb::ModelIdentifier());
    auto loaded = Model::LoadBuffer(b.GetBufferPointer(), b.GetSize(), BufferOwnership::kCopy, {},
                                    "no-op-table.sfrt");
    ASSERT_FALSE(loaded.ok()) << static_cast<int>(type);
    EXPECT_NE(loaded.message().find("layer 0 'l0': op type " +
                                    std::to_string(static_cast<int>(type)) + " has no op table"),
              std::string::npos)
        << loaded.message();
  }
}

}  // namespace
}  // namespace sfrt
