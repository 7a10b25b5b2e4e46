// ImportOnnx on small ONNX graphs built here with the onnx protobuf API (no Python needed).
#include "sfrt/exporter/onnx_importer.h"

#include <gtest/gtest.h>
#include <onnx/onnx_pb.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <string>
#include <variant>
#include <vector>

#include "sfrt/exporter/model_writer.h"
#include "sfrt/model.h"
#include "sfrt/model_limits.h"

namespace sfrt::exporter {
namespace {

// Per-test scratch directory (unique per process and test, removed after the test).
std::filesystem::path& TestDir() {
  static std::filesystem::path dir;
  return dir;
}

class OnnxImporter : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    TestDir() = std::filesystem::path(::testing::TempDir()) /
                ("sfrt_onnx_importer_test_" + std::to_string(::getpid()) + "_" + info->name());
    std::filesystem::create_directories(TestDir());
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(TestDir(), ec);
  }
};

constexpr int64_t kInt64Max = std::numeric_limits<int64_t>::max();
constexpr int64_t kInt64Min = std::numeric_limits<int64_t>::min();

void SetInt(onnx::NodeProto& n, const std::string& name, int64_t v) {
  auto* a = n.add_attribute();
  a->set_name(name);
  a->set_type(onnx::AttributeProto::INT);
  a->set_i(v);
}

void SetInts(onnx::NodeProto& n, const std::string& name, const std::vector<int64_t>& v) {
  auto* a = n.add_attribute();
  a->set_name(name);
  a->set_type(onnx::AttributeProto::INTS);
  for (int64_t x : v) a->add_ints(x);
}

void SetFloat(onnx::NodeProto& n, const std::string& name, float v) {
  auto* a = n.add_attribute();
  a->set_name(name);
  a->set_type(onnx::AttributeProto::FLOAT);
  a->set_f(v);
}

void SetString(onnx::NodeProto& n, const std::string& name, const std::string& v) {
  auto* a = n.add_attribute();
  a->set_name(name);
  a->set_type(onnx::AttributeProto::STRING);
  a->set_s(v);
}

// Deterministic conv weights: element i of the OIHW tensor is WeightValue(i).
float WeightValue(int64_t i) { return 0.001f * static_cast<float>(i) - 0.25f; }
float BiasValue(int64_t co) { return 0.5f + static_cast<float>(co); }

// Builds a ModelProto. Tensors are named by the caller; nodes are appended in order.
class OnnxModel {
 public:
  explicit OnnxModel(int64_t opset = 13) {
    proto_.set_ir_version(8);
    proto_.set_producer_name("onnx_importer_test");
    auto* op = proto_.add_opset_import();
    op->set_domain("");
    op->set_version(opset);
    proto_.mutable_graph()->set_name("test");
  }

  onnx::ModelProto& proto() { return proto_; }
  onnx::GraphProto& graph() { return *proto_.mutable_graph(); }

  void Input(const std::string& name, const std::vector<int64_t>& dims,
             int elem_type = onnx::TensorProto::FLOAT) {
    auto* in = graph().add_input();
    in->set_name(name);
    auto* tt = in->mutable_type()->mutable_tensor_type();
    tt->set_elem_type(elem_type);
    for (int64_t d : dims) tt->mutable_shape()->add_dim()->set_dim_value(d);
  }

  void Output(const std::string& name, int elem_type = onnx::TensorProto::FLOAT) {
    auto* out = graph().add_output();
    out->set_name(name);
    out->mutable_type()->mutable_tensor_type()->set_elem_type(elem_type);
  }

  // A scalar INT8 initialiser stored as raw_data (one byte, two's complement).
  void Int8(const std::string& name, int8_t value) {
    auto* t = graph().add_initializer();
    t->set_name(name);
    t->set_data_type(onnx::TensorProto::INT8);
    t->set_raw_data(std::string(1, static_cast<char>(value)));
  }

  // Float initialiser, stored as raw_data (as torch writes it) or as float_data.
  void Floats(const std::string& name, const std::vector<int64_t>& dims,
              const std::vector<float>& values, bool raw = true) {
    auto* t = graph().add_initializer();
    t->set_name(name);
    FillFloats(*t, dims, values, raw);
  }

  void Int64s(const std::string& name, const std::vector<int64_t>& values) {
    auto* t = graph().add_initializer();
    t->set_name(name);
    t->set_data_type(onnx::TensorProto::INT64);
    t->add_dims(static_cast<int64_t>(values.size()));
    for (int64_t v : values) t->add_int64_data(v);
  }

  void Int32s(const std::string& name, const std::vector<int32_t>& values) {
    auto* t = graph().add_initializer();
    t->set_name(name);
    t->set_data_type(onnx::TensorProto::INT32);
    t->add_dims(static_cast<int64_t>(values.size()));
    for (int32_t v : values) t->add_int32_data(v);
  }

  // A Constant node holding an int64 tensor (scalar when `scalar`).
  void ConstInt64s(const std::string& output, const std::vector<int64_t>& values,
                   bool scalar = false) {
    auto& n = Node("Constant", {}, {output}, output + "_node");
    auto* a = n.add_attribute();
    a->set_name("value");
    a->set_type(onnx::AttributeProto::TENSOR);
    auto* t = a->mutable_t();
    t->set_data_type(onnx::TensorProto::INT64);
    if (!scalar) t->add_dims(static_cast<int64_t>(values.size()));
    std::string raw;
    for (int64_t v : values) {
      for (int b = 0; b < 8; ++b)
        raw.push_back(static_cast<char>((static_cast<uint64_t>(v) >> (8 * b)) & 0xff));
    }
    t->set_raw_data(raw);
  }

  void ConstFloats(const std::string& output, const std::vector<int64_t>& dims,
                   const std::vector<float>& values) {
    auto& n = Node("Constant", {}, {output}, output + "_node");
    auto* a = n.add_attribute();
    a->set_name("value");
    a->set_type(onnx::AttributeProto::TENSOR);
    FillFloats(*a->mutable_t(), dims, values, true);
  }

  onnx::NodeProto& Node(const std::string& op, const std::vector<std::string>& inputs,
                        const std::vector<std::string>& outputs, const std::string& name = "") {
    auto* n = graph().add_node();
    n->set_op_type(op);
    n->set_name(name);
    for (const auto& i : inputs) n->add_input(i);
    for (const auto& o : outputs) n->add_output(o);
    return *n;
  }

  // Conv with deterministic OIHW weights "<name>.w" and bias "<name>.b" (unless !bias).
  onnx::NodeProto& Conv(const std::string& name, const std::string& in, const std::string& out,
                        int64_t cin, int64_t cout, int64_t k, int64_t stride,
                        const std::vector<int64_t>& pads, bool bias = true) {
    std::vector<float> w(static_cast<size_t>(cout * cin * k * k));
    for (size_t i = 0; i < w.size(); ++i) w[i] = WeightValue(static_cast<int64_t>(i));
    Floats(name + ".w", {cout, cin, k, k}, w);
    std::vector<std::string> inputs = {in, name + ".w"};
    if (bias) {
      std::vector<float> b(static_cast<size_t>(cout));
      for (int64_t co = 0; co < cout; ++co) b[co] = BiasValue(co);
      Floats(name + ".b", {cout}, b);
      inputs.push_back(name + ".b");
    }
    auto& n = Node("Conv", inputs, {out}, name);
    SetInts(n, "kernel_shape", {k, k});
    SetInts(n, "strides", {stride, stride});
    if (!pads.empty()) SetInts(n, "pads", pads);
    return n;
  }

  // Writes the model into the test's temporary directory and returns the path.
  std::string Save(const std::string& file) const {
    const std::string path = (TestDir() / file).string();
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    EXPECT_TRUE(proto_.SerializeToOstream(&f)) << path;
    return path;
  }

 private:
  static void FillFloats(onnx::TensorProto& t, const std::vector<int64_t>& dims,
                         const std::vector<float>& values, bool raw) {
    t.set_data_type(onnx::TensorProto::FLOAT);
    for (int64_t d : dims) t.add_dims(d);
    if (raw) {
      std::string bytes(values.size() * 4, '\0');
      for (size_t i = 0; i < values.size(); ++i) {
        uint32_t u = 0;
        std::memcpy(&u, &values[i], 4);
        for (int b = 0; b < 4; ++b) bytes[4 * i + b] = static_cast<char>((u >> (8 * b)) & 0xff);
      }
      t.set_raw_data(bytes);
    } else {
      for (float v : values) t.add_float_data(v);
    }
  }

  onnx::ModelProto proto_;
};

template <typename T>
const T& LayerAs(const ModelSpec& spec, size_t i) {
  EXPECT_LT(i, spec.layers.size());
  EXPECT_TRUE(std::holds_alternative<T>(spec.layers.at(i))) << "layer " << i;
  return std::get<T>(spec.layers.at(i));
}

// The import fails with a one-line message naming the file and containing every `part`.
void ExpectImportError(const std::string& path, std::initializer_list<std::string> parts,
                       const OnnxImportOptions& options = {}) {
  const Result<ModelSpec> r = ImportOnnx(path, options);
  ASSERT_FALSE(r.ok()) << "import of " << path << " unexpectedly succeeded";
  const std::string& m = r.message();
  EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  EXPECT_NE(m.find(path), std::string::npos) << "file not named in: " << m;
  for (const std::string& part : parts) {
    EXPECT_NE(m.find(part), std::string::npos) << "'" << part << "' missing in: " << m;
  }
}

Result<ModelSpec> ImportOk(const std::string& path, const OnnxImportOptions& options = {}) {
  Result<ModelSpec> r = ImportOnnx(path, options);
  EXPECT_TRUE(r.ok()) << r.message();
  return r;
}

// ------------------------------------------------------------------------------ conv chains

TEST_F(OnnxImporter, ImportsConvLeakyReluChainWithHwioWeights) {
  OnnxModel m;
  m.Input("x", {1, 3, 8, 10});
  m.Conv("enc0", "x", "t", 3, 4, 3, 1, {1, 1, 1, 1});
  SetFloat(m.Node("LeakyRelu", {"t"}, {"y"}, "enc0_act"), "alpha", 0.2f);
  m.Output("y");
  const std::string path = m.Save("chain.onnx");
  auto spec = ImportOk(path);
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 1u);
  const auto& c = LayerAs<ConvSpec>(*spec, 0);
  EXPECT_EQ(c.name, "enc0");
  EXPECT_EQ(c.in_channels, 3);
  EXPECT_EQ(c.out_channels, 4);
  EXPECT_EQ(c.kernel_h, 3);
  EXPECT_EQ(c.kernel_w, 3);
  EXPECT_EQ(c.stride_h, 1);
  EXPECT_EQ(c.stride_w, 1);
  EXPECT_EQ(c.pads, (Pads{1, 1, 1, 1}));
  EXPECT_EQ(c.activation, Activation::kLeakyRelu);
  EXPECT_FLOAT_EQ(c.leaky_slope, 0.2f);
  ASSERT_EQ(c.weights_hwio.size(), 3u * 3 * 3 * 4);
  for (int ky = 0; ky < 3; ++ky) {
    for (int kx = 0; kx < 3; ++kx) {
      for (int ci = 0; ci < 3; ++ci) {
        for (int co = 0; co < 4; ++co) {
          EXPECT_EQ(c.weights_hwio[((ky * 3 + kx) * 3 + ci) * 4 + co],
                    WeightValue(((co * 3 + ci) * 3 + ky) * 3 + kx))
              << ky << kx << ci << co;
        }
      }
    }
  }
  ASSERT_EQ(c.bias.size(), 4u);
  for (int co = 0; co < 4; ++co) EXPECT_EQ(c.bias[co], BiasValue(co));
  EXPECT_EQ(spec->input.channels, 3);
  EXPECT_EQ(spec->input.traced_height, 8);
  EXPECT_EQ(spec->input.traced_width, 10);
  EXPECT_EQ(spec->output.channels, 4);
  EXPECT_EQ(spec->producer.source_format, "onnx");
  EXPECT_EQ(spec->producer.source_file, "chain.onnx");
  ASSERT_EQ(spec->producer.source_sha256.size(), 64u);
  EXPECT_EQ(spec->producer.source_sha256.find_first_not_of("0123456789abcdef"), std::string::npos);
}

