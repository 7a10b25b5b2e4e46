// The rules that choose a convolution's kernel, shared by the step planner (step_planner.cc,
// Session::PlanSteps) and the weight packing that follows it (session.cc, PackWeights). Not an
// API.
#pragma once

#include "session_steps.h"
#include "sfrt/model.h"
#include "sfrt/session.h"

namespace sfrt {

// Whether a SIMD kernel takes convolution `p`: undilated and ungrouped, and a 3x3 stride-1
// kernel when it reads a fused upsampling (`upsampled`), else at most `max_taps` taps.
bool SimdFits(const ConvParams& p, bool upsampled, int max_taps);

// Whether the int8 SIMD step of `p` runs on the kernel table's narrow kernel.
bool Int8Narrow(const KernelTuning& tuning, const IsaInt8Kernels* kernels8, const ConvParams& p,
                bool upsampled);

}  // namespace sfrt
