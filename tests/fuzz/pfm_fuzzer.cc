// Fuzz target: the PFM reader. An image it accepts must survive SerializePfm -> ParsePfm
// unchanged (bit for bit, NaNs included).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string_view>

#include "sfrt/pipeline/io/pfm.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  auto image = sfrt::io::ParsePfm(bytes, "fuzz.pfm");
  if (!image.ok()) return 0;
  auto again = sfrt::io::SerializePfm(image->data, image->height, image->width, image->channels);
  if (!again.ok()) {
    std::fprintf(stderr, "accepted PFM does not serialise: %s\n", again.message().c_str());
    std::abort();
  }
  auto back = sfrt::io::ParsePfm(
      std::string_view(reinterpret_cast<const char*>(again->data()), again->size()), "again.pfm");
  if (!back.ok() || back->height != image->height || back->width != image->width ||
      back->channels != image->channels || back->data.size() != image->data.size() ||
      (!image->data.empty() && std::memcmp(back->data.data(), image->data.data(),
                                           image->data.size() * sizeof(float)) != 0)) {
    std::fprintf(stderr, "PFM round trip changed the image\n");
    std::abort();
  }
  return 0;
}