TEST_F(OnnxImporter, LeakyReluWithoutAlphaUsesOnnxDefaultSlope) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("LeakyRelu", {"t"}, {"y"}, "act");
  m.Output("y");
  auto spec = ImportOk(m.Save("leaky_default.onnx"));
  ASSERT_TRUE(spec.ok());
  EXPECT_FLOAT_EQ(LayerAs<ConvSpec>(*spec, 0).leaky_slope, 0.01f);
}

TEST_F(OnnxImporter, FusesReluIntoPrecedingConv) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "t", 2, 3, 3, 1, {1, 1, 1, 1});
  m.Node("Relu", {"t"}, {"y"}, "relu");
  m.Output("y");
  auto spec = ImportOk(m.Save("relu.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 1u);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).activation, Activation::kRelu);
}

TEST_F(OnnxImporter, ConvWithoutBiasGetsZeroBiasAndNoActivation) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "y", 2, 3, 1, 1, {}, /*bias=*/false);
  m.Output("y");
  auto spec = ImportOk(m.Save("nobias.onnx"));
  ASSERT_TRUE(spec.ok());
  const auto& c = LayerAs<ConvSpec>(*spec, 0);
  EXPECT_EQ(c.bias, std::vector<float>(3, 0.0f));
  EXPECT_EQ(c.activation, Activation::kNone);
  EXPECT_EQ(c.kernel_h, 1);
  EXPECT_EQ(c.pads, Pads{});
}

TEST_F(OnnxImporter, ReadsFloatDataInitializersAndConstantNodeTensors) {
  OnnxModel m;
  m.Input("x", {1, 1, 4, 4});
  // 2x1x1x2 kernel (non-square) in float_data; bias from a Constant node.
  m.Floats("w", {2, 1, 1, 2}, {1.0f, 2.0f, 3.0f, 4.0f}, /*raw=*/false);
  m.ConstFloats("b", {2}, {-1.0f, 7.5f});
  m.Node("Conv", {"x", "w", "b"}, {"y"}, "c");
  m.Output("y");
  auto spec = ImportOk(m.Save("float_data.onnx"));
  ASSERT_TRUE(spec.ok());
  const auto& c = LayerAs<ConvSpec>(*spec, 0);
  EXPECT_EQ(c.kernel_h, 1);
  EXPECT_EQ(c.kernel_w, 2);
  // HWIO: [kx][co] for ky = 0, ci = 0.
  EXPECT_EQ(c.weights_hwio, (std::vector<float>{1.0f, 3.0f, 2.0f, 4.0f}));
  EXPECT_EQ(c.bias, (std::vector<float>{-1.0f, 7.5f}));
}

TEST_F(OnnxImporter, PassesIdentityNodesThrough) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Node("Identity", {"x"}, {"x1"}, "id0");
  m.Conv("c", "x1", "t", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("Identity", {"t"}, {"t1"}, "id1");
  m.Node("LeakyRelu", {"t1"}, {"u"}, "act");
  m.Node("Identity", {"u"}, {"y"}, "id2");
  m.Output("y");
  auto spec = ImportOk(m.Save("identity.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 1u);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).activation, Activation::kLeakyRelu);
}

TEST_F(OnnxImporter, GeneratesLayerNamesForUnnamedNodes) {
  OnnxModel m;
  m.Input("x", {1, 2, 4, 4});
  m.Conv("", "x", "a", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Floats("scales", {4}, {1, 1, 2, 2});
  auto& r = m.Node("Resize", {"a", "", "scales"}, {"b"});
  SetString(r, "coordinate_transformation_mode", "asymmetric");
  SetString(r, "nearest_mode", "floor");
  m.Conv("", "b", "y", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Output("y");
  auto spec = ImportOk(m.Save("unnamed.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 3u);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).name, "conv0");
  EXPECT_EQ(LayerAs<UpsampleSpec>(*spec, 1).name, "up0");
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 2).name, "conv1");
}

TEST_F(OnnxImporter, TorchModulePathsBecomeLayerNames) {
  OnnxModel m;
  m.Input("x", {1, 2, 4, 4});
  m.Conv("/encoder/conv0/Conv", "x", "a", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Floats("scales", {4}, {1, 1, 2, 2});
  auto& r = m.Node("Resize", {"a", "", "scales"}, {"b"});
  r.set_name("/Resize_1");
  SetString(r, "coordinate_transformation_mode", "asymmetric");
  SetString(r, "nearest_mode", "floor");
  m.Conv("plain_name", "b", "y", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Output("y");
  auto spec = ImportOk(m.Save("torch_names.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 3u);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).name, "encoder/conv0");
  EXPECT_EQ(LayerAs<UpsampleSpec>(*spec, 1).name, "Resize_1");
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 2).name, "plain_name");
}

TEST_F(OnnxImporter, IgnoresNodesTheOutputDoesNotDependOn) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "y", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("Sigmoid", {"y"}, {"unused"}, "dead");
  m.Output("y");
  auto spec = ImportOk(m.Save("dead.onnx"));
  ASSERT_TRUE(spec.ok());
  EXPECT_EQ(spec->layers.size(), 1u);
}

// ------------------------------------------------------------------------------ padding

TEST_F(OnnxImporter, FoldsZeroPadIntoFollowingConv) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  m.Int64s("pads", {0, 0, 0, 0, 0, 0, 1, 1});
  m.Node("Pad", {"x", "pads"}, {"p"}, "pad0");
  m.Conv("c0", "p", "y", 2, 3, 3, 2, {0, 0, 0, 0});
  m.Output("y");
  auto spec = ImportOk(m.Save("pad_fold.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 1u);
  const auto& c = LayerAs<ConvSpec>(*spec, 0);
  EXPECT_EQ(c.name, "c0");
  EXPECT_EQ(c.pads, (Pads{0, 0, 1, 1}));
  // (0, 1) at in = 8, stride 2 is exactly TensorFlow 'same'.
  EXPECT_EQ(c.padding_rule, PaddingRule::kSameUpper);
}

TEST_F(OnnxImporter, SumsPadNodeAndConvPadsWithExplicitZeroValue) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  m.Int64s("pads", {0, 0, 1, 0, 0, 0, 0, 2});  // top 1, right 2
  m.Floats("zero", {}, {0.0f});
  SetString(m.Node("Pad", {"x", "pads", "zero"}, {"p"}, "pad0"), "mode", "constant");
  m.Conv("c0", "p", "y", 2, 3, 3, 1, {0, 1, 1, 0});  // left 1, bottom 1
  m.Output("y");
  auto spec = ImportOk(m.Save("pad_sum.onnx"));
  ASSERT_TRUE(spec.ok());
  const auto& c = LayerAs<ConvSpec>(*spec, 0);
  EXPECT_EQ(c.pads, (Pads{1, 1, 1, 2}));
  EXPECT_EQ(c.padding_rule, PaddingRule::kExplicit);
}

// Adds torch.onnx.export's graph for F.pad(x, tf_same_pads(x.shape)) (see
// tests/fixtures/gen_sceneednet.py) in front of a stride-`stride` 3x3 conv: shape arithmetic
// on Shape/Gather, then torch's pads reordering (ConstantOfShape, Concat, Reshape, a reversing
// Slice, Transpose, Reshape, Cast). Returns the name of the Pad output.
std::string AddTfSamePadSubgraph(OnnxModel& m, const std::string& x, const std::string& p,
                                 int64_t stride, int64_t opset) {
  auto t = [&](const std::string& s) { return p + "/" + s; };
  auto scalar = [&](const std::string& name, int64_t v) { m.ConstInt64s(t(name), {v}, true); };
  auto unsqueeze = [&](const std::string& in, const std::string& out) {
    if (opset >= 13) {
      m.ConstInt64s(t(out + "_axes"), {0});
      m.Node("Unsqueeze", {in, t(out + "_axes")}, {out}, out);
    } else {
      SetInts(m.Node("Unsqueeze", {in}, {out}, out), "axes", {0});
    }
  };
  m.Node("Shape", {x}, {t("shape")}, t("Shape"));
  scalar("stride", stride);
  scalar("stride_m1", stride - 1);
  scalar("one", 1);
  scalar("two", 2);
  scalar("kernel", 3);
  m.ConstInt64s(t("zero_f"), {0}, true);
  for (int axis : {2, 3}) {
    const std::string a = "ax" + std::to_string(axis);
    scalar(a + "_index", axis);
    m.Node("Gather", {t("shape"), t(a + "_index")}, {t(a + "_size")}, t(a + "_Gather"));
    m.Node("Add", {t(a + "_size"), t("stride_m1")}, {t(a + "_num")}, t(a + "_Add"));
    m.Node("Div", {t(a + "_num"), t("stride")}, {t(a + "_out")}, t(a + "_Div"));
    m.Node("Sub", {t(a + "_out"), t("one")}, {t(a + "_out_m1")}, t(a + "_Sub"));
    m.Node("Mul", {t(a + "_out_m1"), t("stride")}, {t(a + "_span")}, t(a + "_Mul"));
    m.Node("Add", {t(a + "_span"), t("kernel")}, {t(a + "_need")}, t(a + "_Add2"));
    m.Node("Sub", {t(a + "_need"), t(a + "_size")}, {t(a + "_total_raw")}, t(a + "_Sub2"));
    SetInt(m.Node("Cast", {t("zero_f")}, {t(a + "_zero")}, t(a + "_Cast0")), "to",
           onnx::TensorProto::INT64);
    m.Node("Clip", {t(a + "_total_raw"), t(a + "_zero"), ""}, {t(a + "_total")}, t(a + "_Clip"));
    m.Node("Div", {t(a + "_total"), t("two")}, {t(a + "_before")}, t(a + "_Div2"));
    m.Node("Sub", {t(a + "_total"), t(a + "_before")}, {t(a + "_after")}, t(a + "_Sub3"));
    unsqueeze(t(a + "_before"), t(a + "_before_1d"));
    unsqueeze(t(a + "_after"), t(a + "_after_1d"));
  }
  // F.pad order: [left, right, top, bottom].
  SetInt(m.Node("Concat",
                {t("ax3_before_1d"), t("ax3_after_1d"), t("ax2_before_1d"), t("ax2_after_1d")},
                {t("pads4")}, t("Concat")),
         "axis", 0);
  m.ConstInt64s(t("eight"), {8}, true);
  m.Node("Size", {t("pads4")}, {t("n")}, t("Size"));
  m.Node("Sub", {t("eight"), t("n")}, {t("nzeros")}, t("Sub_zeros"));
  unsqueeze(t("nzeros"), t("nzeros_1d"));
  auto& cos = m.Node("ConstantOfShape", {t("nzeros_1d")}, {t("zeros")}, t("ConstantOfShape"));
  auto* value = cos.add_attribute();
  value->set_name("value");
  value->set_type(onnx::AttributeProto::TENSOR);
  value->mutable_t()->set_data_type(onnx::TensorProto::INT64);
  value->mutable_t()->add_dims(1);
  value->mutable_t()->add_int64_data(0);
  SetInt(m.Node("Concat", {t("pads4"), t("zeros")}, {t("pads8")}, t("Concat2")), "axis", 0);
  m.ConstInt64s(t("pairs_shape"), {-1, 2});
  m.Node("Reshape", {t("pads8"), t("pairs_shape")}, {t("pairs")}, t("Reshape"));
  m.ConstInt64s(t("rev_start"), {-1});
  m.ConstInt64s(t("rev_end"), {kInt64Min + 1});
  m.ConstInt64s(t("rev_axes"), {0});
  m.ConstInt64s(t("rev_steps"), {-1});
  m.Node("Slice", {t("pairs"), t("rev_start"), t("rev_end"), t("rev_axes"), t("rev_steps")},
         {t("reversed")}, t("Slice"));
  SetInts(m.Node("Transpose", {t("reversed")}, {t("transposed")}, t("Transpose")), "perm", {1, 0});
  m.ConstInt64s(t("flat"), {-1});
  m.Node("Reshape", {t("transposed"), t("flat")}, {t("onnx_pads")}, t("Reshape2"));
  SetInt(m.Node("Cast", {t("onnx_pads")}, {t("onnx_pads64")}, t("Cast")), "to",
         onnx::TensorProto::INT64);
  SetString(m.Node("Pad", {x, t("onnx_pads64"), ""}, {t("padded")}, t("Pad")), "mode", "constant");
  return t("padded");
}

TEST_F(OnnxImporter, EvaluatesShapeDerivedPadSubgraphsAsTorchExportsThem) {
  for (int64_t opset : {11, 13, 17}) {
    SCOPED_TRACE("opset " + std::to_string(opset));
    OnnxModel m(opset);
    m.Input("x", {1, 2, 9, 12});
    const std::string p0 = AddTfSamePadSubgraph(m, "x", "/conv0", 2, opset);
    m.Conv("/conv0/Conv", p0, "c0", 2, 4, 3, 2, {0, 0, 0, 0});
    SetFloat(m.Node("LeakyRelu", {"c0"}, {"a0"}, "/LeakyRelu"), "alpha", 0.3f);
    const std::string p1 = AddTfSamePadSubgraph(m, "a0", "/conv1", 2, opset);
    m.Conv("/conv1/Conv", p1, "y", 4, 3, 3, 2, {0, 0, 0, 0});
    m.Output("y");
    auto spec = ImportOk(m.Save("tf_same_" + std::to_string(opset) + ".onnx"));
    ASSERT_TRUE(spec.ok());
    ASSERT_EQ(spec->layers.size(), 2u);
    const auto& c0 = LayerAs<ConvSpec>(*spec, 0);
    const auto& c1 = LayerAs<ConvSpec>(*spec, 1);
    // conv0 at 9x12: rows total 2 -> (1, 1), cols total 1 -> (0, 1).
    EXPECT_EQ(c0.pads, (Pads{1, 0, 1, 1}));
    // conv1 at 5x6: rows total 2 -> (1, 1), cols total 1 -> (0, 1).
    EXPECT_EQ(c1.pads, (Pads{1, 0, 1, 1}));
    EXPECT_EQ(c0.padding_rule, PaddingRule::kSameUpper);
    EXPECT_EQ(c1.padding_rule, PaddingRule::kSameUpper);
    EXPECT_EQ(c0.activation, Activation::kLeakyRelu);
    EXPECT_EQ(spec->output.channels, 3);
  }
}

// Two convs: stride 2 at 8x8 with pads `first`, then stride 1 with pads (1, 1, 1, 1).
std::string TwoConvModel(const std::string& file, const std::vector<int64_t>& first) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  m.Conv("down", "x", "a", 2, 3, 3, 2, first);
  m.Conv("same", "a", "y", 3, 3, 3, 1, {1, 1, 1, 1});
  m.Output("y");
  return m.Save(file);
}

TEST_F(OnnxImporter, DetectsSameUpperWhenEveryConvMatchesIt) {
  auto spec = ImportOk(TwoConvModel("same_upper.onnx", {0, 0, 1, 1}));
  ASSERT_TRUE(spec.ok());
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).padding_rule, PaddingRule::kSameUpper);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 1).padding_rule, PaddingRule::kSameUpper);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).pads, (Pads{0, 0, 1, 1}));
}

