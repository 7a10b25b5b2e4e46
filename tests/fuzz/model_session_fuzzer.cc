// Fuzz target: the model loader without the checksum (so mutations reach the semantic checks
// instead of stopping at the CRC), then, for a model that loads, a Session planned for a small
// maximum size and run on zeros at two sizes. Loading, planning and running must never crash,
// whatever the file holds; planning may refuse a model with a Status.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "sfrt/model.h"
#include "sfrt/session.h"

namespace {

constexpr int kMaxSide = 16;

void RunAt(sfrt::Session& session, int height, int width) {
  auto shape = session.OutputShape(height, width);
  if (!shape.ok()) return;
  const int channels = session.model().metadata().input.channels;
  std::vector<float> input(static_cast<size_t>(height) * width * channels, 0.0f);
  std::vector<float> output(shape->elements(), 0.0f);
  (void)session.Run(input, height, width, output);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sfrt::LoadOptions load;
  load.verify_checksum = false;
  auto model = sfrt::Model::LoadBuffer(data, size, sfrt::BufferOwnership::kCopy, load, "fuzz");
  if (!model.ok()) return 0;
  sfrt::SessionOptions options;
  options.max_height = kMaxSide;
  options.max_width = kMaxSide;
  options.threads = 1;
  auto session = sfrt::Session::Create(*model, options);
  if (!session.ok()) return 0;
  RunAt(**session, kMaxSide, kMaxSide);
  RunAt(**session, 7, 5);
  return 0;
}
