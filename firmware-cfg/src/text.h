// Text helpers the profile's parser (profile.cc) and its summary (profile_summary.cc) share. Not
// an API.
#pragma once

#include <sstream>
#include <string>
#include <vector>

namespace sfrt::config {

// The items with `sep` between them.
inline std::string Join(const std::vector<std::string>& items, const char* sep = ", ") {
  std::string out;
  for (const std::string& item : items) {
    if (!out.empty()) out += sep;
    out += item;
  }
  return out;
}

// A number in its shortest natural form (as std::ostream writes it): 30, 2.5, 99.9.
inline std::string FormatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace sfrt::config
