// Text helpers for importer error messages: whatever a source file contains, a message stays
// one line.
#pragma once

#include <cstdio>
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

// Three significant digits in scientific form, as the export's reports print errors: 1.23e-04.
inline std::string Sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2e", v);
  return buf;
}

// A count with thousands separators: 1234567 -> "1,234,567".
inline std::string GroupDigits(unsigned long long value) {
  const std::string digits = std::to_string(value);
  std::string out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out.push_back(',');
    out.push_back(digits[i]);
  }
  return out;
}

}  // namespace sfrt::exporter
