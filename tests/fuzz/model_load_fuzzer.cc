// Fuzz target: the model file loader with every check on (size, identifier, version, FlatBuffers
// verifier, semantic checks, CRC-32C). Any input must load or fail with a Status; nothing else.
#include <cstddef>
#include <cstdint>

#include "sfrt/model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto model = sfrt::Model::LoadBuffer(data, size, sfrt::BufferOwnership::kCopy, {}, "fuzz");
  if (model.ok()) {
    // A loaded model's description must be readable end to end.
    volatile size_t params = (*model)->parameter_count();
    (void)params;
  }
  return 0;
}
