// The runtime's developer switches as environment variables, for A/B runs and scripts:
//   SFRT_ISA=auto|ref|avx2|avx512|avx512amx|neon   SessionOptions::isa (only while it is still
//   kAuto) SFRT_WINOGRAD=off|f2|f4              KernelTuning::winograd_tile (0, 2, 4)
//   SFRT_WINOGRAD_UPCONV=off|on          KernelTuning::winograd_upconv
//   SFRT_FEWOUT=off|on                   KernelTuning::few_out
//   SFRT_CONCAT_IN_PLACE=off|on          KernelTuning::concat_in_place
//   SFRT_AMX_PAIRS=off|on                KernelTuning::amx_pairs
// The runtime library reads no environment (libraries take options); the `sfrt` tool and the
// kernel benchmarks call ApplySessionEnvironment wherever they build SessionOptions.
#pragma once

#include "sfrt/session.h"
#include "sfrt/status.h"

namespace sfrt::tools {

// Applies every variable above that is set and not empty to `options`. An explicit ISA (a
// --isa flag) wins over SFRT_ISA. Errors name the variable, its value and the accepted values.
Status ApplySessionEnvironment(SessionOptions& options);
// The same on the two session fields that other options structs carry (pipeline, eval).
Status ApplySessionEnvironment(Isa& isa, KernelTuning& tuning);

}  // namespace sfrt::tools