TEST_F(OnnxImporter, KeepsExplicitPadsWhenAnyConvDiffersFromSameUpper) {
  // torch's padding=1 at an even size: (1, 1) where 'same' is (0, 1).
  auto spec = ImportOk(TwoConvModel("explicit.onnx", {1, 1, 1, 1}));
  ASSERT_TRUE(spec.ok());
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).padding_rule, PaddingRule::kExplicit);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 1).padding_rule, PaddingRule::kExplicit);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).pads, (Pads{1, 1, 1, 1}));
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 1).pads, (Pads{1, 1, 1, 1}));
}

TEST_F(OnnxImporter, ForcedSameUpperRejectsConvThatContradictsIt) {
  OnnxImportOptions options;
  options.padding = PaddingDetection::kSameUpper;
  ExpectImportError(TwoConvModel("forced_bad.onnx", {1, 1, 1, 1}),
                    {"conv 'down'", "(top 1, left 1, bottom 1, right 1)",
                     "(top 0, left 0, bottom 1, right 1)", "8x8", "SameUpper"},
                    options);
}

TEST_F(OnnxImporter, ForcedSameUpperAcceptsMatchingConvs) {
  OnnxImportOptions options;
  options.padding = PaddingDetection::kSameUpper;
  auto spec = ImportOk(TwoConvModel("forced_ok.onnx", {0, 0, 1, 1}), options);
  ASSERT_TRUE(spec.ok());
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).padding_rule, PaddingRule::kSameUpper);
}

TEST_F(OnnxImporter, ForcedExplicitKeepsTracedNumbers) {
  OnnxImportOptions options;
  options.padding = PaddingDetection::kExplicit;
  auto spec = ImportOk(TwoConvModel("forced_explicit.onnx", {0, 0, 1, 1}), options);
  ASSERT_TRUE(spec.ok());
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).padding_rule, PaddingRule::kExplicit);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).pads, (Pads{0, 0, 1, 1}));
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 1).padding_rule, PaddingRule::kExplicit);
}

TEST_F(OnnxImporter, AutoPadSameUpperIsTracedAtInputSize) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 9});
  SetString(m.Conv("c", "x", "y", 2, 2, 3, 2, {}), "auto_pad", "SAME_UPPER");
  m.Output("y");
  auto spec = ImportOk(m.Save("auto_pad.onnx"));
  ASSERT_TRUE(spec.ok());
  const auto& c = LayerAs<ConvSpec>(*spec, 0);
  EXPECT_EQ(c.pads, (Pads{0, 1, 1, 1}));  // rows: total 1 -> (0, 1); cols: total 2 -> (1, 1)
  EXPECT_EQ(c.padding_rule, PaddingRule::kSameUpper);
}

TEST_F(OnnxImporter, AutoPadValidMeansNoPadding) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 9});
  SetString(m.Conv("c", "x", "y", 2, 2, 3, 1, {}), "auto_pad", "VALID");
  m.Output("y");
  auto spec = ImportOk(m.Save("valid.onnx"));
  ASSERT_TRUE(spec.ok());
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).pads, Pads{});
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).padding_rule, PaddingRule::kExplicit);
}

// ------------------------------------------------------------------------------ resize

// conv (2 channels, 3x3 same) -> Resize, with the Resize's attributes and inputs given.
struct ResizeCase {
  int64_t opset = 13;
  std::vector<float> scales;   // empty: not given
  std::vector<int64_t> sizes;  // empty: not given
  std::string ctm = "asymmetric";
  std::string nearest_mode = "floor";
  std::string mode = "nearest";
};

std::string ResizeModel(const std::string& file, const ResizeCase& rc) {
  OnnxModel m(rc.opset);
  m.Input("x", {1, 2, 8, 10});
  m.Conv("c", "x", "a", 2, 2, 3, 1, {1, 1, 1, 1});
  std::vector<std::string> inputs = {"a", "", "", ""};
  if (rc.opset == 11) {  // opset 11: roi and scales present, possibly empty
    m.Floats("roi", {0}, {});
    inputs[1] = "roi";
    m.Floats("scales", {static_cast<int64_t>(rc.scales.size())}, rc.scales);
    inputs[2] = "scales";
  } else if (!rc.scales.empty()) {
    m.Floats("scales", {static_cast<int64_t>(rc.scales.size())}, rc.scales);
    inputs[2] = "scales";
  }
  if (!rc.sizes.empty()) {
    m.Int64s("sizes", rc.sizes);
    inputs[3] = "sizes";
  } else {
    inputs.pop_back();
  }
  auto& n = m.Node("Resize", inputs, {"y"}, "up");
  if (!rc.ctm.empty()) SetString(n, "coordinate_transformation_mode", rc.ctm);
  if (!rc.nearest_mode.empty()) SetString(n, "nearest_mode", rc.nearest_mode);
  SetString(n, "mode", rc.mode);
  m.Output("y");
  return m.Save(file);
}

TEST_F(OnnxImporter, ResizeWithScalesBecomesUpsample) {
  ResizeCase rc;
  rc.scales = {1, 1, 2, 3};
  auto spec = ImportOk(ResizeModel("resize_scales.onnx", rc));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 2u);
  const auto& up = LayerAs<UpsampleSpec>(*spec, 1);
  EXPECT_EQ(up.name, "up");
  EXPECT_EQ(up.factor_h, 2);
  EXPECT_EQ(up.factor_w, 3);
  EXPECT_EQ(spec->output.channels, 2);
}

TEST_F(OnnxImporter, ResizeWithSizesBecomesUpsample) {
  ResizeCase rc;
  rc.opset = 11;  // empty roi and scales, as torch exports F.interpolate(size=...)
  rc.sizes = {1, 2, 32, 20};
  auto spec = ImportOk(ResizeModel("resize_sizes.onnx", rc));
  ASSERT_TRUE(spec.ok());
  const auto& up = LayerAs<UpsampleSpec>(*spec, 1);
  EXPECT_EQ(up.factor_h, 4);
  EXPECT_EQ(up.factor_w, 2);
}

TEST_F(OnnxImporter, ResizeDefaultsToHalfPixelRoundPreferFloorWhichIsExact) {
  ResizeCase rc;
  rc.scales = {1, 1, 3, 3};
  rc.ctm = "";
  rc.nearest_mode = "";
  auto spec = ImportOk(ResizeModel("resize_defaults.onnx", rc));
  ASSERT_TRUE(spec.ok());
  EXPECT_EQ(LayerAs<UpsampleSpec>(*spec, 1).factor_h, 3);
}

// ONNX's reference Resize (nearest, one axis), straight from the operator definition.
int64_t OnnxNearestSource(const std::string& ctm, const std::string& nearest_mode, int64_t y,
                          int64_t in_len, int64_t f) {
  const int64_t out_len = in_len * f;
  const double scale = static_cast<double>(f);
  const double yd = static_cast<double>(y);
  double x = 0;
  if (ctm == "asymmetric") {
    x = yd / scale;
  } else if (ctm == "half_pixel") {
    x = (yd + 0.5) / scale - 0.5;
  } else if (ctm == "pytorch_half_pixel") {
    x = out_len > 1 ? (yd + 0.5) / scale - 0.5 : 0.0;
  } else if (ctm == "tf_half_pixel_for_nn") {
    x = (yd + 0.5) / scale;
  } else if (ctm == "align_corners") {
    x = out_len == 1 ? 0.0
                     : yd * static_cast<double>(in_len - 1) / static_cast<double>(out_len - 1);
  }
  double r = 0;
  const bool half = x == std::floor(x) + 0.5;
  if (nearest_mode == "floor") {
    r = std::floor(x);
  } else if (nearest_mode == "ceil") {
    r = std::ceil(x);
  } else if (nearest_mode == "round_prefer_floor") {
    r = half ? std::floor(x) : std::round(x);
  } else {  // round_prefer_ceil
    r = half ? std::ceil(x) : std::round(x);
  }
  return std::clamp<int64_t>(static_cast<int64_t>(r), 0, in_len - 1);
}

// Whether the reference equals in[floor(y / f)] for every input length up to 40.
bool ReferenceIsFloorOfQuotient(const std::string& ctm, const std::string& nearest_mode,
                                int64_t f) {
  for (int64_t n = 1; n <= 40; ++n) {
    for (int64_t y = 0; y < n * f; ++y) {
      if (OnnxNearestSource(ctm, nearest_mode, y, n, f) != y / f) return false;
    }
  }
  return true;
}

