// Fuzz target: the Keras HDF5 importer on an in-memory file image (HDF5's core driver). A model
// it accepts must serialise to a model file that the runtime loads.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "sfrt/exporter/keras_importer.h"
#include "sfrt/exporter/model_writer.h"
#include "sfrt/model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view image(reinterpret_cast<const char*>(data), size);
  auto imported = sfrt::exporter::ImportKerasH5FromMemory(image, "fuzz.h5");
  if (!imported.ok()) return 0;
  auto file = sfrt::exporter::SerializeModel(imported->spec);
  if (!file.ok()) return 0;
  auto model = sfrt::Model::LoadBuffer(file->data(), file->size(), sfrt::BufferOwnership::kCopy);
  if (!model.ok()) {
    std::fprintf(stderr, "imported Keras model serialises to a file the loader rejects: %s\n",
                 model.message().c_str());
    std::abort();
  }
  return 0;
}
