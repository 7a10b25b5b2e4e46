#include "sfrt/session_environment.h"

#include <cstdlib>
#include <string>

#include "sfrt/isa.h"

namespace sfrt::tools {
namespace {

// The value of `name`, or nullptr when it is unset or empty.
const char* Variable(const char* name) {
  const char* value = std::getenv(name);
  return value != nullptr && *value != '\0' ? value : nullptr;
}

Status Invalid(const char* name, const std::string& value, const std::string& accepted) {
  return Status::Error(std::string(name) + "='" + value + "' is not one of " + accepted);
}

Status ApplySwitch(const char* name, bool& field) {
  const char* value = Variable(name);
  if (value == nullptr) return Status::Ok();
  const std::string v = value;
  if (v != "off" && v != "on") return Invalid(name, v, "off, on");
  field = v == "on";
  return Status::Ok();
}

}  // namespace

Status ApplySessionEnvironment(SessionOptions& options) {
  return ApplySessionEnvironment(options.isa, options.tuning);
}

Status ApplySessionEnvironment(Isa& isa, KernelTuning& tuning) {
  if (const char* value = Variable("SFRT_ISA"); value != nullptr && isa == Isa::kAuto) {
    Isa parsed = Isa::kAuto;
    if (!ParseIsa(value, &parsed)) {
      return Invalid("SFRT_ISA", value, IsaNameList(true));
    }
    isa = parsed;
  }
  if (const char* value = Variable("SFRT_WINOGRAD"); value != nullptr) {
    const std::string v = value;
    if (v == "off") {
      tuning.winograd_tile = 0;
    } else if (v == "f2") {
      tuning.winograd_tile = 2;
    } else if (v == "f4") {
      tuning.winograd_tile = 4;
    } else {
      return Invalid("SFRT_WINOGRAD", v, "off, f2, f4");
    }
  }
  if (Status s = ApplySwitch("SFRT_WINOGRAD_UPCONV", tuning.winograd_upconv); !s.ok()) {
    return s;
  }
  if (Status s = ApplySwitch("SFRT_FEWOUT", tuning.few_out); !s.ok()) return s;
  if (Status s = ApplySwitch("SFRT_CONCAT_IN_PLACE", tuning.concat_in_place); !s.ok()) return s;
  return ApplySwitch("SFRT_AMX_PAIRS", tuning.amx_pairs);
}

}  // namespace sfrt::tools