TEST_F(OnnxImporter, NearestResizeIsAnUpsampleExactlyForTheModesThatAreFloorOfQuotient) {
  int accepted = 0;
  int rejected = 0;
  for (const char* ctm : {"asymmetric", "half_pixel", "pytorch_half_pixel", "tf_half_pixel_for_nn",
                          "align_corners"}) {
    for (const char* nm : {"floor", "ceil", "round_prefer_floor", "round_prefer_ceil"}) {
      for (int64_t f : {1, 2, 3, 4}) {
        SCOPED_TRACE(std::string(ctm) + " + " + nm + " at factor " + std::to_string(f));
        ResizeCase rc;
        rc.scales = {1, 1, static_cast<float>(f), static_cast<float>(f)};
        rc.ctm = ctm;
        rc.nearest_mode = nm;
        const std::string path = ResizeModel("resize_modes.onnx", rc);
        const bool exact = ReferenceIsFloorOfQuotient(ctm, nm, f);
        auto spec = ImportOk(path);
        ASSERT_TRUE(spec.ok());
        ASSERT_EQ(spec->layers.size(), 2u);
        if (exact) {
          ++accepted;
          EXPECT_EQ(LayerAs<UpsampleSpec>(*spec, 1).factor_h, f);
        } else {
          // Any other mode is a general Resize with the node's own rounding.
          ++rejected;
          const ResizeParams& r = LayerAs<ResizeSpec>(*spec, 1).params;
          EXPECT_EQ(r.mode, ResizeMode::kNearest);
          EXPECT_STREQ(ResizeCoordinatesName(r.coordinates), ctm);
          EXPECT_STREQ(NearestRoundingName(r.nearest), nm);
          EXPECT_EQ(r.scale_num_h, f);
          EXPECT_EQ(r.scale_den_h, 1);
        }
      }
    }
  }
  // Sanity: the common cases are on the expected side.
  EXPECT_TRUE(ReferenceIsFloorOfQuotient("asymmetric", "floor", 2));
  EXPECT_TRUE(ReferenceIsFloorOfQuotient("half_pixel", "round_prefer_floor", 3));
  EXPECT_FALSE(ReferenceIsFloorOfQuotient("asymmetric", "round_prefer_floor", 3));
  EXPECT_FALSE(ReferenceIsFloorOfQuotient("half_pixel", "floor", 2));
  EXPECT_GT(accepted, 0);
  EXPECT_GT(rejected, 0);
}

TEST_F(OnnxImporter, UpsampleOpBecomesUpsample) {
  OnnxModel m(11);
  m.Input("x", {1, 2, 4, 4});
  m.Floats("scales", {4}, {1, 1, 2, 2});
  m.Node("Upsample", {"x", "scales"}, {"y"}, "legacy_up");
  m.Output("y");
  auto spec = ImportOk(m.Save("upsample.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 1u);
  EXPECT_EQ(LayerAs<UpsampleSpec>(*spec, 0).factor_w, 2);
}

// ------------------------------------------------------------------------------ crops

// x (1, 2, 6, 10) -> conv stride 2 -> (3, 5) -> Resize x4 -> (12, 20) -> `slices` -> conv.
// Each slice is {starts, ends, axes}.
struct SliceSpec {
  std::vector<int64_t> starts, ends, axes;
};

std::string CropModel(const std::string& file, const std::vector<SliceSpec>& slices,
                      std::vector<float> scales = {1, 1, 4, 4}, int64_t in_w = 10) {
  OnnxModel m;
  m.Input("x", {1, 2, 6, in_w});
  m.Conv("down", "x", "a", 2, 2, 3, 2, {1, 1, 1, 1});
  m.Floats("scales", {4}, scales);
  auto& r = m.Node("Resize", {"a", "", "scales"}, {"b"}, "up");
  SetString(r, "coordinate_transformation_mode", "asymmetric");
  SetString(r, "nearest_mode", "floor");
  std::string cur = "b";
  for (size_t i = 0; i < slices.size(); ++i) {
    const std::string k = std::to_string(i);
    m.Int64s("starts" + k, slices[i].starts);
    m.Int64s("ends" + k, slices[i].ends);
    m.Int64s("axes" + k, slices[i].axes);
    m.Node("Slice", {cur, "starts" + k, "ends" + k, "axes" + k}, {"s" + k}, "crop_" + k);
    cur = "s" + k;
  }
  m.Conv("after", cur, "y", 2, 3, 3, 1, {1, 1, 1, 1});
  m.Output("y");
  return m.Save(file);
}

TEST_F(OnnxImporter, SliceBackToInputSizeCropsExcessFromTopAndLeft) {
  auto spec =
      ImportOk(CropModel("crop_top_left.onnx", {{{6, 10}, {kInt64Max, kInt64Max}, {2, 3}}}));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 4u);
  const auto& crop = LayerAs<CropSpec>(*spec, 2);
  EXPECT_EQ(crop.name, "crop_0");
  EXPECT_EQ(crop.rule, CropRule::kToInputSize);
  EXPECT_TRUE(crop.excess_rows_from_top);
  EXPECT_TRUE(crop.excess_cols_from_left);
  EXPECT_EQ(crop.amounts, (Pads{6, 10, 0, 0}));  // the traced amounts, for information
}

TEST_F(OnnxImporter, SliceWithNegativeEndsCropsExcessFromBottomAndRight) {
  auto spec = ImportOk(CropModel("crop_bottom_right.onnx", {{{0, 0}, {-6, -10}, {-2, -1}}}));
  ASSERT_TRUE(spec.ok());
  const auto& crop = LayerAs<CropSpec>(*spec, 2);
  EXPECT_EQ(crop.rule, CropRule::kToInputSize);
  EXPECT_FALSE(crop.excess_rows_from_top);
  EXPECT_FALSE(crop.excess_cols_from_left);
}

TEST_F(OnnxImporter, CropSideDefaultsToTopLeftOnAnAxisWithNothingRemoved) {
  // Resize x(4, 2): (12, 10); only rows removed, at the bottom.
  auto spec =
      ImportOk(CropModel("crop_rows_only.onnx", {{{0}, {6}, {2}}}, {1, 1, 4, 2}, /*in_w=*/10));
  ASSERT_TRUE(spec.ok());
  const auto& crop = LayerAs<CropSpec>(*spec, 2);
  EXPECT_EQ(crop.rule, CropRule::kToInputSize);
  EXPECT_FALSE(crop.excess_rows_from_top);
  EXPECT_TRUE(crop.excess_cols_from_left);
}

TEST_F(OnnxImporter, MergesConsecutiveSlicesIntoOneCrop) {
  auto spec =
      ImportOk(CropModel("crop_two_slices.onnx", {{{6}, {kInt64Max}, {2}}, {{0}, {-10}, {3}}}));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 4u);
  const auto& crop = LayerAs<CropSpec>(*spec, 2);
  EXPECT_EQ(crop.name, "crop_0");
  EXPECT_EQ(crop.rule, CropRule::kToInputSize);
  EXPECT_TRUE(crop.excess_rows_from_top);
  EXPECT_FALSE(crop.excess_cols_from_left);
  EXPECT_EQ(crop.amounts, (Pads{6, 0, 0, 10}));
}

TEST_F(OnnxImporter, SliceToAnotherSizeIsAnExplicitCrop) {
  auto spec = ImportOk(CropModel("crop_explicit.onnx", {{{1, 2}, {12, 20}, {2, 3}}}));
  ASSERT_TRUE(spec.ok());
  const auto& crop = LayerAs<CropSpec>(*spec, 2);
  EXPECT_EQ(crop.rule, CropRule::kExplicit);
  EXPECT_EQ(crop.amounts, (Pads{1, 2, 0, 0}));
}

TEST_F(OnnxImporter, CenterCropToInputSizeStaysExplicit) {
  // 12 -> 6 rows removing 3 + 3: no single side reproduces it at other sizes.
  auto spec = ImportOk(CropModel("crop_center.onnx", {{{3, 5}, {9, 15}, {2, 3}}}));
  ASSERT_TRUE(spec.ok());
  const auto& crop = LayerAs<CropSpec>(*spec, 2);
  EXPECT_EQ(crop.rule, CropRule::kExplicit);
  EXPECT_EQ(crop.amounts, (Pads{3, 5, 3, 5}));
}

TEST_F(OnnxImporter, ReadsInt32SliceBounds) {
  OnnxModel m;
  m.Input("x", {1, 2, 6, 10});
  m.Floats("scales", {4}, {1, 1, 2, 2});
  auto& r = m.Node("Resize", {"x", "", "scales"}, {"b"}, "up");
  SetString(r, "coordinate_transformation_mode", "asymmetric");
  SetString(r, "nearest_mode", "floor");
  m.Int32s("starts", {6});
  m.Int32s("ends", {2147483647});
  m.Int32s("axes", {2});
  m.Int32s("steps", {1});
  m.Node("Slice", {"b", "starts", "ends", "axes", "steps"}, {"c"}, "rows");
  m.Int32s("starts_w", {0});
  m.Int32s("ends_w", {10});
  m.Int32s("axes_w", {3});
  m.Node("Slice", {"c", "starts_w", "ends_w", "axes_w"}, {"y"}, "cols");
  m.Output("y");
  auto spec = ImportOk(m.Save("crop_int32.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 2u);
  const auto& crop = LayerAs<CropSpec>(*spec, 1);
  EXPECT_EQ(crop.rule, CropRule::kToInputSize);
  EXPECT_TRUE(crop.excess_rows_from_top);
  EXPECT_FALSE(crop.excess_cols_from_left);
  EXPECT_EQ(crop.amounts, (Pads{6, 0, 0, 10}));
}

// ------------------------------------------------------------------------------ errors

TEST_F(OnnxImporter, RejectsUnsupportedOpNamingNodeAndOpType) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("Softsign", {"t"}, {"y"}, "squash");
  m.Output("y");
  ExpectImportError(m.Save("softsign.onnx"),
                    {"node 'squash' (op Softsign): unsupported; supported ops: Conv, Pad"});
}

TEST_F(OnnxImporter, ExportListsEveryUnsupportedOnnxNodeWithItsOp) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "t0", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("Softsign", {"t0"}, {"t1"}, "squash");
  m.Node("Erf", {"t1"}, {"t2"}, "");  // unnamed: labelled by its index
  m.Node("Softplus", {"t2"}, {"y"}, "soft");
  m.Output("y");
  ExpectImportError(m.Save("three.onnx"),
                    {"3 nodes are unsupported: node 'squash' (op Softsign), node #2 (op Erf), "
                     "node 'soft' (op Softplus); supported ops (default ONNX domain): Conv, Pad"});
}

TEST_F(OnnxImporter, ExportListsAtMostTwentyUnsupportedNodesThenTheirCount) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "t0", 2, 2, 3, 1, {1, 1, 1, 1});
  constexpr int kNodes = 26;
  for (int i = 0; i < kNodes; ++i) {
    m.Node("Softsign", {"t" + std::to_string(i)},
           {i + 1 == kNodes ? "y" : "t" + std::to_string(i + 1)}, "s" + std::to_string(i));
  }
  m.Output("y");
  const std::string path = m.Save("many.onnx");
  ExpectImportError(path, {"26 nodes are unsupported: node 's0' (op Softsign)",
                           "node 's19' (op Softsign) and 6 more;"});
  const Result<ModelSpec> r = ImportOnnx(path);
  EXPECT_EQ(r.message().find("'s20'"), std::string::npos) << r.message();
}

// BatchNormalization inputs: X, scale, B, mean, var.
onnx::NodeProto& AddBatchNorm(OnnxModel& m, const std::string& in,
                              const std::vector<std::string>& outputs) {
  m.Floats("bn.scale", {2}, {1, 1});
  m.Floats("bn.b", {2}, {0, 0});
  m.Floats("bn.mean", {2}, {0, 0});
  m.Floats("bn.var", {2}, {1, 1});
  return m.Node("BatchNormalization", {in, "bn.scale", "bn.b", "bn.mean", "bn.var"}, outputs, "bn");
}

