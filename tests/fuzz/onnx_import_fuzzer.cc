// Fuzz target: the ONNX importer on bytes in memory. A graph it accepts must serialise to a model
// file that the runtime loads (the exporter never writes a file the loader rejects).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "sfrt/exporter/model_writer.h"
#include "sfrt/exporter/onnx_importer.h"
#include "sfrt/model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  auto spec = sfrt::exporter::ImportOnnxFromMemory(bytes, "fuzz.onnx");
  if (!spec.ok()) return 0;
  auto file = sfrt::exporter::SerializeModel(*spec);
  if (!file.ok()) return 0;  // e.g. a layer the writer refuses: a Status, fine
  auto model = sfrt::Model::LoadBuffer(file->data(), file->size(), sfrt::BufferOwnership::kCopy);
  if (!model.ok()) {
    std::fprintf(stderr, "imported ONNX serialises to a file the loader rejects: %s\n",
                 model.message().c_str());
    std::abort();
  }
  return 0;
}
