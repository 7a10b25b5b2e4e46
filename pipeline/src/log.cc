#include "sfrt/pipeline/log.h"

#include <unistd.h>

#include <cstdio>

namespace sfrt::pipeline {
namespace {

int Len(std::string_view s) { return static_cast<int>(s.size()); }

}  // namespace

StderrLog::StderrLog(std::string prefix, LogLevel level)
    : prefix_(std::move(prefix)), level_(level), tty_(::isatty(STDERR_FILENO) == 1) {}

void StderrLog::Write(LogLevel level, std::string_view tag, std::string_view text) {
  if (static_cast<int>(level) > static_cast<int>(level_)) return;
  std::fprintf(stderr, "%s: %.*s: %.*s\n", prefix_.c_str(), Len(tag), tag.data(), Len(text),
               text.data());
}

void StderrLog::Progress(std::string_view line, bool final) {
  if (tty_) {
    std::fprintf(stderr, "\r%s: %.*s\x1b[K%s", prefix_.c_str(), Len(line), line.data(),
                 final ? "\n" : "");
  } else {
    std::fprintf(stderr, "%s: %.*s\n", prefix_.c_str(), Len(line), line.data());
  }
  std::fflush(stderr);
}

LogSink& DefaultLog() {
  static StderrLog log("sfrt pipeline");
  return log;
}

}  // namespace sfrt::pipeline
