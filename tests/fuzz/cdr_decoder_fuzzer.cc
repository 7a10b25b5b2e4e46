// Fuzz target: the ROS 2 CDR decoders (ros2/src/messages.h). The input is decoded as every
// message type; a message a decoder accepts must survive Encode -> Decode unchanged, and the
// zero-copy Image view must agree with the owning Image decoder, decoding and encoding. "Unchanged"
// is judged on the re-encoded bytes, not operator==: a float64 NaN from the input is not equal to
// itself, and Encode writes every field, so equal bytes mean equal messages, bit for bit.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string_view>
#include <vector>

#include "messages.h"

namespace {

namespace msg = sfrt::ros2::msg;

void Fail(std::string_view type, const char* what) {
  std::fprintf(stderr, "%.*s: %s\n", static_cast<int>(type.size()), type.data(), what);
  std::abort();
}

template <typename T>
void CheckType(std::span<const uint8_t> input) {
  T message;
  if (!msg::Decode(input, &message).ok()) return;
  std::vector<uint8_t> bytes;
  msg::Encode(message, &bytes);
  T again;
  if (sfrt::Status status = msg::Decode(bytes, &again); !status.ok()) {
    std::fprintf(stderr, "%s\n", status.message().c_str());
    Fail(msg::NamesOf<T>().ros2_type, "an accepted message does not decode after encoding");
  }
  std::vector<uint8_t> bytes_again;
  msg::Encode(again, &bytes_again);
  if (bytes_again != bytes) {
    Fail(msg::NamesOf<T>().ros2_type, "Encode -> Decode changed an accepted message");
  }
}

void CheckImageView(std::span<const uint8_t> input) {
  msg::ImageView view;
  msg::Image image;
  const bool view_ok = msg::DecodeImageView(input, &view).ok();
  if (view_ok != msg::Decode(input, &image).ok()) {
    Fail("sensor_msgs/msg/Image", "the view and the owning decoder disagree on acceptance");
  }
  if (!view_ok) return;
  const bool same = view.header.stamp == image.header.stamp &&
                    view.header.frame_id == image.header.frame_id && view.height == image.height &&
                    view.width == image.width && view.encoding == image.encoding &&
                    view.is_bigendian == image.is_bigendian && view.step == image.step &&
                    std::vector<uint8_t>(view.data.begin(), view.data.end()) == image.data;
  if (!same) Fail("sensor_msgs/msg/Image", "the view and the owning decoder disagree on content");
  std::vector<uint8_t> from_view;
  std::vector<uint8_t> from_image;
  msg::Encode(view, &from_view);
  msg::Encode(image, &from_image);
  if (from_view != from_image) Fail("sensor_msgs/msg/Image", "a view encodes unlike its Image");
  const auto begin = reinterpret_cast<uintptr_t>(input.data());
  const auto at = reinterpret_cast<uintptr_t>(view.data.data());
  if (!view.data.empty() && (at < begin || at + view.data.size() > begin + input.size())) {
    Fail("sensor_msgs/msg/Image", "the view's data does not lie inside the input");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const uint8_t> input(data, size);
  CheckType<msg::Time>(input);
  CheckType<msg::Header>(input);
  CheckType<msg::Image>(input);
  CheckType<msg::CompressedImage>(input);
  CheckType<msg::RegionOfInterest>(input);
  CheckType<msg::CameraInfo>(input);
  CheckType<msg::KeyValue>(input);
  CheckType<msg::DiagnosticStatus>(input);
  CheckType<msg::DiagnosticArray>(input);
  CheckImageView(input);
  return 0;
}
