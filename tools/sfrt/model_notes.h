// What the sfrt commands say about a model's metadata in the same words everywhere: its output
// units (only what the file states) and its training state (a notice for untrained weights).
#pragma once

#include <string>

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

}  // namespace sfrt::tools
