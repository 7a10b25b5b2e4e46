// Every limit in sfrt/model_limits.h is the loader's: a model at the limit loads, one past it is
// rejected with a message that names the field. The importers check the same table, so these
// tests keep the table and the loader from drifting apart.
#include "sfrt/model_limits.h"

#include <gtest/gtest.h>

#include <string>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/model.h"

namespace sfrt::exporter {
namespace {

ConvSpec MakeConv(int in, int out, int kh, int kw) {
  ConvSpec c;
  c.name = "c";
  c.in_channels = in;
  c.out_channels = out;
  c.kernel_h = kh;
  c.kernel_w = kw;
  c.weights_hwio.assign(static_cast<size_t>(kh) * kw * in * out, 0.01f);
  c.bias.assign(static_cast<size_t>(out), 0.0f);
  return c;
}

ModelSpec OneConv(const ConvSpec& conv) {
  ModelSpec spec;
  spec.input.channels = conv.in_channels;
  spec.input.image_order.clear();
  exporter::SetOutputChannels(spec, conv.out_channels);
  spec.output.channel_names.clear();
  spec.layers.emplace_back(conv);
  return spec;
}

// Loads `spec` through the writer; returns "" when it loads, else the loader's message.
std::string LoadMessage(const ModelSpec& spec) {
  auto bytes = SerializeModel(spec);
  if (!bytes.ok()) return "writer: " + bytes.message();
  auto model = Model::LoadBuffer(bytes->data(), bytes->size(), BufferOwnership::kCopy);
  return model.ok() ? std::string() : model.message();
}

void ExpectLoads(const ModelSpec& spec) { EXPECT_EQ(LoadMessage(spec), ""); }

void ExpectRejected(const ModelSpec& spec, const std::string& part) {
  const std::string m = LoadMessage(spec);
  EXPECT_NE(m, "") << "the loader accepted a model past the limit";
  EXPECT_EQ(m.rfind("writer: ", 0), std::string::npos) << m;
  EXPECT_NE(m.find(part), std::string::npos) << "'" << part << "' missing in: " << m;
}

TEST(ModelLimits, LoaderEnforcesMaxKernelExactly) {
  ExpectLoads(OneConv(MakeConv(1, 1, model_limits::kMaxKernel, 1)));
  ExpectRejected(OneConv(MakeConv(1, 1, model_limits::kMaxKernel + 1, 1)), "kernel is");
  ExpectRejected(OneConv(MakeConv(1, 1, 1, model_limits::kMaxKernel + 1)), "kernel is");
}

TEST(ModelLimits, LoaderEnforcesMaxStrideExactly) {
  ConvSpec c = MakeConv(1, 1, 1, 1);
  c.stride_h = c.stride_w = model_limits::kMaxStride;
  ExpectLoads(OneConv(c));
  c.stride_w = model_limits::kMaxStride + 1;
  ExpectRejected(OneConv(c), "stride is");
}

TEST(ModelLimits, LoaderEnforcesMaxChannelsExactlyOnConvOutputAndInput) {
  ExpectLoads(OneConv(MakeConv(1, model_limits::kMaxChannels, 1, 1)));
  ExpectRejected(OneConv(MakeConv(1, model_limits::kMaxChannels + 1, 1, 1)), "out_channels is");
  ExpectLoads(OneConv(MakeConv(model_limits::kMaxChannels, 1, 1, 1)));
  ExpectRejected(OneConv(MakeConv(model_limits::kMaxChannels + 1, 1, 1, 1)), "input.channels is");
}

TEST(ModelLimits, LoaderEnforcesMaxPadOfKernelMinusOneOnEverySide) {
  for (int side = 0; side < 4; ++side) {
    ConvSpec c = MakeConv(1, 1, 3, 5);
    int& amount = side == 0   ? c.pads.top
                  : side == 1 ? c.pads.left
                  : side == 2 ? c.pads.bottom
                              : c.pads.right;
    const int kernel = side % 2 == 0 ? c.kernel_h : c.kernel_w;
    amount = model_limits::MaxPad(kernel);
    ExpectLoads(OneConv(c));
    amount = model_limits::MaxPad(kernel) + 1;
    ExpectRejected(OneConv(c), "pads.");
  }
}

TEST(ModelLimits, LoaderEnforcesMaxUpsampleExactly) {
  ModelSpec spec = OneConv(MakeConv(1, 1, 1, 1));
  UpsampleSpec up;
  up.name = "up";
  up.factor_h = up.factor_w = model_limits::kMaxUpsample;
  spec.layers.emplace_back(up);
  ExpectLoads(spec);
  std::get<UpsampleSpec>(spec.layers.back()).factor_h = model_limits::kMaxUpsample + 1;
  ExpectRejected(spec, "upsampling factor is");
}

TEST(ModelLimits, LoaderEnforcesMaxLayersExactly) {
  ModelSpec spec = OneConv(MakeConv(1, 1, 1, 1));
  UpsampleSpec up;
  up.factor_h = up.factor_w = 1;
  for (int i = 1; i < model_limits::kMaxLayers; ++i) {
    up.name = "up" + std::to_string(i);
    spec.layers.emplace_back(up);
  }
  ExpectLoads(spec);
  spec.layers.emplace_back(up);
  ExpectRejected(spec, "layers; at most");
}

}  // namespace
}  // namespace sfrt::exporter
