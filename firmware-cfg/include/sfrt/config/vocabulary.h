// The words a deployment profile, the pipeline and the `sfrt` command share, declared once
// (header-only, standard C++ only: pipeline/ includes it without linking the profile library).
//   Stage       the pipeline's four stages, as profiles, summary.json, profiles' reports and the
//               run's table spell them: "source", "preprocess", "infer", "output". The source
//               stage reads the camera or the files; profiles written before it was so named
//               may still say "capture" (accepted with a warning).
//   FlowFormat  the flow files the pipeline writes: "pfm", "npy".
//   LogLevel    how severe a message is, as profiles spell it (logging.level): "error", "warn",
//               "info", "debug"; the pipeline's LogSink (pipeline/log.h) gets it with each message.
#pragma once

#include <string_view>

namespace sfrt::config {

enum class Stage { kSource = 0, kPreprocess, kInfer, kOutput };
inline constexpr int kStageCount = 4;
inline constexpr const char* kStageNames[kStageCount] = {"source", "preprocess", "infer", "output"};
// The profile key profiles used for the source stage before it was named "source".
inline constexpr const char* kOldSourceStageName = "capture";

constexpr const char* StageName(Stage s) {
  const int i = static_cast<int>(s);
  return i >= 0 && i < kStageCount ? kStageNames[i] : "?";
}

enum class FlowFormat { kPfm, kNpy };
constexpr const char* FlowFormatName(FlowFormat f) { return f == FlowFormat::kPfm ? "pfm" : "npy"; }

enum class LogLevel { kError, kWarn, kInfo, kDebug };
constexpr const char* LogLevelName(LogLevel l) {
  switch (l) {
    case LogLevel::kError:
      return "error";
    case LogLevel::kWarn:
      return "warn";
    case LogLevel::kInfo:
      return "info";
    case LogLevel::kDebug:
      return "debug";
  }
  return "?";
}

}  // namespace sfrt::config
