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

Status Invalid(const char* name, const std::string& value, const char* accepted) {
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
  if (const char* value = Variable("SFRT_ISA"); value != nullptr && options.isa == Isa::kAuto) {
    Isa isa = Isa::kAuto;
    if (!ParseIsa(value, &isa)) {
      return Invalid("SFRT_ISA", value, "auto, ref, avx2, avx512, neon");
    }
    options.isa = isa;
  }
  if (const char* value = Variable("SFRT_WINOGRAD"); value != nullptr) {
    const std::string v = value;
    if (v == "off") {
      options.tuning.winograd_tile = 0;
    } else if (v == "f2") {
      options.tuning.winograd_tile = 2;
    } else if (v == "f4") {
      options.tuning.winograd_tile = 4;
    } else {
      return Invalid("SFRT_WINOGRAD", v, "off, f2, f4");
    }
  }
  if (Status s = ApplySwitch("SFRT_WINOGRAD_UPCONV", options.tuning.winograd_upconv); !s.ok()) {
    return s;
  }
  return ApplySwitch("SFRT_FEWOUT", options.tuning.few_out);
}

}  // namespace sfrt::tools
