// Serialises a ModelSpec into the .sfrt FlatBuffers format (runtime/schema/sfrt_model.fbs).
#pragma once

#include <cstdint>
#include <vector>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/status.h"

namespace sfrt::exporter {

// The version recorded in Producer.exporter_version when the spec leaves it empty.
const char* ExporterVersion();

// Checks the spec (chain consistency, weight counts) and returns the file's bytes. Tensor data
// is 64-byte aligned relative to the start of the returned buffer.
Result<std::vector<uint8_t>> SerializeModel(const ModelSpec& spec);

}  // namespace sfrt::exporter
