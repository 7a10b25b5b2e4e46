// Writes small valid .sfrt model files into a directory, as seeds for the model fuzz targets and
// the fault-injection test: SceneEDNet at 1/16 and 1/64 width (fp32), 1/64 width with fp16
// weights, a three-layer chain with explicit padding and an explicit crop, and SceneEDNet-U at
// 1/64 width with a residual Add (a graph: named inputs, Concat, Add, crops to a second input).
// Usage: sfrt_fuzz_make_model_seeds OUT_DIR
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/unet_spec.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/sceneednet_spec.h"

namespace {

sfrt::exporter::ModelSpec ExplicitChain() {
  using namespace sfrt::exporter;
  ModelSpec spec;
  spec.name = "explicit-chain";
  ConvSpec conv;
  conv.name = "conv";
  conv.in_channels = 12;
  conv.out_channels = 4;
  conv.stride_h = 2;
  conv.stride_w = 1;
  conv.pads = {1, 0, 2, 1};
  conv.activation = Activation::kRelu;
  conv.weights_hwio.assign(static_cast<size_t>(3 * 3 * 12 * 4), 0.25f);
  conv.bias.assign(4, -0.5f);
  spec.layers.push_back(conv);
  spec.layers.push_back(UpsampleSpec{"up", 2, 3, {}});
  spec.layers.push_back(CropSpec{"crop", CropRule::kExplicit, {1, 1, 0, 2}, true, true, {}});
  ConvSpec out;
  out.name = "output";
  out.in_channels = 4;
  out.out_channels = 3;
  out.kernel_h = out.kernel_w = 1;
  out.weights_hwio.assign(static_cast<size_t>(4 * 3), 0.5f);
  out.bias.assign(3, 0.0f);
  spec.layers.push_back(out);
  return spec;
}

bool Write(const std::filesystem::path& path, const sfrt::exporter::ModelSpec& spec) {
  auto bytes = sfrt::exporter::SerializeModel(spec);
  if (!bytes.ok()) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), bytes.message().c_str());
    return false;
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes->data()),
            static_cast<std::streamsize>(bytes->size()));
  out.close();
  if (!out) {
    std::fprintf(stderr, "%s: cannot write\n", path.c_str());
    return false;
  }
  std::printf("%s (%zu bytes)\n", path.c_str(), bytes->size());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  const std::filesystem::path dir = argv[1];
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  auto w64_fp16 = sfrt::exporter::SceneEdNetSpec(64, 3);
  w64_fp16.weight_type = sfrt::WeightType::kFloat16;
  const bool ok = Write(dir / "sceneednet-w16.sfrt", sfrt::exporter::SceneEdNetSpec(16, 1)) &&
                  Write(dir / "sceneednet-w64.sfrt", sfrt::exporter::SceneEdNetSpec(64, 2)) &&
                  Write(dir / "sceneednet-w64-fp16.sfrt", w64_fp16) &&
                  Write(dir / "explicit-chain.sfrt", ExplicitChain()) &&
                  Write(dir / "sceneednet-u-w64.sfrt", sfrt::testing::SceneEdNetUSpec(64, 4, true));
  return ok ? 0 : 1;
}
