// The words for a scene-flow model's image input, declared once for every module: the runtime
// (model metadata), the exporter (model specs), camera/ (preprocessing) and the tools. Header-only,
// standard C++ only, so a module that may use nothing else of ours may still use it.
//   ImageSlot   which image of the window (t, t+1) a group of input channels holds, as the model
//               file spells it: two stereo pairs, "left0", "right0", "left1", "right1" (3
//               channels each), or two RGB-D frames, "color0", "depth0", "color1", "depth1"
//               (colour 3 channels, depth 1; schema 1.11).
//   ColorOrder  the channel order within each colour image: "BGR" (OpenCV's) or "RGB".
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string_view>

namespace sfrt::vocabulary {

enum class ImageSlot {
  kLeft0 = 0,
  kRight0 = 1,
  kLeft1 = 2,
  kRight1 = 3,
  kColor0 = 4,
  kDepth0 = 5,
  kColor1 = 6,
  kDepth1 = 7,
};
inline constexpr int kImageSlots = 8;
inline constexpr std::array<std::string_view, kImageSlots> kImageSlotNames = {
    "left0", "right0", "left1", "right1", "color0", "depth0", "color1", "depth1"};
// The order the slots are written in when a model says nothing else (the paper's).
inline constexpr std::array<ImageSlot, 4> kDefaultImageOrder = {
    ImageSlot::kLeft0, ImageSlot::kRight0, ImageSlot::kLeft1, ImageSlot::kRight1};
// The same for two RGB-D frames: 8 channels, colour then depth of t, then of t+1.
inline constexpr std::array<ImageSlot, 4> kDefaultRgbdOrder = {
    ImageSlot::kColor0, ImageSlot::kDepth0, ImageSlot::kColor1, ImageSlot::kDepth1};

// Whether a slot belongs to the RGB-D frames (else to the stereo pairs).
constexpr bool IsRgbdSlot(ImageSlot s) { return static_cast<int>(s) >= 4; }
constexpr bool IsDepthSlot(ImageSlot s) {
  return s == ImageSlot::kDepth0 || s == ImageSlot::kDepth1;
}
// Input channels a slot fills: 1 for a depth map, 3 for a colour image.
constexpr int SlotChannels(ImageSlot s) { return IsDepthSlot(s) ? 1 : 3; }

constexpr std::string_view ImageSlotName(ImageSlot s) {
  const int i = static_cast<int>(s);
  return i >= 0 && i < kImageSlots ? kImageSlotNames[static_cast<size_t>(i)] : "?";
}
// The slot a name spells (exactly, lower case), or nothing.
constexpr std::optional<ImageSlot> ImageSlotFromName(std::string_view name) {
  for (int i = 0; i < kImageSlots; ++i) {
    if (name == kImageSlotNames[static_cast<size_t>(i)]) return static_cast<ImageSlot>(i);
  }
  return std::nullopt;
}

// The short names a command line also takes for the slots: L = left, R = right, C = colour,
// D = depth; 0 = time t, 1 = t+1.
inline constexpr std::array<std::string_view, kImageSlots> kImageSlotShortNames = {
    "L0", "R0", "L1", "R1", "C0", "D0", "C1", "D1"};

// ASCII letters equal regardless of case.
constexpr bool EqualsIgnoringCase(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  const auto lower = [](char c) { return c >= 'A' && c <= 'Z' ? static_cast<char>(c + 32) : c; };
  for (size_t i = 0; i < a.size(); ++i) {
    if (lower(a[i]) != lower(b[i])) return false;
  }
  return true;
}

// The slot a name or short name spells in any case ("left0", "LEFT0", "L0", "l0"), or nothing.
constexpr std::optional<ImageSlot> ImageSlotFromAnyName(std::string_view name) {
  for (int i = 0; i < kImageSlots; ++i) {
    const auto at = static_cast<size_t>(i);
    if (EqualsIgnoringCase(name, kImageSlotNames[at]) ||
        EqualsIgnoringCase(name, kImageSlotShortNames[at])) {
      return static_cast<ImageSlot>(i);
    }
  }
  return std::nullopt;
}

enum class ColorOrder { kBGR, kRGB };

constexpr std::string_view ColorOrderName(ColorOrder c) {
  return c == ColorOrder::kBGR ? "BGR" : "RGB";
}
// "BGR" or "RGB" (exactly, upper case), or nothing.
constexpr std::optional<ColorOrder> ColorOrderFromName(std::string_view name) {
  if (name == "BGR") return ColorOrder::kBGR;
  if (name == "RGB") return ColorOrder::kRGB;
  return std::nullopt;
}

}  // namespace sfrt::vocabulary