TEST_F(OnnxImporter, TrainingModeBatchNormSaysEvalModeExportFoldsIt) {
  {  // opset 14+: the training_mode attribute
    OnnxModel m(15);
    m.Input("x", {1, 2, 5, 5});
    m.Conv("c", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
    SetInt(AddBatchNorm(m, "t", {"y"}), "training_mode", 1);
    m.Output("y");
    ExpectImportError(m.Save("bn_training.onnx"),
                      {"node 'bn' (op BatchNormalization): is a training-mode "
                       "BatchNormalization (training_mode = 1)",
                       "an eval-mode export (model.eval() before torch.onnx.export) uses the "
                       "running statistics, which sfrt folds into the preceding Conv"});
  }
  {  // opset < 14: a training-mode export adds the running mean and variance outputs
    OnnxModel m(12);
    m.Input("x", {1, 2, 5, 5});
    m.Conv("c", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
    AddBatchNorm(m, "t", {"y", "running_mean", "running_var"});
    m.Output("y");
    ExpectImportError(m.Save("bn_training_outputs.onnx"),
                      {"node 'bn' (op BatchNormalization): is a training-mode "
                       "BatchNormalization (it outputs the running mean and variance)",
                       "model.eval() before torch.onnx.export"});
  }
}

// An inference BatchNormalization after a Conv (what a PyTorch export keeps with
// training=TrainingMode.PRESERVE, or another exporter writes) is folded into the Conv: weights
// scaled per output channel by scale / sqrt(var + epsilon), the bias shifted; the activation
// after it still fuses. One layer, no normalisation left.
TEST_F(OnnxImporter, FoldsInferenceBatchNormIntoThePrecedingConv) {
  auto build = [](bool with_bn) {
    OnnxModel m(15);
    m.Input("x", {1, 2, 5, 5});
    m.Conv("c", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
    std::string act_in = "t";
    if (with_bn) {
      m.Floats("bn.scale", {2}, {2.0f, 0.5f});
      m.Floats("bn.b", {2}, {0.1f, -0.2f});
      m.Floats("bn.mean", {2}, {0.3f, -0.4f});
      m.Floats("bn.var", {2}, {4.0f, 0.25f});
      auto& bn =
          m.Node("BatchNormalization", {"t", "bn.scale", "bn.b", "bn.mean", "bn.var"}, {"n"}, "bn");
      auto* eps = bn.add_attribute();
      eps->set_name("epsilon");
      eps->set_type(onnx::AttributeProto::FLOAT);
      eps->set_f(1e-3f);
      act_in = "n";
    }
    auto& act = m.Node("LeakyRelu", {act_in}, {"y"}, "act");
    auto* alpha = act.add_attribute();
    alpha->set_name("alpha");
    alpha->set_type(onnx::AttributeProto::FLOAT);
    alpha->set_f(0.2f);
    m.Output("y");
    return m.Save(with_bn ? "conv_bn.onnx" : "conv.onnx");
  };
  const Result<ModelSpec> plain = ImportOk(build(false));
  const Result<ModelSpec> folded = ImportOk(build(true));
  ASSERT_TRUE(plain.ok() && folded.ok());
  ASSERT_EQ(folded->layers.size(), 1u);
  const auto& a = std::get<ConvSpec>(plain->layers[0]);
  const auto& b = std::get<ConvSpec>(folded->layers[0]);
  EXPECT_EQ(b.activation, Activation::kLeakyRelu);
  EXPECT_FLOAT_EQ(b.leaky_slope, 0.2f);
  const double scale[2] = {2.0 / std::sqrt(4.0 + 1e-3), 0.5 / std::sqrt(0.25 + 1e-3)};
  const double shift[2] = {0.1 - 0.3 * scale[0], -0.2 + 0.4 * scale[1]};
  ASSERT_EQ(a.weights_hwio.size(), b.weights_hwio.size());
  for (size_t i = 0; i < a.weights_hwio.size(); ++i) {
    EXPECT_NEAR(b.weights_hwio[i], a.weights_hwio[i] * scale[i % 2], 1e-6) << "weight " << i;
  }
  ASSERT_EQ(b.bias.size(), 2u);
  for (size_t o = 0; o < 2; ++o) {
    EXPECT_NEAR(b.bias[o], a.bias[o] * scale[o] + shift[o], 1e-6) << "bias " << o;
  }
}

TEST_F(OnnxImporter, BatchNormNotDirectlyAfterAConvBecomesAPerChannelScaleAndShift) {
  OnnxModel m(15);
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("Relu", {"t"}, {"r"}, "relu");
  AddBatchNorm(m, "r", {"y"});
  m.Output("y");
  auto spec = ImportOk(m.Save("relu_bn.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 2u);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).activation, Activation::kRelu);
  const auto& bn = LayerAs<ChannelAffineSpec>(*spec, 1);
  EXPECT_EQ(bn.name, "bn");
  ASSERT_EQ(bn.scale.size(), 2u);
  ASSERT_EQ(bn.shift.size(), 2u);
  EXPECT_EQ(bn.activation, Activation::kNone);
}

TEST_F(OnnxImporter, FoldsArithmeticByPerChannelConstantsIntoTheConvBefore) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Floats("gain", {1, 2, 1, 1}, {2.0f, -0.5f});
  m.Floats("offset", {2, 1, 1}, {0.25f, 1.0f});
  m.Floats("four", {}, {4.0f});
  m.Node("Mul", {"gain", "t"}, {"t1"}, "gain");  // the constant first
  m.Node("Sub", {"t1", "offset"}, {"t2"}, "offset");
  m.Node("Div", {"t2", "four"}, {"y"}, "quarter");
  m.Output("y");
  auto spec = ImportOk(m.Save("arith.onnx"));
  ASSERT_TRUE(spec.ok()) << spec.message();
  ASSERT_EQ(spec->layers.size(), 1u);
  const auto& c = LayerAs<ConvSpec>(*spec, 0);
  // ((conv * gain) - offset) / 4, per output channel: weights times gain / 4, and the bias
  // (BiasValue(co)) likewise, less offset / 4.
  const float gain[2] = {2.0f, -0.5f}, offset[2] = {0.25f, 1.0f};
  for (int co = 0; co < 2; ++co) {
    EXPECT_FLOAT_EQ(c.bias[static_cast<size_t>(co)],
                    (BiasValue(co) * gain[co] - offset[co]) * 0.25f);
    // Tap (0, 0), input 0: OIHW element co * 18.
    EXPECT_FLOAT_EQ(c.weights_hwio[static_cast<size_t>(co)],
                    WeightValue(co * 18) * gain[co] * 0.25f);
  }
}

TEST_F(OnnxImporter, TurnsSigmoidTimesTwoMinusOneIntoChannelAffines) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Conv("c", "x", "t", 2, 3, 3, 1, {1, 1, 1, 1});
  m.Floats("two", {}, {2.0f});
  m.Floats("one", {}, {1.0f});
  m.Node("Sigmoid", {"t"}, {"s"}, "squash");
  m.Node("Mul", {"s", "two"}, {"s2"}, "double");
  m.Node("Sub", {"s2", "one"}, {"y"}, "centre");
  m.Output("y");
  auto spec = ImportOk(m.Save("sigmoid.onnx"));
  ASSERT_TRUE(spec.ok()) << spec.message();
  ASSERT_EQ(spec->layers.size(), 3u);
  const auto& squash = LayerAs<ChannelAffineSpec>(*spec, 1);
  EXPECT_EQ(squash.activation, Activation::kSigmoid);
  EXPECT_EQ(squash.scale, std::vector<float>(3, 1.0f));
  EXPECT_EQ(squash.shift, std::vector<float>(3, 0.0f));
  // The Mul and the Sub after it make one scale and shift (the sigmoid is already activated).
  const auto& affine = LayerAs<ChannelAffineSpec>(*spec, 2);
  EXPECT_EQ(affine.activation, Activation::kNone);
  EXPECT_EQ(affine.scale, std::vector<float>(3, 2.0f));
  EXPECT_EQ(affine.shift, std::vector<float>(3, -1.0f));
}

TEST_F(OnnxImporter, ClipFromZeroUnboundedFusesAsReluAndReluSixBecomesAClip) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Floats("zero", {}, {0.0f});
  m.Floats("six", {}, {6.0f});
  m.Conv("c0", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("Clip", {"t", "zero", ""}, {"r"}, "relu");
  m.Conv("c1", "r", "u", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("Clip", {"u", "zero", "six"}, {"v"}, "relu6");
  SetFloat(m.Node("Elu", {"v"}, {"y"}, "elu"), "alpha", 0.5f);
  m.Output("y");
  auto spec = ImportOk(m.Save("clip.onnx"));
  ASSERT_TRUE(spec.ok()) << spec.message();
  ASSERT_EQ(spec->layers.size(), 4u);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).activation, Activation::kRelu);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 1).activation, Activation::kNone);
  const auto& relu6 = LayerAs<ChannelAffineSpec>(*spec, 2);
  EXPECT_EQ(relu6.activation, Activation::kClip);
  EXPECT_EQ(relu6.clip_min, 0.0f);
  EXPECT_EQ(relu6.clip_max, 6.0f);
  const auto& elu = LayerAs<ChannelAffineSpec>(*spec, 3);
  EXPECT_EQ(elu.activation, Activation::kElu);
  EXPECT_EQ(elu.elu_alpha, 0.5f);
}

// 8-bit integers are exact in float32, and so is an operator that only selects among its
// input values and integer constants: Clip to INT8 bounds (the -3 read from its raw byte) and
// MaxPool import as they would for float input.
TEST_F(OnnxImporter, ImportsAnInt8GraphOfSelectionOperatorsWithItsIntegerClipBounds) {
  OnnxModel m;
  m.Input("x", {1, 2, 6, 6}, onnx::TensorProto::INT8);
  m.Int8("low", -3);
  m.Int8("high", 100);
  m.Node("Clip", {"x", "low", "high"}, {"c"}, "clip");
  auto& pool = m.Node("MaxPool", {"c"}, {"y"}, "pool");
  SetInts(pool, "kernel_shape", {2, 2});
  SetInts(pool, "strides", {2, 2});
  m.Output("y", onnx::TensorProto::INT8);
  auto spec = ImportOk(m.Save("int8_select.onnx"));
  ASSERT_TRUE(spec.ok()) << spec.message();
  ASSERT_EQ(spec->layers.size(), 2u);
  const auto& clip = LayerAs<ChannelAffineSpec>(*spec, 0);
  EXPECT_EQ(clip.activation, Activation::kClip);
  EXPECT_EQ(clip.clip_min, -3.0f);
  EXPECT_EQ(clip.clip_max, 100.0f);
  EXPECT_EQ(LayerAs<PoolSpec>(*spec, 1).kind, PoolKind::kMax);
}

// A MaxPool's Indices output (ONNX's second output, INT64) becomes an argmax pool when the
// import chooses it; a graph of two outputs is refused unless one is chosen, listing both, and
// a name that is no output is refused the same way. storage_order 1 numbers column-major.
TEST_F(OnnxImporter, ImportsAMaxPoolsIndicesOutputAsAnArgMaxPoolWhenChosen) {
  OnnxModel m;
  m.Input("x", {1, 3, 6, 6});
  auto& pool = m.Node("MaxPool", {"x"}, {"y", "where"}, "pool");
  SetInts(pool, "kernel_shape", {2, 2});
  SetInts(pool, "strides", {2, 2});
  auto* order = pool.add_attribute();
  order->set_name("storage_order");
  order->set_type(onnx::AttributeProto::INT);
  order->set_i(1);
  m.Output("y");
  m.Output("where", onnx::TensorProto::INT64);
  const std::string path = m.Save("maxpool_argmax.onnx");
  auto unchosen = ImportOnnx(path);
  ASSERT_FALSE(unchosen.ok());
  EXPECT_NE(unchosen.message().find("graph has 2 outputs ('y', 'where'); an sfrt model computes "
                                    "one: choose it"),
            std::string::npos)
      << unchosen.message();
  OnnxImportOptions options;
  options.output = "elsewhere";
  auto unknown = ImportOnnx(path, options);
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.message().find("graph has no output 'elsewhere'; its outputs: 'y', 'where'"),
            std::string::npos)
      << unknown.message();
  options.output = "where";
  auto indices = ImportOk(path, options);
  ASSERT_TRUE(indices.ok());
  ASSERT_EQ(indices->layers.size(), 1u);
  EXPECT_EQ(LayerAs<PoolSpec>(*indices, 0).kind, PoolKind::kArgMax);
  EXPECT_TRUE(LayerAs<PoolSpec>(*indices, 0).indices_column_major);
  EXPECT_EQ(indices->output.channels, 3);
  options.output = "y";
  auto values = ImportOk(path, options);
  ASSERT_TRUE(values.ok());
  ASSERT_EQ(values->layers.size(), 1u);
  EXPECT_EQ(LayerAs<PoolSpec>(*values, 0).kind, PoolKind::kMax);
  EXPECT_FALSE(LayerAs<PoolSpec>(*values, 0).indices_column_major);
}

