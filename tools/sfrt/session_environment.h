// The runtime's developer switches, for A/B runs and scripts, declared once (TuningSwitches())
// and reachable two ways: as environment variables SFRT_<NAME> (every `sfrt` command and the
// kernel benchmarks) and as `sfrt bench --tuning NAME=VALUE[,NAME=VALUE...]` (several variants
// timed in one process). The switches:
//   winograd=auto|off|f2|f4     KernelTuning::winograd_tile (kWinogradAuto, 0, 2, 4)
//   winograd_upconv=off|on      KernelTuning::winograd_upconv
//   fewout=off|on               KernelTuning::few_out
//   concat_in_place=off|on      KernelTuning::concat_in_place
//   amx_pairs=off|on            KernelTuning::amx_pairs
// and, as a variable only, SFRT_ISA=auto|ref|avx2|avx512|avx512amx|neon (SessionOptions::isa,
// only while it is still kAuto: an explicit --isa wins).
// The runtime library reads no environment (libraries take options); the `sfrt` tool and the
// kernel benchmarks call ApplySessionEnvironment wherever they build SessionOptions.
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/session.h"
#include "sfrt/status.h"

namespace sfrt::tools {

// One developer switch: its name (the environment variable is "SFRT_" and the name in upper
// case), the values it accepts as a user reads them ("off, on"), the one KernelTuning's defaults
// amount to, and how a value sets the tuning.
struct TuningSwitch {
  const char* name;
  const char* values;
  const char* default_value;
  // Sets the field for `value`; false (nothing changed) when the switch does not take it.
  bool (*apply)(std::string_view value, KernelTuning& tuning);
};
// Every switch, in the order above.
std::span<const TuningSwitch> TuningSwitches();
// The values the switch takes, in the order of TuningSwitch::values.
std::vector<std::string_view> TuningValues(const TuningSwitch& s);
// "SFRT_" + the switch's name in upper case.
std::string TuningVariable(const TuningSwitch& s);

// Applies every variable above that is set and not empty to `options`. An explicit ISA (a
// --isa flag) wins over SFRT_ISA. Errors name the variable, its value and the accepted values.
Status ApplySessionEnvironment(SessionOptions& options);
// The same on the two session fields that other options structs carry (pipeline, eval).
Status ApplySessionEnvironment(Isa& isa, KernelTuning& tuning);

// A tuning variant as `sfrt bench --tuning` takes it: "default" (nothing changed) or
// comma-separated NAME=VALUE switches, applied in order onto `tuning`. Errors name the
// assignment at fault and what is accepted; `tuning` may then be partly changed.
Status ApplyTuningVariant(std::string_view variant, KernelTuning& tuning);
// What `sfrt bench --tuning each` times: "default", then NAME=VALUE for every value of every
// switch other than its default, one switch at a time.
std::vector<std::string> EachTuningVariant();

}  // namespace sfrt::tools
