// What the sfrt commands say about a model's metadata in the same words everywhere: its output
// units (only what the file states) and its training state (a notice for untrained weights).
#pragma once

#include <cstdint>
#include <string>

#include "sfrt/isa.h"
#include "sfrt/model.h"

namespace sfrt::tools {

// "trained", "untrained" or "unknown".
const char* TrainingStateName(TrainingState state);

// The output units as the file states them: OutputDesc.units of a schema 1.2 or later file
// (e.g. "metres"). Otherwise "unknown (...)" saying why: older exporters wrote a fixed text
// whatever the model, and a 1.2 exporter not given --units writes "unknown".
std::string UnitsText(const ModelMetadata& meta);

// The training camera's baseline with its unit when the file states one: "0.12 metres", "1".
std::string BaselineText(const ModelMetadata& meta);

// One line for a model marked untrained, e.g. "note: tools/demo/x.sfrt is marked untrained
// (seeded weights): its output is not scene flow"; empty for any other training state.
std::string UntrainedNotice(const std::string& path, TrainingState state);

// Bytes the file stores for the convolutions' parameters: weights (4, 2 or, int8, 1 byte each),
// biases (4 or 2 bytes), the int8 layers' weight scales (4 bytes each) and phase kernels.
uint64_t StoredParameterBytes(const Model& model);

// "int8 in 11 of 11 convolutions (...)", or "" when every convolution is float32.
std::string Int8LayersText(const Model& model);

// One line per reduced precision whose convolutions in `model` will run on the scalar reference
// kernel in a session on `isa` (kAuto: the best), an optimised ISA without that precision's
// kernels on this CPU (Int8KernelsAvailable, Bf16KernelsAvailable), e.g. "note: 11 int8
// convolutions run on the scalar reference kernel: avx2 has no int8 kernels on this CPU (avx512
// needs AVX-512 VNNI, neon the dot-product extension); a float32 model is faster here"; else "".
std::string PrecisionFallbackNotice(const Model& model, Isa isa);

// For an ISA the user forced (--isa, a profile or SFRT_ISA; not kAuto): "" when it runs every
// precision of `model` on its own kernels (or is kRef, the reference by request), else the
// reason it does not, e.g. "the model's 11 bf16 convolutions have no avx2 kernels on this CPU
// (avx512 needs AVX512_BF16, neon the BF16 extension): drop --isa to let sfrt choose, or force
// ref to run them on the reference kernel". `sfrt run` and `infer` refuse such a run; `bench`,
// a measuring tool, prints PrecisionFallbackNotice and measures the fallback.
std::string ForcedIsaPrecisionProblem(const Model& model, Isa forced);

// Calibration errors as the commands print them: "1.23e-02".
std::string ErrorText(double value);

}  // namespace sfrt::tools