// Arithmetic on integers (a convolution; ONNX's integer Add even wraps around) is not what
// float32 computes, an output of another type is not the graph's, and INT32 does not fit
// float32: each refused, naming the node or tensor.
TEST_F(OnnxImporter, RefusesIntegerGraphsThatFloat32WouldNotComputeExactly) {
  {
    OnnxModel m;
    m.Input("x", {1, 2, 5, 5}, onnx::TensorProto::UINT8);
    m.Conv("c0", "x", "y", 2, 2, 3, 1, {1, 1, 1, 1});
    m.Output("y", onnx::TensorProto::UINT8);
    auto spec = ImportOnnx(m.Save("uint8_conv.onnx"));
    ASSERT_FALSE(spec.ok());
    EXPECT_NE(spec.message().find("node 'c0' (op Conv): computes on the UINT8 input 'x', which "
                                  "sfrt runs in float32; that is exact only for MaxPool"),
              std::string::npos)
        << spec.message();
  }
  {
    OnnxModel m;
    m.Input("x", {1, 2, 4, 4}, onnx::TensorProto::UINT8);
    auto& pool = m.Node("MaxPool", {"x"}, {"y"}, "pool");
    SetInts(pool, "kernel_shape", {2, 2});
    m.Output("y");
    auto spec = ImportOnnx(m.Save("uint8_to_float.onnx"));
    ASSERT_FALSE(spec.ok());
    EXPECT_NE(spec.message().find("graph output 'y' has element type FLOAT, but the input 'x' is "
                                  "UINT8"),
              std::string::npos)
        << spec.message();
  }
  {
    OnnxModel m;
    m.Input("x", {1, 2, 4, 4}, onnx::TensorProto::INT32);
    m.Node("Relu", {"x"}, {"y"}, "relu");
    m.Output("y", onnx::TensorProto::INT32);
    auto spec = ImportOnnx(m.Save("int32.onnx"));
    ASSERT_FALSE(spec.ok());
    EXPECT_NE(spec.message().find("graph input 'x' has element type INT32, expected FLOAT (or "
                                  "INT8, UINT8, INT16, UINT16 into selection operators)"),
              std::string::npos)
        << spec.message();
  }
}

TEST_F(OnnxImporter, RefusesArithmeticThatIsNotAPerChannelScaleAndShift) {
  {
    OnnxModel m;
    m.Input("x", {1, 2, 5, 5});
    m.Floats("ramp", {1, 1, 1, 5}, {1, 2, 3, 4, 5});
    m.Node("Mul", {"x", "ramp"}, {"t"}, "ramp");
    m.Conv("c", "t", "y", 2, 2, 3, 1, {1, 1, 1, 1});
    m.Output("y");
    ExpectImportError(m.Save("ramp.onnx"),
                      {"node 'ramp' (op Mul): unsupported", "has shape [1, 1, 1, 5]",
                       "only per-channel constants"});
  }
  {
    OnnxModel m;
    m.Input("x", {1, 2, 5, 5});
    m.Floats("one", {}, {1.0f});
    m.Node("Div", {"one", "x"}, {"t"}, "invert");
    m.Conv("c", "t", "y", 2, 2, 3, 1, {1, 1, 1, 1});
    m.Output("y");
    ExpectImportError(m.Save("invert.onnx"),
                      {"node 'invert' (op Div): unsupported", "a constant divided by a tensor"});
  }
  {
    OnnxModel m;
    m.Input("x", {1, 2, 5, 5});
    m.Conv("c", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
    m.Node("Mul", {"t", "x"}, {"y"}, "square");
    m.Output("y");
    ExpectImportError(m.Save("square.onnx"),
                      {"node 'square' (op Mul): unsupported", "and a per-channel constant"});
  }
}

TEST_F(OnnxImporter, ImportsAGroupedConvWithEachGroupsWeightsAtItsOwnInputs) {
  OnnxModel m;
  m.Input("x", {1, 4, 5, 5});
  // Weight (4, 2, 3, 3): 4 outputs, 2 inputs per group, 2 groups.
  SetInt(m.Conv("grouped", "x", "y", 2, 4, 3, 1, {1, 1, 1, 1}), "group", 2);
  m.Output("y");
  auto spec = ImportOk(m.Save("group.onnx"));
  ASSERT_TRUE(spec.ok()) << spec.message();
  ASSERT_EQ(spec->layers.size(), 1u);
  const auto& c = std::get<ConvSpec>(spec->layers[0]);
  EXPECT_EQ(c.groups, 2);
  EXPECT_EQ(c.in_channels, 4);
  EXPECT_EQ(c.out_channels, 4);
  ASSERT_EQ(c.weights_hwio.size(), 3u * 3 * 2 * 4);
  for (int co = 0; co < 4; ++co) {
    for (int ci = 0; ci < 2; ++ci) {
      for (int ky = 0; ky < 3; ++ky) {
        for (int kx = 0; kx < 3; ++kx) {
          EXPECT_EQ(c.weights_hwio[static_cast<size_t>(((ky * 3 + kx) * 2 + ci) * 4 + co)],
                    WeightValue(((co * 2 + ci) * 3 + ky) * 3 + kx));
        }
      }
    }
  }
}

TEST_F(OnnxImporter, ImportsADilatedConvAndPadsItsDilatedExtentForSameUpper) {
  OnnxModel m;
  m.Input("x", {1, 2, 9, 9});
  auto& n = m.Conv("dilated", "x", "y", 2, 2, 3, 1, {});
  SetInts(n, "dilations", {2, 3});
  SetString(n, "auto_pad", "SAME_UPPER");
  m.Output("y");
  auto spec = ImportOk(m.Save("dilation.onnx"));
  ASSERT_TRUE(spec.ok()) << spec.message();
  const auto& c = std::get<ConvSpec>(spec->layers[0]);
  EXPECT_EQ(c.dilation_h, 2);
  EXPECT_EQ(c.dilation_w, 3);
  EXPECT_EQ(c.padding_rule, PaddingRule::kSameUpper);
  // Extents 5 and 7 at stride 1: 4 and 6 rows and columns of padding, halved.
  EXPECT_EQ(c.pads, (Pads{2, 3, 2, 3}));
}

TEST_F(OnnxImporter, RejectsAGroupThatDoesNotDivideTheOutputs) {
  OnnxModel m;
  m.Input("x", {1, 3, 5, 5});
  SetInt(m.Conv("grouped", "x", "y", 1, 4, 3, 1, {1, 1, 1, 1}), "group", 3);
  m.Output("y");
  ExpectImportError(m.Save("group3.onnx"),
                    {"node 'grouped' (op Conv)", "'group' = 3", "divide the weight's 4 output"});
}

TEST_F(OnnxImporter, RejectsADilationOfZero) {
  OnnxModel m;
  m.Input("x", {1, 2, 9, 9});
  SetInts(m.Conv("dilated", "x", "y", 2, 2, 3, 1, {2, 2, 2, 2}), "dilations", {0, 1});
  m.Output("y");
  ExpectImportError(m.Save("dilation0.onnx"),
                    {"node 'dilated' (op Conv)", "'dilations' = [0, 1]", "each 1..64"});
}

TEST_F(OnnxImporter, KeepsSameLowerAutoPadAsItsOwnRuleBesideSameUpperConvs) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  SetString(m.Conv("lower", "x", "h", 2, 2, 3, 2, {}), "auto_pad", "SAME_LOWER");
  m.Conv("upper", "h", "y", 2, 2, 3, 2, {0, 0, 1, 1});  // TensorFlow 'same' at 4x4
  m.Output("y");
  auto spec = ImportOk(m.Save("same_lower.onnx"));
  ASSERT_TRUE(spec.ok());
  // total 1 at in = 8, stride 2: the odd pixel goes first.
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).pads, (Pads{1, 1, 0, 0}));
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).padding_rule, PaddingRule::kSameLower);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 1).padding_rule, PaddingRule::kSameUpper);
}

// ConvTranspose's auto_pad and output_shape become pads and output padding at the traced size:
// 3 -> 6 at stride 2, kernel 3 leaves one extra row (total padding 1), cut at the start for
// SAME_LOWER; output_shape 8 needs one row more than the kernel writes (output padding 1).
TEST_F(OnnxImporter, ConvTransposeAutoPadAndOutputShapeBecomePadsAndOutputPadding) {
  struct Case {
    const char* auto_pad;
    std::vector<int64_t> output_shape;
    Pads pads;
    int output_padding;
  };
  for (const Case& c :
       {Case{"SAME_LOWER", {}, {1, 1, 0, 0}, 0}, Case{"SAME_UPPER", {}, {0, 0, 1, 1}, 0},
        Case{"NOTSET", {8, 8}, {0, 0, 0, 0}, 1}}) {
    SCOPED_TRACE(c.auto_pad);
    OnnxModel m;
    m.Input("x", {1, 1, 3, 3});
    m.Floats("w", {1, 2, 3, 3}, std::vector<float>(18, 0.5f));
    auto& n = m.Node("ConvTranspose", {"x", "w"}, {"y"}, "up");
    SetInts(n, "strides", {2, 2});
    SetString(n, "auto_pad", c.auto_pad);
    if (!c.output_shape.empty()) SetInts(n, "output_shape", c.output_shape);
    m.Output("y");
    auto spec = ImportOk(m.Save("deconv_auto_pad.onnx"));
    ASSERT_TRUE(spec.ok());
    const auto& d = LayerAs<ConvTransposeSpec>(*spec, 0);
    EXPECT_EQ(d.pads, c.pads);
    EXPECT_EQ(d.output_padding_h, c.output_padding);
    EXPECT_EQ(d.output_padding_w, c.output_padding);
  }
}

TEST_F(OnnxImporter, RejectsAnUnknownAutoPad) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  SetString(m.Conv("odd", "x", "y", 2, 2, 3, 2, {}), "auto_pad", "SAME_MIDDLE");
  m.Output("y");
  ExpectImportError(m.Save("same_middle.onnx"),
                    {"node 'odd' (op Conv)", "'auto_pad' = 'SAME_MIDDLE'", "SAME_LOWER"});
}

TEST_F(OnnxImporter, LinearResizeBecomesAResizeLayer) {
  ResizeCase rc;
  rc.scales = {1, 1, 2, 2};
  rc.mode = "linear";
  rc.ctm = "align_corners";
  auto spec = ImportOk(ResizeModel("linear.onnx", rc));
  ASSERT_TRUE(spec.ok());
  const ResizeSpec& resize = LayerAs<ResizeSpec>(*spec, 1);
  EXPECT_EQ(resize.name, "up");
  EXPECT_EQ(resize.params.mode, ResizeMode::kLinear);
  EXPECT_EQ(resize.params.coordinates, ResizeCoordinates::kAlignCorners);
}

TEST_F(OnnxImporter, RejectsAnUnknownResizeMode) {
  ResizeCase rc;
  rc.scales = {1, 1, 2, 2};
  rc.mode = "area";
  ExpectImportError(ResizeModel("area.onnx", rc),
                    {"node 'up' (op Resize)", "'mode' = 'area'", "nearest, linear, cubic"});
}

TEST_F(OnnxImporter, NonIntegerScalesAreKeptAsExactFractions) {
  ResizeCase rc;
  rc.scales = {1, 1, 1.5f, 0.6f};
  auto spec = ImportOk(ResizeModel("scale_1_5.onnx", rc));
  ASSERT_TRUE(spec.ok());
  const ResizeParams& r = LayerAs<ResizeSpec>(*spec, 1).params;
  EXPECT_EQ(r.scale_num_h, 3);
  EXPECT_EQ(r.scale_den_h, 2);
  // 0.6f is 10066330 / 2^24 exactly.
  EXPECT_EQ(static_cast<double>(r.scale_num_w) / static_cast<double>(r.scale_den_w),
            static_cast<double>(0.6f));
}

