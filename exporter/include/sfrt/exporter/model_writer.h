// Serialises a ModelSpec into the .sfrt FlatBuffers format (runtime/schema/sfrt_model.fbs).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/status.h"

namespace sfrt::exporter {

// The version recorded in Producer.exporter_version when the spec leaves it empty.
const char* ExporterVersion();

// Checks the spec (chain consistency, weight counts) and returns the file's bytes. Tensor data
// is 64-byte aligned relative to the start of the returned buffer.
Result<std::vector<uint8_t>> SerializeModel(const ModelSpec& spec);

// SerializeModel, then writes `path` atomically (temporary file in the same directory, fsync,
// rename): a failed export never leaves a half-written model behind.
Status WriteModelFile(const ModelSpec& spec, const std::string& path);

}  // namespace sfrt::exporter
