#include "sfrt/model_notes.h"

#include <cstdio>

namespace sfrt::tools {
namespace {

constexpr char kNotStated[] = "unknown";

bool UnitsStated(const ModelMetadata& meta) {
  return meta.output.units_declared && !meta.output.units.empty() &&
         meta.output.units != kNotStated;
}

}  // namespace

const char* TrainingStateName(TrainingState state) {
  switch (state) {
    case TrainingState::kTrained:
      return "trained";
    case TrainingState::kUntrained:
      return "untrained";
    case TrainingState::kUnknown:
      break;
  }
  return "unknown";
}

std::string UnitsText(const ModelMetadata& meta) {
  if (UnitsStated(meta)) return meta.output.units;
  if (!meta.output.units_declared) {
    return "unknown (schema " + std::to_string(meta.schema_major) + "." +
           std::to_string(meta.schema_minor) +
           " files do not state units; sfrt export MODEL.sfrt -o NEW.sfrt --units UNITS records "
           "them)";
  }
  return "unknown (not stated when exported; sfrt export --units records them)";
}

std::string BaselineText(const ModelMetadata& meta) {
  char number[32];
  std::snprintf(number, sizeof(number), "%g", static_cast<double>(meta.camera.baseline));
  return UnitsStated(meta) ? std::string(number) + " " + meta.output.units : std::string(number);
}

std::string UntrainedNotice(const std::string& path, TrainingState state) {
  if (state != TrainingState::kUntrained) return "";
  return "note: " + path +
         " is marked untrained (its weights were never trained): its output is "
         "not scene flow";
}

}  // namespace sfrt::tools