TEST_F(OnnxImporter, SizesThatAreNotMultiplesOfTheInputGiveTheirRatio) {
  ResizeCase rc;
  rc.sizes = {1, 2, 12, 20};  // 8 -> 12, 10 -> 20
  auto spec = ImportOk(ResizeModel("sizes_12.onnx", rc));
  ASSERT_TRUE(spec.ok());
  const ResizeParams& r = LayerAs<ResizeSpec>(*spec, 1).params;
  EXPECT_EQ(r.scale_num_h, 3);
  EXPECT_EQ(r.scale_den_h, 2);
  EXPECT_EQ(r.scale_num_w, 2);
  EXPECT_EQ(r.scale_den_w, 1);
}

TEST_F(OnnxImporter, RejectsResizeOfTheChannelAxis) {
  ResizeCase rc;
  rc.scales = {1, 2, 2, 2};
  ExpectImportError(ResizeModel("resize_channels.onnx", rc),
                    {"node 'up' (op Resize)", "batch or channel"});
}

TEST_F(OnnxImporter, RejectsReflectPad) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  m.Int64s("pads", {0, 0, 1, 1, 0, 0, 1, 1});
  SetString(m.Node("Pad", {"x", "pads"}, {"p"}, "mirror"), "mode", "reflect");
  m.Conv("c", "p", "y", 2, 2, 3, 1, {});
  m.Output("y");
  ExpectImportError(m.Save("reflect.onnx"), {"node 'mirror' (op Pad)", "'mode' = 'reflect'"});
}

TEST_F(OnnxImporter, RejectsNonZeroPadValue) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  m.Int64s("pads", {0, 0, 1, 1, 0, 0, 1, 1});
  m.Floats("value", {}, {0.5f});
  m.Node("Pad", {"x", "pads", "value"}, {"p"}, "grey");
  m.Conv("c", "p", "y", 2, 2, 3, 1, {});
  m.Output("y");
  ExpectImportError(m.Save("pad_value.onnx"), {"node 'grey' (op Pad)", "'constant_value' = 0.5"});
}

TEST_F(OnnxImporter, RejectsPadOnTheChannelAxis) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  m.Int64s("pads", {0, 1, 0, 0, 0, 0, 0, 0});
  m.Node("Pad", {"x", "pads"}, {"p"}, "chpad");
  m.Conv("c", "p", "y", 3, 2, 3, 1, {});
  m.Output("y");
  ExpectImportError(m.Save("pad_channels.onnx"),
                    {"node 'chpad' (op Pad)", "[0, 1, 0, 0, 0, 0, 0, 0]", "batch or channel"});
}

TEST_F(OnnxImporter, RejectsPadNotFollowedByConv) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  m.Int64s("pads", {0, 0, 1, 1, 0, 0, 1, 1});
  m.Node("Pad", {"x", "pads"}, {"p"}, "lonely");
  m.Floats("scales", {4}, {1, 1, 2, 2});
  m.Node("Resize", {"p", "", "scales"}, {"y"}, "up");
  m.Output("y");
  ExpectImportError(m.Save("pad_resize.onnx"),
                    {"node 'lonely' (op Pad)", "followed by a Conv", "node 'up' (op Resize)"});
}

TEST_F(OnnxImporter, RejectsSliceWithStepTwo) {
  OnnxModel m;
  m.Input("x", {1, 2, 8, 8});
  m.Int64s("starts", {0});
  m.Int64s("ends", {8});
  m.Int64s("axes", {2});
  m.Int64s("steps", {2});
  m.Node("Slice", {"x", "starts", "ends", "axes", "steps"}, {"y"}, "strided");
  m.Output("y");
  ExpectImportError(m.Save("slice_step.onnx"), {"node 'strided' (op Slice)", "'steps' = [2]"});
}

TEST_F(OnnxImporter, RejectsSliceOfTheChannelAxis) {
  OnnxModel m;
  m.Input("x", {1, 4, 8, 8});
  m.Int64s("starts", {0});
  m.Int64s("ends", {2});
  m.Int64s("axes", {1});
  m.Node("Slice", {"x", "starts", "ends", "axes"}, {"y"}, "half");
  m.Output("y");
  ExpectImportError(m.Save("slice_channels.onnx"), {"node 'half' (op Slice)", "axis 1 (channels)"});
}

