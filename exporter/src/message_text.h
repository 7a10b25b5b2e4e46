// Text helpers for importer error messages: whatever a source file contains, a message stays
// one line.
#pragma once

#include <string>
#include <string_view>

namespace sfrt::exporter {

// Replaces control characters (newlines included) with '?'.
inline std::string Printable(std::string_view s) {
  std::string out(s);
  for (char& ch : out) {
    if (static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f) ch = '?';
  }
  return out;
}

// 'name', printable.
inline std::string Quote(std::string_view s) { return "'" + Printable(s) + "'"; }

}  // namespace sfrt::exporter
