// A finished .sfrt file as a source: its layers, weights and metadata back into a ModelSpec, so
// that `sfrt export model.sfrt -o new.sfrt --units metres` can rewrite a model's metadata (or
// move it to the current schema version) without retraining or the original ONNX file.
#pragma once

#include <string>

#include "sfrt/exporter/model_spec.h"
#include "sfrt/status.h"

namespace sfrt::exporter {

// Loads and verifies `path` as the runtime would (checksums included) and returns everything it
// holds: layers with their weights (fp32 values; fp16 files widen exactly, so writing them back
// as fp16 gives the same bits; int8 layers with their int8 weights, scales and quantisation as
// stored), input, output and camera metadata, name, weight type, training state, the calibration
// record (schema 1.3), and the producer's source fields (format, file, SHA-256: they keep naming
// what the weights were converted from). The producer's exporter version is left empty (the writer
// fills in its own). Units of a file before schema 1.2 come back empty (unknown): those exporters
// wrote a fixed text there.
Result<ModelSpec> ImportSfrt(const std::string& path);

}  // namespace sfrt::exporter
