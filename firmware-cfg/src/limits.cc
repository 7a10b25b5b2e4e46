#include "sfrt/config/limits.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <thread>

namespace sfrt::config {

std::string RangeText(const IntRange& range) {
  std::string text = std::to_string(range.lo) + ".." + std::to_string(range.hi);
  if (range.unit[0] != '\0') text += std::string(" ") + range.unit;
  if (range.note[0] != '\0') text += std::string(" (") + range.note + ")";
  return text;
}

bool ParseFiniteNumber(const std::string& text, double* value) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno != 0 || !std::isfinite(v)) {
    return false;
  }
  *value = v;
  return true;
}

bool InRange(const IntRange& range, long long value) {
  return value >= range.lo && value <= range.hi;
}

std::string CheckRange(const IntRange& range, const std::string& flag, long long value) {
  if (InRange(range, value)) return "";
  return flag + ": " + std::to_string(value) + " is outside the " + range.what + " limits " +
         RangeText(range);
}

std::string CheckSize(const IntRange& range, const std::string& flag, long long height,
                      long long width) {
  if (InRange(range, height) && InRange(range, width)) return "";
  return flag + ": " + std::to_string(height) + "x" + std::to_string(width) +
         " (HxW) is outside the " + range.what + " limits " + RangeText(range);
}

int ResolveThreads(int threads) {
  if (threads != 0) return threads;
  const unsigned cpus = std::thread::hardware_concurrency();
  return cpus > 0 ? static_cast<int>(cpus) : 1;
}

std::vector<std::string> LimitsMarkdownRows() {
  std::vector<std::string> rows;
  for (const IntRange* r : {&kInputSide, &kTensorSide, &kFrameSide, &kThreads, &kCameraBuffers}) {
    std::string extra = r->unit;
    if (r->note[0] != '\0') extra += (extra.empty() ? "" : "; ") + std::string(r->note);
    rows.push_back("| " + std::string(r->what) + " | " + std::to_string(r->lo) + ".." +
                   std::to_string(r->hi) + " | " + extra + " |");
  }
  rows.push_back("| profile file size | 0.." + std::to_string(kMaxProfileBytes) +
                 " | bytes (1 MiB); bigger files are refused before parsing |");
  rows.push_back("| profile errors printed | " + std::to_string(kMaxPrintedErrors) +
                 " | then \"... and N more errors\" |");
  return rows;
}

}  // namespace sfrt::config
