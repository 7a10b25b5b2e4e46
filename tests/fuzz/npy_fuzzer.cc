// Fuzz target: the .npy reader. An array it accepts must survive SerializeNpy -> ParseNpy
// unchanged (shape and bits).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string_view>

#include "sfrt/pipeline/io/npy.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  auto array = sfrt::io::ParseNpy(bytes, "fuzz.npy");
  if (!array.ok()) return 0;
  if (array->data.size() != array->element_count()) {
    std::fprintf(stderr, "accepted .npy holds %zu values for shape %s\n", array->data.size(),
                 array->ShapeString().c_str());
    std::abort();
  }
  auto again = sfrt::io::SerializeNpy(array->shape, array->data);
  if (!again.ok()) {
    std::fprintf(stderr, "accepted .npy does not serialise: %s\n", again.message().c_str());
    std::abort();
  }
  auto back = sfrt::io::ParseNpy(
      std::string_view(reinterpret_cast<const char*>(again->data()), again->size()), "again.npy");
  if (!back.ok() || back->shape != array->shape || back->data.size() != array->data.size() ||
      (!array->data.empty() && std::memcmp(back->data.data(), array->data.data(),
                                           array->data.size() * sizeof(float)) != 0)) {
    std::fprintf(stderr, ".npy round trip changed the array\n");
    std::abort();
  }
  return 0;
}
