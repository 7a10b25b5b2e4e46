// How a vocabulary is declared once: an enum whose enumerators count from 0, and beside it one
// array of names in the same order. Its name and its parser are made from that array here, so a
// word is spelled in one place (ggml's pattern: one enum, its name table beside it).
//
//   enum class FlowFormat { kPfm, kNpy };
//   inline constexpr std::array<const char*, 2> kFlowFormatNames = {"pfm", "npy"};
//   NameOf(kFlowFormatNames, FlowFormat::kNpy)             -> "npy"
//   FromName<FlowFormat>(kFlowFormatNames, "npy")          -> FlowFormat::kNpy
//   NameList(kFlowFormatNames)                              -> "pfm, npy"
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace sfrt::vocabulary {

// The name of `value`, or "?" for a value outside the table.
template <typename E, size_t N>
constexpr const char* NameOf(const std::array<const char*, N>& names, E value) {
  const auto i = static_cast<size_t>(value);
  return i < N ? names[i] : "?";
}

// The value `name` spells exactly, or nothing.
template <typename E, size_t N>
constexpr std::optional<E> FromName(const std::array<const char*, N>& names,
                                    std::string_view name) {
  for (size_t i = 0; i < N; ++i) {
    if (name == names[i]) return static_cast<E>(i);
  }
  return std::nullopt;
}

// The names with `separator` between them, for help texts and messages: "pfm, npy".
template <size_t N>
std::string NameList(const std::array<const char*, N>& names, std::string_view separator = ", ") {
  std::string out;
  for (size_t i = 0; i < N; ++i) {
    if (i > 0) out += separator;
    out += names[i];
  }
  return out;
}

}  // namespace sfrt::vocabulary