TEST_F(OnnxImporter, ActivationThatDoesNotFollowAConvBecomesItsOwnLayer) {
  OnnxModel m;
  m.Input("x", {1, 2, 4, 4});
  m.Floats("scales", {4}, {1, 1, 2, 2});
  m.Node("Resize", {"x", "", "scales"}, {"u"}, "up");
  m.Node("Relu", {"u"}, {"y"}, "late_relu");
  m.Output("y");
  auto spec = ImportOk(m.Save("relu_after_resize.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 2u);
  EXPECT_EQ(LayerAs<ChannelAffineSpec>(*spec, 1).activation, Activation::kRelu);
}

TEST_F(OnnxImporter, ConvOutputThatOnlyAShapeReadsBesidesItsActivationStillFuses) {
  // c0's output feeds its LeakyRelu and conv 'side', whose output only a Shape reads (it sets the
  // Resize size, a constant at the static input shape): 'side' is no layer, and the activation
  // fuses into c0 as in a chain.
  OnnxModel m;
  m.Input("x", {1, 2, 4, 4});
  m.Conv("c0", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("LeakyRelu", {"t"}, {"u"}, "act");
  m.Conv("side", "t", "v", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("Shape", {"v"}, {"v_shape"}, "side_shape");
  m.Int64s("mult", {1, 1, 2, 2});
  m.Node("Mul", {"v_shape", "mult"}, {"sizes"}, "sizes");
  SetString(m.Node("Resize", {"u", "", "", "sizes"}, {"y"}, "up"), "coordinate_transformation_mode",
            "asymmetric");
  m.Output("y");
  auto spec = ImportOk(m.Save("shape_only_branch.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 2u);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).activation, Activation::kLeakyRelu);
  EXPECT_FALSE(IsGraph(*spec));
}

TEST_F(OnnxImporter, ActivationOfAConvOutputThatAnotherLayerReadsBecomesItsOwnLayer) {
  // c0's output feeds its LeakyRelu and conv 'side', both concatenated: the activation cannot
  // be fused into c0, so it is a ChannelAffine of its own (scale 1, shift 0).
  OnnxModel m;
  m.Input("x", {1, 2, 4, 4});
  m.Conv("c0", "x", "t", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Node("LeakyRelu", {"t"}, {"u"}, "act");
  m.Conv("side", "t", "v", 2, 2, 3, 1, {1, 1, 1, 1});
  SetInt(m.Node("Concat", {"u", "v"}, {"y"}, "cat"), "axis", 1);
  m.Output("y");
  auto spec = ImportOk(m.Save("branch.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 4u);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).activation, Activation::kNone);
  const auto& act = LayerAs<ChannelAffineSpec>(*spec, 1);
  EXPECT_EQ(act.name, "act");
  EXPECT_EQ(act.inputs, std::vector<std::string>{"c0"});
  EXPECT_EQ(act.scale, std::vector<float>(2, 1.0f));
  EXPECT_EQ(act.shift, std::vector<float>(2, 0.0f));
  EXPECT_EQ(act.activation, Activation::kLeakyRelu);
  EXPECT_FLOAT_EQ(act.leaky_slope, 0.01f);
}

// A U-Net step and a residual: x -> c0 (relu) -> c1; add(c0, c1) + relu; concat(add, c0) -> c2.
TEST_F(OnnxImporter, ConcatAndAddBecomeGraphLayersNamingWhatTheyRead) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 7});
  m.Conv("c0", "x", "a0", 2, 3, 3, 1, {1, 1, 1, 1});
  m.Node("Relu", {"a0"}, {"a"}, "r0");
  m.Conv("c1", "a", "b", 3, 3, 3, 1, {1, 1, 1, 1});
  m.Node("Add", {"a", "b"}, {"s0"}, "sum");
  m.Node("Relu", {"s0"}, {"s"}, "r1");
  SetInt(m.Node("Concat", {"s", "a"}, {"cat_out"}, "cat"), "axis", -3);
  m.Conv("c2", "cat_out", "y", 6, 3, 1, 1, {});
  m.Output("y");
  auto spec = ImportOk(m.Save("unet_step.onnx"));
  ASSERT_TRUE(spec.ok());
  ASSERT_EQ(spec->layers.size(), 5u);
  EXPECT_TRUE(IsGraph(*spec));
  EXPECT_EQ(spec->input.name, "x");
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).inputs, std::vector<std::string>{"x"});
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 0).activation, Activation::kRelu);
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 1).inputs, std::vector<std::string>{"c0"});
  const AddSpec& add = LayerAs<AddSpec>(*spec, 2);
  EXPECT_EQ(add.name, "sum");
  EXPECT_EQ(add.inputs, (std::vector<std::string>{"c0", "c1"}));
  EXPECT_EQ(add.activation, Activation::kRelu);
  EXPECT_EQ(LayerAs<ConcatSpec>(*spec, 3).inputs, (std::vector<std::string>{"sum", "c0"}));
  EXPECT_EQ(LayerAs<ConvSpec>(*spec, 4).in_channels, 6);
  // The file it makes loads as a graph.
  auto bytes = SerializeModel(*spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
  EXPECT_FALSE((*model)->is_chain());
}

// An upsampled tensor sliced back to its skip tensor's size before a Concat (a U-Net decoder
// at an odd size) is a crop to that tensor's size, which holds at every input size.
TEST_F(OnnxImporter, SliceOfAnUpsamplingBeforeAConcatCropsToTheSkipTensorsSize) {
  OnnxModel m;
  m.Input("x", {1, 2, 9, 11});
  m.Conv("enc", "x", "e", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Conv("down", "e", "d", 2, 4, 3, 2, {1, 1, 1, 1});  // 5x6
  m.Floats("scales", {4}, {1, 1, 2, 2});
  auto& up = m.Node("Resize", {"d", "", "scales"}, {"u"}, "up");
  SetString(up, "coordinate_transformation_mode", "asymmetric");
  SetString(up, "nearest_mode", "floor");
  m.Int64s("starts", {0, 0});
  m.Int64s("ends", {9, 11});
  m.Int64s("axes", {2, 3});
  m.Node("Slice", {"u", "starts", "ends", "axes"}, {"c"}, "fit");  // 10x12 -> 9x11
  SetInt(m.Node("Concat", {"c", "e"}, {"cat_out"}, "cat"), "axis", 1);
  m.Conv("dec", "cat_out", "y", 6, 3, 3, 1, {1, 1, 1, 1});
  m.Output("y");
  auto spec = ImportOk(m.Save("unet_crop.onnx"));
  ASSERT_TRUE(spec.ok());
  const CropSpec& crop = LayerAs<CropSpec>(*spec, 3);
  EXPECT_EQ(crop.rule, CropRule::kToSecondInput);
  EXPECT_EQ(crop.inputs, (std::vector<std::string>{"up", "enc"}));
  EXPECT_FALSE(crop.excess_rows_from_top);
  EXPECT_FALSE(crop.excess_cols_from_left);
  auto bytes = SerializeModel(*spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  ASSERT_TRUE(model.ok()) << model.message();
}

TEST_F(OnnxImporter, ConcatAlongAnotherAxisOrAddWithBroadcastingIsRefused) {
  {
    OnnxModel m;
    m.Input("x", {1, 2, 4, 4});
    m.Conv("c0", "x", "a", 2, 2, 3, 1, {1, 1, 1, 1});
    SetInt(m.Node("Concat", {"a", "x"}, {"y"}, "wide"), "axis", 3);
    m.Output("y");
    ExpectImportError(m.Save("concat_w.onnx"),
                      {"node 'wide' (op Concat)", "along axis 3", "only the channel axis"});
  }
  {
    OnnxModel m;
    m.Input("x", {1, 2, 4, 4});
    m.Conv("c0", "x", "a", 2, 1, 3, 1, {1, 1, 1, 1});
    m.Node("Add", {"a", "x"}, {"y"}, "bcast");
    m.Output("y");
    ExpectImportError(m.Save("add_bcast.onnx"),
                      {"node 'bcast' (op Add)", "(1, 1, 4, 4)", "(1, 2, 4, 4)", "no broadcasting"});
  }
}

TEST_F(OnnxImporter, RejectsTwoGraphOutputs) {
  OnnxModel m;
  m.Input("x", {1, 2, 4, 4});
  m.Conv("c0", "x", "a", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Conv("c1", "a", "y", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Output("a");
  m.Output("y");
  ExpectImportError(m.Save("two_outputs.onnx"), {"2 outputs"});
}

TEST_F(OnnxImporter, RejectsNonConstantWeights) {
  OnnxModel m;
  m.Input("x", {1, 1, 3, 3});
  m.Node("Conv", {"x", "x"}, {"y"}, "self");
  m.Output("y");
  ExpectImportError(m.Save("weights_from_input.onnx"),
                    {"node 'self' (op Conv)", "input 1 'x' depends on the network input"});
}

TEST_F(OnnxImporter, RejectsMissingFile) {
  const std::string path = (TestDir() / "no_such_model.onnx").string();
  std::filesystem::remove(path);
  ExpectImportError(path, {"cannot open"});
}

TEST_F(OnnxImporter, RejectsGarbageBytes) {
  const std::string path = (TestDir() / "garbage.onnx").string();
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f << "this is not an ONNX model\n\xff\xfe\x01\x02";
  }
  ExpectImportError(path, {"not a valid ONNX file"});
}

TEST_F(OnnxImporter, RejectsEmptyFile) {
  const std::string path = (TestDir() / "empty.onnx").string();
  { std::ofstream f(path, std::ios::binary | std::ios::trunc); }
  ExpectImportError(path, {"not a valid ONNX file"});
}

TEST_F(OnnxImporter, RejectsOpsetsOutside11To17) {
  for (int64_t opset : {9, 10, 18}) {
    OnnxModel m(opset);
    m.Input("x", {1, 2, 4, 4});
    m.Conv("c", "x", "y", 2, 2, 3, 1, {1, 1, 1, 1});
    m.Output("y");
    ExpectImportError(m.Save("opset" + std::to_string(opset) + ".onnx"),
                      {"opset " + std::to_string(opset) + " is not supported", "11 to 17"});
  }
  for (int64_t opset : {11, 17}) {
    OnnxModel m(opset);
    m.Input("x", {1, 2, 4, 4});
    m.Conv("c", "x", "y", 2, 2, 3, 1, {1, 1, 1, 1});
    m.Output("y");
    auto spec = ImportOk(m.Save("opset" + std::to_string(opset) + ".onnx"));
  }
}

TEST_F(OnnxImporter, RejectsSymbolicInputDimension) {
  OnnxModel m;
  m.Input("x", {1, 2, 4, 4});
  m.graph()
      .mutable_input(0)
      ->mutable_type()
      ->mutable_tensor_type()
      ->mutable_shape()
      ->mutable_dim(2)
      ->set_dim_param("height");
  m.Conv("c", "x", "y", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Output("y");
  ExpectImportError(m.Save("symbolic.onnx"), {"graph input 'x'", "dimension 2 (H)", "'height'"});
}

TEST_F(OnnxImporter, RejectsBatchOtherThanOne) {
  OnnxModel m;
  m.Input("x", {2, 2, 4, 4});
  m.Conv("c", "x", "y", 2, 2, 3, 1, {1, 1, 1, 1});
  m.Output("y");
  ExpectImportError(m.Save("batch2.onnx"), {"graph input 'x'", "batch size 2"});
}

TEST_F(OnnxImporter, RejectsExternalTensorData) {
  OnnxModel m;
  m.Input("x", {1, 2, 4, 4});
  m.Conv("c", "x", "y", 2, 2, 3, 1, {1, 1, 1, 1});
  auto* w = m.graph().mutable_initializer(0);
  w->clear_raw_data();
  w->set_data_location(onnx::TensorProto::EXTERNAL);
  auto* entry = w->add_external_data();
  entry->set_key("location");
  entry->set_value("weights.bin");
  m.Output("y");
  ExpectImportError(m.Save("external.onnx"), {"'c.w'", "external data"});
}

TEST_F(OnnxImporter, RejectsWeightsWithTooFewValues) {
  OnnxModel m;
  m.Input("x", {1, 2, 4, 4});
  m.Conv("c", "x", "y", 2, 2, 3, 1, {1, 1, 1, 1});
  m.graph().mutable_initializer(0)->mutable_raw_data()->resize(12);
  m.Output("y");
  ExpectImportError(m.Save("short_weights.onnx"), {"node 'c' (op Conv)", "'c.w'", "12 bytes"});
}

TEST_F(OnnxImporter, ErrorMessagesStayOnOneLineWhateverTheNames) {
  OnnxModel m;
  m.Input("x", {1, 2, 5, 5});
  m.Node("Softsign", {"x"}, {"y"}, "bad\nname");
  m.Output("y");
  ExpectImportError(m.Save("newline.onnx"), {"bad?name", "(op Softsign)"});
}

// Found by fuzz_onnx_import: a 1-channel network kept the default image order (four images, 12
// channels), which the loader rejects. The file does not say which images other channel counts
// hold, so the spec names none, and the written file loads.
TEST_F(OnnxImporter, InputThatIsNotTwelveChannelsGetsNoImageOrderAndTheWrittenFileLoads) {
  OnnxModel m;
  m.Input("x", {1, 1, 4, 4});
  m.Conv("c", "x", "y", 1, 2, 3, 1, {1, 1, 1, 1});
  m.Output("y");
  auto spec = ImportOk(m.Save("one_channel.onnx"));
  ASSERT_TRUE(spec.ok());
  EXPECT_TRUE(spec->input.image_order.empty());
  auto bytes = SerializeModel(*spec);
  ASSERT_TRUE(bytes.ok()) << bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  EXPECT_TRUE(model.ok()) << model.message();
  OnnxModel twelve;
  twelve.Input("x", {1, 12, 4, 4});
  twelve.Conv("c", "x", "y", 12, 3, 3, 1, {1, 1, 1, 1});
  twelve.Output("y");
  auto stereo = ImportOk(twelve.Save("twelve.onnx"));
  ASSERT_TRUE(stereo.ok());
  EXPECT_EQ(stereo->input.image_order.size(), 4u);
}

// ------------------------------------------------------------------------------ loader limits
// Each limit of sfrt/model_limits.h is checked at import, naming the node and the attribute, so
// an imported model never serialises to a file the loader rejects (tests/exporter/model_limits_test
// checks the loader enforces the same numbers).

TEST_F(OnnxImporter, ConvKernelAboveTheLoaderLimitNamesNodeAndKernelShape) {
  const int64_t k = model_limits::kMaxKernel + 1;
  OnnxModel m;
  m.Input("x", {1, 1, k + 2, k + 2});
  m.Conv("big", "x", "y", 1, 1, k, 1, {});
  m.Output("y");
  ExpectImportError(
      m.Save("kernel.onnx"),
      {"node 'big' (op Conv)", "attribute 'kernel_shape' = [32, 32]", "largest kernel side 31"});
}

TEST_F(OnnxImporter, ConvStrideAboveTheLoaderLimitNamesNodeAndStrides) {
  OnnxModel m;
  m.Input("x", {1, 1, 40, 40});
  m.Conv("far", "x", "y", 1, 1, 1, model_limits::kMaxStride + 1, {});
  m.Output("y");
  ExpectImportError(m.Save("stride.onnx"), {"node 'far' (op Conv)",
                                            "attribute 'strides' = [17, 17]", "largest stride 16"});
}

TEST_F(OnnxImporter, ConvOutputChannelsAboveTheLoaderLimitNameNodeAndWeight) {
  const int64_t c = model_limits::kMaxChannels + 1;
  OnnxModel m;
  m.Input("x", {1, 1, 2, 2});
  m.Conv("wide", "x", "y", 1, c, 1, 1, {}, /*bias=*/false);
  m.Output("y");
  ExpectImportError(
      m.Save("channels.onnx"),
      {"node 'wide' (op Conv)", "weight 'wide.w' has 65537 output channels", "at most 65536"});
}

TEST_F(OnnxImporter, InputChannelsAboveTheLoaderLimitNameTheGraphInput) {
  OnnxModel m;
  m.Input("x", {1, model_limits::kMaxChannels + 1, 1, 1});
  m.Node("Identity", {"x"}, {"y"}, "id");
  m.Output("y");
  ExpectImportError(m.Save("input_channels.onnx"),
                    {"graph input 'x' has 65537 channels", "at most 65536"});
}

TEST_F(OnnxImporter, ConvPadsAboveKernelMinusOneNameNodeAndPads) {
  OnnxModel m;
  m.Input("x", {1, 1, 8, 8});
  m.Conv("conv0", "x", "y", 1, 1, 3, 1, {0, 1152, 0, 0});
  m.Output("y");
  const std::string path = m.Save("pads.onnx");
  ExpectImportError(path, {"node 'conv0' (op Conv): attribute 'pads' = [0, 1152, 0, 0]",
                           "exceed the kernel's extent - 1", "at most 2 top/bottom, 2 left/right"});
  // One past the limit on each side is refused; the limit itself imports.
  for (int side = 0; side < 4; ++side) {
    std::vector<int64_t> pads = {0, 0, 0, 0};
    pads[side] = model_limits::MaxPad(3) + 1;
    OnnxModel one;
    one.Input("x", {1, 1, 8, 8});
    one.Conv("conv0", "x", "y", 1, 1, 3, 1, pads);
    one.Output("y");
    ExpectImportError(one.Save("pads_side.onnx"), {"node 'conv0' (op Conv)", "attribute 'pads'"});
    pads[side] = model_limits::MaxPad(3);
    OnnxModel ok;
    ok.Input("x", {1, 1, 8, 8});
    ok.Conv("conv0", "x", "y", 1, 1, 3, 1, pads);
    ok.Output("y");
    EXPECT_TRUE(ImportOk(ok.Save("pads_ok.onnx")).ok()) << "side " << side;
  }
}

TEST_F(OnnxImporter, PadNodeFoldedIntoConvPastKernelMinusOneNamesBothNodes) {
  OnnxModel m;
  m.Input("x", {1, 1, 8, 8});
  m.Int64s("pads", {0, 0, 0, 2, 0, 0, 0, 0});
  m.Node("Pad", {"x", "pads"}, {"p"}, "wide_pad");
  m.Conv("conv0", "p", "y", 1, 1, 3, 1, {0, 1, 0, 0});
  m.Output("y");
  ExpectImportError(m.Save("pad_fold.onnx"),
                    {"node 'conv0' (op Conv): attribute 'pads' = [0, 3, 0, 0]",
                     "node 'wide_pad' (op Pad) folded in", "exceed the kernel's extent - 1"});
}

TEST_F(OnnxImporter, UpsampleFactorAboveTheLoaderLimitNamesNodeAndScales) {
  OnnxModel m;
  m.Input("x", {1, 1, 2, 2});
  m.Conv("c", "x", "t", 1, 1, 1, 1, {});
  m.Floats("scales", {4}, {1, 1, 1, static_cast<float>(model_limits::kMaxUpsample + 1)});
  m.Node("Resize", {"t", "", "scales"}, {"y"}, "up");
  m.Output("y");
  ExpectImportError(m.Save("upsample.onnx"),
                    {"node 'up' (op Resize)", "input 'scales' = [1, 1, 1, 65]",
                     "value 65 on axis 3 is not in (0, 64]"});
}

TEST_F(OnnxImporter, MoreLayersThanTheLoaderLimitAreRefusedWithTheirCount) {
  OnnxModel m;
  m.Input("x", {1, 1, 2, 2});
  m.Conv("c", "x", "t0", 1, 1, 1, 1, {});
  m.Floats("ones", {4}, {1, 1, 1, 1});
  std::string in = "t0";
  for (int i = 1; i <= model_limits::kMaxLayers; ++i) {
    const std::string out = i == model_limits::kMaxLayers ? "y" : "t" + std::to_string(i);
    m.Node("Resize", {in, "", "ones"}, {out}, "up" + std::to_string(i));
    in = out;
  }
  m.Output("y");
  ExpectImportError(m.Save("layers.onnx"), {"graph gives 4097 layers; at most 4096"});
}

}  // namespace
}  // namespace sfrt::exporter
