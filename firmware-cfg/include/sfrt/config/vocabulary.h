// The words a deployment profile, the pipeline and the `sfrt` command share, declared once, each
// an enum with its names beside it (sfrt/vocabulary/names.h makes the name and the parser from
// them). Header-only, standard C++ only: pipeline/ includes it without linking the profile
// library.
//   Stage       the pipeline's four stages, as profiles, summary.json, profiles' reports and the
//               run's table spell them: "source", "preprocess", "infer", "output". The source
//               stage reads the camera or the files; profiles written before it was so named
//               may still say "capture" (accepted with a warning).
//   FlowFormat  the flow files the pipeline writes: "pfm", "npy".
//   LogLevel    how severe a message is, as profiles spell it (logging.level): "error", "warn",
//               "info", "debug"; the pipeline's LogSink (pipeline/log.h) gets it with each message.
//   MissAction  what the pipeline does when a window misses the latency budget (latency.on_miss,
//               sfrt run --on-miss, the nodes' on_miss parameter): "drop-next", "smaller-input",
//               "count-only".
#pragma once

#include <array>
#include <optional>
#include <string_view>

#include "sfrt/vocabulary/names.h"

namespace sfrt::config {

enum class Stage { kSource = 0, kPreprocess, kInfer, kOutput };
inline constexpr int kStageCount = 4;
inline constexpr std::array<const char*, kStageCount> kStageNames = {"source", "preprocess",
                                                                     "infer", "output"};
// The profile key profiles used for the source stage before it was named "source".
inline constexpr const char* kOldSourceStageName = "capture";
constexpr const char* StageName(Stage s) { return vocabulary::NameOf(kStageNames, s); }
// The index of a stage in arrays indexed by stage (0 .. kStageCount - 1).
constexpr int StageIndex(Stage s) { return static_cast<int>(s); }

enum class FlowFormat { kPfm, kNpy };
inline constexpr std::array<const char*, 2> kFlowFormatNames = {"pfm", "npy"};
constexpr const char* FlowFormatName(FlowFormat f) {
  return vocabulary::NameOf(kFlowFormatNames, f);
}
constexpr std::optional<FlowFormat> FlowFormatFromName(std::string_view name) {
  return vocabulary::FromName<FlowFormat>(kFlowFormatNames, name);
}

enum class LogLevel { kError, kWarn, kInfo, kDebug };
inline constexpr std::array<const char*, 4> kLogLevelNames = {"error", "warn", "info", "debug"};
constexpr const char* LogLevelName(LogLevel l) { return vocabulary::NameOf(kLogLevelNames, l); }

enum class MissAction { kDropNext, kSmallerInput, kCountOnly };
inline constexpr std::array<const char*, 3> kMissActionNames = {"drop-next", "smaller-input",
                                                                "count-only"};
constexpr const char* MissActionName(MissAction a) {
  return vocabulary::NameOf(kMissActionNames, a);
}
constexpr std::optional<MissAction> MissActionFromName(std::string_view name) {
  return vocabulary::FromName<MissAction>(kMissActionNames, name);
}

}  // namespace sfrt::config
