// FailurePolicy: what a run does when one frame or one window fails, "skip" it (counted and
// named) and go on, or "stop" the run naming it. Declared once for the two places it applies:
// a bad input frame (camera/: sfrt run --on-bad-frame, profiles' replay.on_bad_frame) and a
// window whose output cannot be written (pipeline/: sfrt run --on-output-error).
#pragma once

#include <array>
#include <optional>
#include <string_view>

#include "sfrt/vocabulary/names.h"

namespace sfrt::vocabulary {

enum class FailurePolicy { kSkip, kStop };
inline constexpr std::array<const char*, 2> kFailurePolicyNames = {"skip", "stop"};
constexpr const char* FailurePolicyName(FailurePolicy p) { return NameOf(kFailurePolicyNames, p); }
constexpr std::optional<FailurePolicy> FailurePolicyFromName(std::string_view name) {
  return FromName<FailurePolicy>(kFailurePolicyNames, name);
}

}  // namespace sfrt::vocabulary
