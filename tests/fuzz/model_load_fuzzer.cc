// Fuzz target: the model file loader (size, identifier, version, FlatBuffers verifier, semantic
// checks, CRC-32C). Any input must load or fail with a Status; nothing else.
// Schema 1.1 files carry a CRC over the whole file, so almost every mutation of a valid seed
// would stop at the checksum; the last input byte therefore turns checksum verification off
// for most inputs, letting mutations reach the verifier and the semantic checks behind it.
#include <cstddef>
#include <cstdint>

#include "sfrt/model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sfrt::LoadOptions options;
  options.verify_checksum = size > 0 && data[size - 1] % 8 == 0;
  auto model = sfrt::Model::LoadBuffer(data, size, sfrt::BufferOwnership::kCopy, options, "fuzz");
  if (model.ok()) {
    // A loaded model's description must be readable end to end.
    volatile size_t params = (*model)->parameter_count();
    (void)params;
  }
  return 0;
}
