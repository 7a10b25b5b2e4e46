#include "sfrt/session_environment.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdlib>
#include <string>

#include "sfrt/isa.h"

namespace sfrt::tools {
namespace {

// "off" or "on" into `field`.
bool SetSwitch(std::string_view value, bool& field) {
  if (value != "off" && value != "on") return false;
  field = value == "on";
  return true;
}

bool SetWinograd(std::string_view value, KernelTuning& t) {
  if (value == "auto") {
    t.winograd_tile = KernelTuning::kWinogradAuto;
  } else if (value == "off") {
    t.winograd_tile = 0;
  } else if (value == "f2") {
    t.winograd_tile = 2;
  } else if (value == "f4") {
    t.winograd_tile = 4;
  } else {
    return false;
  }
  return true;
}

constexpr std::array<TuningSwitch, 5> kSwitches{{
    {"winograd", "auto, off, f2, f4", "auto", SetWinograd},
    {"winograd_upconv", "off, on", "on",
     [](std::string_view v, KernelTuning& t) { return SetSwitch(v, t.winograd_upconv); }},
    {"fewout", "off, on", "on",
     [](std::string_view v, KernelTuning& t) { return SetSwitch(v, t.few_out); }},
    {"concat_in_place", "off, on", "on",
     [](std::string_view v, KernelTuning& t) { return SetSwitch(v, t.concat_in_place); }},
    {"amx_pairs", "off, on", "on",
     [](std::string_view v, KernelTuning& t) { return SetSwitch(v, t.amx_pairs); }},
}};

// The value of `name`, or nullptr when it is unset or empty.
const char* Variable(const char* name) {
  const char* value = std::getenv(name);
  return value != nullptr && *value != '\0' ? value : nullptr;
}

Status Invalid(std::string_view name, std::string_view value, std::string_view accepted) {
  return Status::Error(std::string(name) + "='" + std::string(value) + "' is not one of " +
                       std::string(accepted));
}

std::string SwitchNames() {
  std::string names;
  for (const TuningSwitch& s : kSwitches) {
    if (!names.empty()) names += ", ";
    names += s.name;
  }
  return names;
}

// One NAME=VALUE of a tuning variant.
Status ApplyAssignment(std::string_view assignment, KernelTuning& tuning) {
  const size_t eq = assignment.find('=');
  if (eq == std::string_view::npos) {
    return Status::Error("'" + std::string(assignment) +
                         "' is not NAME=VALUE (names: " + SwitchNames() + ")");
  }
  const std::string_view name = assignment.substr(0, eq);
  const std::string_view value = assignment.substr(eq + 1);
  for (const TuningSwitch& s : kSwitches) {
    if (name != s.name) continue;
    if (!s.apply(value, tuning)) return Invalid(name, value, s.values);
    return Status::Ok();
  }
  return Status::Error("'" + std::string(name) +
                       "' is not a tuning switch (names: " + SwitchNames() + ")");
}

}  // namespace

std::span<const TuningSwitch> TuningSwitches() { return kSwitches; }

std::string TuningVariable(const TuningSwitch& s) {
  std::string variable = "SFRT_";
  for (const char* c = s.name; *c != '\0'; ++c) {
    variable += static_cast<char>(std::toupper(static_cast<unsigned char>(*c)));
  }
  return variable;
}

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
  for (const TuningSwitch& s : kSwitches) {
    const std::string variable = TuningVariable(s);
    const char* value = Variable(variable.c_str());
    if (value != nullptr && !s.apply(value, tuning)) return Invalid(variable, value, s.values);
  }
  return Status::Ok();
}

std::vector<std::string_view> TuningValues(const TuningSwitch& s) {
  std::vector<std::string_view> out;
  const std::string_view values = s.values;
  for (size_t begin = 0; begin < values.size();) {
    const size_t end = std::min(values.find(", ", begin), values.size());
    out.push_back(values.substr(begin, end - begin));
    begin = end + 2;
  }
  return out;
}

std::vector<std::string> EachTuningVariant() {
  std::vector<std::string> variants = {"default"};
  for (const TuningSwitch& s : kSwitches) {
    for (std::string_view value : TuningValues(s)) {
      if (value != s.default_value) {
        variants.push_back(std::string(s.name) + "=" + std::string(value));
      }
    }
  }
  return variants;
}

Status ApplyTuningVariant(std::string_view variant, KernelTuning& tuning) {
  if (variant == "default") return Status::Ok();
  if (variant.empty()) {
    return Status::Error("a tuning variant is 'default' or NAME=VALUE[,NAME=VALUE...], not empty");
  }
  size_t begin = 0;
  while (begin <= variant.size()) {
    const size_t comma = std::min(variant.find(',', begin), variant.size());
    if (Status s = ApplyAssignment(variant.substr(begin, comma - begin), tuning); !s.ok()) {
      return s;
    }
    begin = comma + 1;
  }
  return Status::Ok();
}

}  // namespace sfrt::tools
